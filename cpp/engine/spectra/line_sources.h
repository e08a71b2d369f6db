// Where a species' HITRAN lines come from: the folders searched for line
// files, the files that match a species, and the lines read from them.
//
// A folder holds a species' lines in files named (case-insensitively)
// `<SPECIES>.par`, `.data`, `.par.gz` or `.data.gz`, then `<SPECIES>_*`,
// `<SPECIES>-*` or `<SPECIES>.*` with one of those extensions, in name order.
// All of a species' files in one folder are used, merged by priority
// (MergeLineLists: the first file wins where two cover the same isotopologue),
// e.g. `H2O.par` (HITRAN2020, main isotopologue) with
// `H2O_HITRAN2012.par.gz` (the others, and outside that span).
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/spectra/line_list.h"

namespace qogi {

// Thrown when no line file of a species is found, or a named path does not
// exist (Python receives FileNotFoundError).
class LineListNotFound : public std::runtime_error {
 public:
  explicit LineListNotFound(const std::string& what) : std::runtime_error(what) {}
};

// Environment variable holding extra folders of line lists, separated by ':'
// (';' on Windows); searched after the caller's folders.
constexpr const char* kHitranPathVariable = "QOGI_HITRAN_PATH";

// Folders searched for line lists, in order: `folders`, then the folders in
// $QOGI_HITRAN_PATH, then `fallback` (for qogi's Python package: the per-user
// cache of downloads and the subsets the package ships). A leading "~" is
// the home folder ($HOME).
std::vector<std::string> LineSearchPath(const std::vector<std::string>& folders,
                                        const std::vector<std::string>& fallback);

// The line files of a species in one folder, highest priority first (see the
// file comment); empty when the folder does not exist or has none.
std::vector<std::string> SpeciesLineFiles(const std::string& folder, const std::string& species);

// The line files of `species` (a HITRAN formula, "CH4").
//
// `paths` are files and folders the caller names; each must exist. When any
// of them is a file, the files are used as given and the folders are searched
// for the species' files, in the order given. Otherwise the folders of
// LineSearchPath(paths, fallback) are searched in order and the first that
// holds any file of the species wins (a folder named earlier hides the ones
// after it).
//
// Throws LineListNotFound naming every folder searched and how to provide
// line lists.
std::vector<std::string> FindLineFiles(const std::string& species,
                                       const std::vector<std::string>& paths,
                                       const std::vector<std::string>& fallback);

// The lines of one molecule (HITRAN code) read from `files` (ReadLineFiles,
// first file highest priority). Throws std::invalid_argument when the files
// hold none of its lines, and std::runtime_error (from the reader) naming the
// file, line and field of a malformed record.
LineList ReadMoleculeLines(const std::vector<std::string>& files, int molecule);

// Where each species' lines come from, most specific first: lines given in
// memory, then files or folders named per species, then the search path.
struct LineSources {
  // Lines already in memory, per species formula; lines of other molecules
  // in them are left out.
  std::map<std::string, LineList> lines;
  // Files and folders per species formula (FindLineFiles' `paths`).
  std::map<std::string, std::vector<std::string>> paths;
  // Folders searched after the named ones and $QOGI_HITRAN_PATH
  // (FindLineFiles' `fallback`).
  std::vector<std::string> fallback;
};

// The lines of `species` (a HITRAN formula) from `sources`. Throws
// LineListNotFound, std::invalid_argument (no lines of the species) or
// std::runtime_error (a malformed file), as above.
LineList LoadSpeciesLines(const std::string& species, const LineSources& sources);

}  // namespace qogi
