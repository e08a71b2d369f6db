#include "engine/spectra/isotopologue.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <map>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "engine/optics/planck.h"
#include "engine/spectra/embedded_data.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

struct TipsTable {
  std::vector<double> t, q;
};

struct Database {
  std::map<int, std::string> molecules;
  std::vector<Isotopologue> isotopologues;
  std::map<std::pair<int, int>, std::size_t> index;
  std::map<std::pair<int, int>, TipsTable> tips;
};

// Splits the data rows of an embedded CSV (skipping '#' comments and the
// header row) into fields.
std::vector<std::vector<std::string>> CsvRows(const char* text) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(text);
  std::string line;
  bool header_seen = false;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (!header_seen) {
      header_seen = true;
      continue;
    }
    std::vector<std::string> fields;
    std::string field;
    std::istringstream ls(line);
    while (std::getline(ls, field, ',')) fields.push_back(field);
    rows.push_back(std::move(fields));
  }
  return rows;
}

// Lagrange interpolation through 3 or 4 grid points chosen as TIPS does.
double TipsInterpolate(const TipsTable& tab, double temperature_K) {
  const std::vector<double>& a = tab.t;
  const std::vector<double>& b = tab.q;
  const std::size_t n = a.size();
  // First node at or above T, searching from the second node.
  std::size_t i = 1;
  while (i < n - 1 && a[i] < temperature_K) ++i;
  std::size_t first, count;
  if (i < 2) {
    first = 0, count = 3;
  } else if (i == n - 1) {
    first = n - 3, count = 3;
  } else {
    first = i - 2, count = 4;
  }
  double sum = 0.0;
  for (std::size_t k = first; k < first + count; ++k) {
    double w = 1.0;
    for (std::size_t m = first; m < first + count; ++m)
      if (m != k) w *= (temperature_K - a[m]) / (a[k] - a[m]);
    sum += w * b[k];
  }
  return sum;
}

Database Load() {
  Database db;
  for (const auto& r : CsvRows(spectra_data::kMoleculesCsv))
    db.molecules[std::atoi(r.at(0).c_str())] = r.at(1);
  for (const auto& r : CsvRows(spectra_data::kTipsCsv)) {
    TipsTable& tab = db.tips[{std::atoi(r.at(0).c_str()), std::atoi(r.at(1).c_str())}];
    tab.t.push_back(std::strtod(r.at(2).c_str(), nullptr));
    tab.q.push_back(std::strtod(r.at(3).c_str(), nullptr));
  }
  for (const auto& r : CsvRows(spectra_data::kIsotopologuesCsv)) {
    Isotopologue iso;
    iso.molecule = std::atoi(r.at(0).c_str());
    iso.local_id = std::atoi(r.at(1).c_str());
    iso.global_id = std::atoi(r.at(2).c_str());
    iso.formula = r.at(3);
    iso.abundance = std::strtod(r.at(4).c_str(), nullptr);
    iso.molar_mass_g_mol = std::strtod(r.at(5).c_str(), nullptr);
    const auto it = db.tips.find({iso.molecule, iso.local_id});
    if (it == db.tips.end() || it->second.t.size() < 4) continue;
    iso.t_min_K = it->second.t.front();
    iso.t_max_K = it->second.t.back();
    iso.q_ref = TipsInterpolate(it->second, constants::kTref);
    db.index[{iso.molecule, iso.local_id}] = db.isotopologues.size();
    db.isotopologues.push_back(std::move(iso));
  }
  return db;
}

const Database& Db() {
  static const Database db = Load();
  return db;
}

std::string ShippedMolecules() {
  std::string s;
  int last = -1;
  for (const auto& iso : Db().isotopologues) {
    if (iso.molecule == last) continue;
    last = iso.molecule;
    if (!s.empty()) s += ", ";
    s += Db().molecules.at(iso.molecule) + " (" + std::to_string(iso.molecule) + ")";
  }
  return s;
}

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

int MoleculeId(const std::string& formula) {
  const std::string want = Upper(formula);
  for (const auto& kv : Db().molecules)
    if (Upper(kv.second) == want) return kv.first;
  throw std::invalid_argument(
      "species must be a HITRAN molecule formula such as "
      "H2O, CO2 or CH4 (qogi has partition sums for " +
      ShippedMolecules() + "); got '" + formula + "'");
}

const std::string& MoleculeFormula(int molecule) {
  const auto it = Db().molecules.find(molecule);
  if (it == Db().molecules.end())
    throw std::invalid_argument("molecule must be a HITRAN molecule code (1-" +
                                std::to_string(Db().molecules.rbegin()->first) + "); got " +
                                std::to_string(molecule));
  return it->second;
}

bool IsKnownMolecule(int molecule) { return Db().molecules.count(molecule) > 0; }

const std::vector<Isotopologue>& Isotopologues() { return Db().isotopologues; }

const Isotopologue* FindIsotopologue(int molecule, int local_id) {
  const auto it = Db().index.find({molecule, local_id});
  return it == Db().index.end() ? nullptr : &Db().isotopologues[it->second];
}

const Isotopologue& GetIsotopologue(int molecule, int local_id) {
  const Isotopologue* iso = FindIsotopologue(molecule, local_id);
  if (iso) return *iso;
  const std::string name =
      IsKnownMolecule(molecule) ? MoleculeFormula(molecule) : "unknown molecule";
  throw std::invalid_argument(
      "isotopologue (molecule " + std::to_string(molecule) + " " + name + ", isotopologue " +
      std::to_string(local_id) +
      ") has no partition-sum (TIPS) data in qogi; qogi ships TIPS-2025 for all "
      "HITRAN isotopologues of " +
      ShippedMolecules() +
      ". Select the isotopologues you need (e.g. isotopologues=[1]) or add the "
      "molecule in scripts/make_spectra_data.py");
}

double PartitionSum(int molecule, int local_id, double temperature_K) {
  const Isotopologue& iso = GetIsotopologue(molecule, local_id);
  CheckInRange(
      temperature_K, iso.t_min_K, iso.t_max_K,
      ("temperature_K (TIPS range of " + MoleculeFormula(molecule) + " " + iso.formula + ")")
          .c_str(),
      "K");
  return TipsInterpolate(Db().tips.at({molecule, local_id}), temperature_K);
}

}  // namespace qogi
