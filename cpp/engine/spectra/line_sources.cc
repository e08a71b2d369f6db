#include "engine/spectra/line_sources.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <system_error>
#include <utility>

#include "engine/spectra/isotopologue.h"

namespace qogi {
namespace {

namespace fs = std::filesystem;

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

std::string ExpandUser(const std::string& p) {
  if (p.empty() || p[0] != '~' || (p.size() > 1 && p[1] != '/' && p[1] != '\\')) return p;
  const char* home = std::getenv("HOME");
  return home ? std::string(home) + p.substr(1) : p;
}

bool IsFile(const std::string& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

bool Exists(const std::string& p) {
  std::error_code ec;
  return fs::exists(p, ec);
}

bool IsDirectory(const std::string& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

std::string Join(const std::vector<std::string>& parts) {
  std::string out;
  for (const auto& s : parts) out += (out.empty() ? "" : ", ") + s;
  return out;
}

}  // namespace

std::vector<std::string> LineSearchPath(const std::vector<std::string>& folders,
                                        const std::vector<std::string>& fallback) {
  std::vector<std::string> out;
  for (const auto& f : folders) out.push_back(ExpandUser(f));
#ifdef _WIN32
  const char sep = ';';
#else
  const char sep = ':';
#endif
  if (const char* env = std::getenv(kHitranPathVariable)) {
    const std::string text(env);
    std::size_t start = 0;
    while (start <= text.size()) {
      std::size_t end = text.find(sep, start);
      if (end == std::string::npos) end = text.size();
      if (end > start) out.push_back(ExpandUser(text.substr(start, end - start)));
      start = end + 1;
    }
  }
  for (const auto& f : fallback) out.push_back(ExpandUser(f));
  return out;
}

std::vector<std::string> SpeciesLineFiles(const std::string& folder, const std::string& species) {
  if (!IsDirectory(folder)) return {};
  static const char* const kExtensions[] = {".par", ".data", ".par.gz", ".data.gz"};
  const std::string sp = Lower(species);
  std::vector<std::pair<std::string, std::string>> entries;  // (lower-case name, path)
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec))
    entries.emplace_back(Lower(e.path().filename().string()), e.path().string());
  std::stable_sort(entries.begin(), entries.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::string> exact, other;
  for (const auto& [name, path] : entries) {
    const char* ext = nullptr;
    for (const char* x : kExtensions)
      if (EndsWith(name, x)) {
        ext = x;
        break;
      }
    if (ext == nullptr || !IsFile(path)) continue;
    const std::string stem = name.substr(0, name.size() - std::string(ext).size());
    if (stem == sp)
      exact.push_back(path);
    else if (stem.size() > sp.size() && stem.compare(0, sp.size(), sp) == 0 &&
             std::string("_-.").find(stem[sp.size()]) != std::string::npos)
      other.push_back(path);
  }
  exact.insert(exact.end(), other.begin(), other.end());
  return exact;
}

std::vector<std::string> FindLineFiles(const std::string& species,
                                       const std::vector<std::string>& paths,
                                       const std::vector<std::string>& fallback) {
  std::vector<std::string> given;
  bool any_file = false;
  for (const auto& p : paths) {
    given.push_back(ExpandUser(p));
    if (!Exists(given.back())) throw LineListNotFound("line list path not found: " + given.back());
    any_file = any_file || IsFile(given.back());
  }
  if (any_file) {
    std::vector<std::string> out;
    for (const auto& p : given) {
      if (IsFile(p)) {
        out.push_back(p);
      } else {
        const auto files = SpeciesLineFiles(p, species);
        out.insert(out.end(), files.begin(), files.end());
      }
    }
    return out;
  }
  std::vector<std::string> searched;
  for (const auto& folder : LineSearchPath(given, fallback)) {
    searched.push_back(folder);
    auto files = SpeciesLineFiles(folder, species);
    if (!files.empty()) return files;
  }
  throw LineListNotFound("no HITRAN line list for '" + species + "' (looked for " + species +
                         ".par/.data[.gz] and " + species +
                         "_*.par/.data[.gz] in: " + Join(searched) +
                         "). Pass line_list=<file or folder>, set " + kHitranPathVariable +
                         " to a folder of line lists, or download one with `qogi hitran fetch " +
                         species + " --range MIN MAX`.");
}

LineList ReadMoleculeLines(const std::vector<std::string>& files, int molecule) {
  LineSelection keep;
  keep.molecule = molecule;
  LineList lines = ReadLineFiles(files, keep);
  if (lines.empty()) {
    const std::string& formula = MoleculeFormula(molecule);
    throw std::invalid_argument("the line list for " + formula + " (" + Join(files) + ") has no " +
                                formula + " lines (molecule code " + std::to_string(molecule) +
                                ")");
  }
  return lines;
}

LineList LoadSpeciesLines(const std::string& species, const LineSources& sources) {
  const int molecule = MoleculeId(species);
  const std::string& formula = MoleculeFormula(molecule);
  const auto given = sources.lines.find(species);
  if (given != sources.lines.end()) {
    const LineList& all = given->second;
    const bool only_this =
        std::all_of(all.molecule.begin(), all.molecule.end(), [&](int m) { return m == molecule; });
    LineSelection keep;
    keep.molecule = molecule;
    LineList lines = only_this ? all : all.Select(keep);
    if (lines.empty())
      throw std::invalid_argument("the line list given for " + formula + " has no " + formula +
                                  " lines (molecule code " + std::to_string(molecule) + ")");
    return lines;
  }
  const auto named = sources.paths.find(species);
  const std::vector<std::string> none;
  const auto files =
      FindLineFiles(formula, named != sources.paths.end() ? named->second : none, sources.fallback);
  return ReadMoleculeLines(files, molecule);
}

}  // namespace qogi
