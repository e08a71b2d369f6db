// HITRAN line lists: a struct-of-arrays LineList, readers for the HITRAN
// 160-character .par format and HAPI's .data (+ .header) tables (gzip or
// plain, LF or CRLF), selection, and the merge of several files of one
// species without counting a line twice.
//
// Units are HITRAN's: wavenumbers in cm-1, intensities at 296 K in
// cm-1/(molecule cm-2) (= cm/molecule) including the natural isotopologue
// abundance, half-widths and shifts in cm-1/atm at 296 K.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace qogi {

// Wavenumber span [nu_min_cm1, nu_max_cm1] that one source covers for one
// isotopologue (from all its records, before any selection). Used by
// MergeLineLists to keep a lower-priority source out of a span that a
// higher-priority source already covers.
struct LineCoverage {
  int molecule = 0;
  int isotopologue = 0;
  double nu_min_cm1 = 0;
  double nu_max_cm1 = 0;
  int source = 0;  // index into LineList::sources of the file it describes
};

// Which lines to keep when reading or selecting.
struct LineSelection {
  // Lines with nu_min_cm1 <= nu <= nu_max_cm1 are kept [cm-1]; default all.
  double nu_min_cm1 = 0.0;
  double nu_max_cm1 = std::numeric_limits<double>::infinity();
  // HITRAN molecule code to keep; 0 (default) keeps every molecule.
  int molecule = 0;
  // Local isotopologue numbers to keep; empty (default) keeps all.
  std::vector<int> isotopologues;
  // Lines with S(296 K) >= min_intensity are kept [cm/molecule]; default 0.
  double min_intensity = 0.0;

  // Throws std::invalid_argument for a bad range, code or threshold.
  void Check() const;
  bool Keeps(int molecule, int isotopologue, double nu_cm1, double intensity) const;
};

// Lines as parallel arrays (one entry per transition).
struct LineList {
  std::vector<int> molecule;        // HITRAN molecule code (6 = CH4)
  std::vector<int> isotopologue;    // HITRAN local isotopologue number (1..)
  std::vector<double> nu_cm1;       // transition wavenumber in vacuum [cm-1]
  std::vector<double> intensity;    // S(296 K) incl. abundance [cm/molecule]
  std::vector<double> einstein_a;   // Einstein A coefficient [s-1] (0 if unknown)
  std::vector<double> gamma_air;    // air-broadened HWHM at 296 K [cm-1/atm]
  std::vector<double> gamma_self;   // self-broadened HWHM at 296 K [cm-1/atm]
  std::vector<double> elower_cm1;   // lower-state energy E'' [cm-1]
  std::vector<double> n_air;        // temperature exponent of gamma_air
  // Temperature exponent of gamma_self. HITRAN .par records have none; the
  // readers then use n_air, as HAPI does.
  std::vector<double> n_self;
  std::vector<double> delta_air;    // air pressure shift at 296 K [cm-1/atm]
  // Self pressure shift [cm-1/atm]. .par records have none; the readers then
  // use delta_air (HAPI would use 0; see docs/spectroscopy.md).
  std::vector<double> delta_self;

  // Span of each source per isotopologue (see LineCoverage).
  std::vector<LineCoverage> coverage;
  // Files the lines came from, in priority order.
  std::vector<std::string> sources;

  std::size_t size() const { return nu_cm1.size(); }
  bool empty() const { return nu_cm1.empty(); }
  void Reserve(std::size_t n);
  // Appends line i of `other`.
  void Append(const LineList& other, std::size_t i);
  // Throws std::invalid_argument when the arrays differ in length or a value
  // is out of range (names the array and the index).
  void Check() const;
  // Lines kept by `selection` (coverage and sources are carried over).
  LineList Select(const LineSelection& selection) const;
  // Sorts the lines by wavenumber (stable).
  void SortByWavenumber();
  // Sets `coverage` from the lines themselves (for lists built in memory).
  void ComputeCoverage();
};

// Reads one line file: HITRAN .par or HAPI .data, optionally gzip-compressed
// (detected from the content, not the name), LF or CRLF. When a HAPI header
// `<stem>.header` lies beside it (stem = name without .gz and .par/.data),
// its column layout is used (fixed columns, plus comma-separated "extra"
// parameters; n_self and delta_self are taken from there when present);
// otherwise the 160-character HITRAN layout. Blank lines are skipped; any
// malformed record throws std::runtime_error naming the file, the line
// number, the field and its columns.
LineList ReadLineFile(const std::string& path, const LineSelection& selection = LineSelection());

// Reads several files and merges them with MergeLineLists (the first file has
// the highest priority).
LineList ReadLineFiles(const std::vector<std::string>& paths,
                       const LineSelection& selection = LineSelection());

// Merges line lists given in priority order without counting a transition
// twice: a line of a lower-priority list is dropped when a higher-priority
// list covers its isotopologue at its wavenumber (LineCoverage). Typical use:
// a newer HITRAN edition of the main isotopologue over a band, completed by
// an older all-isotopologue file outside that band and for the other
// isotopologues. The result is sorted by wavenumber.
LineList MergeLineLists(const std::vector<LineList>& by_priority);

}  // namespace qogi
