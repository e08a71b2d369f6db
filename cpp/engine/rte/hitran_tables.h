// The forward models' cross-section tables built from HITRAN line lists.
//
// For each species: its lines (spectra/line_sources.h: lines in memory, named
// files or folders, or the search path), the wavenumber range where the
// channels can see it, and sigma(nu, T) tables on that range at the run's
// pressure, as a trace in air (self fraction 0) and, with self-broadening, as
// the pure gas (self fraction 1) (spectra/xsec_table.h), handed over as the
// AbsorberTable the radiative transfer reads.
//
// Range rule: from the lowest channel's first response sample to the highest
// channel's last, narrowed to the species' lines +- kTableWing_cm1; the start
// is then moved down to a multiple of the step, so that every species' grid
// lies on one common lattice nu = k step, and the grid is HAPI's for that
// range (WavenumberGrid::FromRange).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "engine/optics/spectral_response.h"
#include "engine/rte/absorber_table.h"
#include "engine/spectra/cross_section.h"
#include "engine/spectra/line_sources.h"
#include "engine/spectra/xsec_table.h"
#include "engine/util/parallel.h"

namespace qogi {

// Default line wing of the tables, and the margin of the range rule beyond a
// species' outermost lines [cm-1].
constexpr double kTableWing_cm1 = 25.0;

// Settings of the forward models' tables (all change the output).
struct AbsorberTableOptions {
  // Pressure the tables are computed at [Pa]; default 101325. > 0.
  double pressure_Pa = 101325.0;
  // Temperature grid [K]; default 200-600 K every 10 K. Strictly increasing,
  // > 0, at least 2 values.
  std::vector<double> temperatures_K = DefaultTemperatures();
  // Wavenumber step [cm-1]; default 0.01. > 0.
  double step_cm1 = 0.01;
  // Also a table of the pure gas (self-broadened); default true.
  bool self_broadening = true;
  // The wing rule (CrossSectionOptions): a fixed window of wing_cm1 [cm-1]
  // (default kTableWing_cm1) or wing_half_widths half-widths (HAPI's rule is
  // wing_cm1 = 0, wing_half_widths = 50; default 0). At least one > 0.
  double wing_cm1 = kTableWing_cm1;
  double wing_half_widths = 0.0;
  // Worker threads (does not change the output); default 0 = all cores.
  int num_threads = 0;

  // Throws std::invalid_argument (what, value, accepted range).
  void Check() const;
  // The cross-section settings of the tables (line shift on, no intensity
  // threshold).
  CrossSectionOptions cross_section_options() const;
  static std::vector<double> DefaultTemperatures();
};

// The wavenumber grid of `species`' table for `lines` seen through `channels`
// (the range rule above). Throws std::invalid_argument naming the species,
// its lines' span and how to fix it when the lines do not reach any channel's
// band.
WavenumberGrid AbsorberTableGrid(const std::string& species, const LineList& lines,
                                 const std::vector<SpectralResponse>& channels, double step_cm1);

// Makes one sigma(nu, T) table: XsecTable::Build by default; a caller may
// pass its own (e.g. one that keeps tables in a disk cache). It must return a
// table on exactly the grid, temperatures, pressure, self fraction and
// options asked for, and report progress and honour cancellation through
// `control` (may be null).
using XsecTableMaker = std::function<XsecTable(
    const std::string& species, const LineList& lines, const WavenumberGrid& grid,
    const std::vector<double>& temperatures_K, double pressure_Pa, double self_fraction,
    const CrossSectionOptions& options, const RunControl* control)>;

// The table of one species from its lines.
AbsorberTable BuildAbsorberTable(const std::string& species, const LineList& lines,
                                 const std::vector<SpectralResponse>& channels,
                                 const AbsorberTableOptions& options,
                                 const RunControl* control = nullptr,
                                 const XsecTableMaker& make = XsecTableMaker());

// The tables of `species` (HITRAN formulas, in order), their lines found and
// read from `sources`. Progress runs once from 0 to 1 over all tables.
// Throws LineListNotFound, std::invalid_argument (unknown species, no lines of
// a species, lines outside every band, bad options), std::runtime_error (a
// malformed line file) or Cancelled.
std::vector<AbsorberTable> BuildAbsorberTables(const std::vector<std::string>& species,
                                               const std::vector<SpectralResponse>& channels,
                                               const LineSources& sources,
                                               const AbsorberTableOptions& options,
                                               const RunControl* control = nullptr,
                                               const XsecTableMaker& make = XsecTableMaker());

}  // namespace qogi
