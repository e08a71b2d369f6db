// Absorption cross-section sigma(nu) [cm2/molecule] of a line list: the sum of
// Voigt lines (voigt.h) with the parameters of line_parameters.h,
//
//   sigma(nu) = sum_i S_i(T) V(nu - nu*_i; gamma_D,i, gamma_L,i)
//               over lines with |nu - nu_i| within their wing,
//
// where line i contributes only inside its window nu_i - W_i < nu <= nu_i + W_i
// around its unshifted position nu_i, with
//
//   W_i = max(wing_cm1, wing_half_widths * max(gamma_L,i, gamma_D,i)).
//
// The defaults (wing_cm1 = 0, wing_half_widths = 50) are HAPI 1.3's
// absorptionCoefficient_Voigt rule (WavenumberWing = 0, WavenumberWingHW = 50,
// window centred on the unshifted line, profile on the shifted one); a fixed
// cutoff of C cm-1 is wing_cm1 = C, wing_half_widths = 0.
//
// Work is split into chunks of output points handled by ParallelFor; each
// chunk owns its output range, so threads never write to the same point.
#pragma once

#include <cstddef>
#include <vector>

#include "engine/spectra/line_list.h"
#include "engine/spectra/line_parameters.h"
#include "engine/util/parallel.h"

namespace qogi {

// A uniform wavenumber grid nu_j = nu0_cm1 + j step_cm1, j = 0 .. size - 1.
struct WavenumberGrid {
  double nu0_cm1 = 0.0;    // first point [cm-1]; >= 0
  double step_cm1 = 0.01;  // spacing [cm-1]; > 0
  std::size_t size = 0;    // number of points; >= 1

  void Check() const;
  double operator[](std::size_t j) const { return nu0_cm1 + static_cast<double>(j) * step_cm1; }
  double last_cm1() const { return (*this)[size - 1]; }
  // HAPI's grid for a range and step (its arange_): floor((max - min)/step) + 1
  // points from nu_min_cm1, plus one when the next point lands within 1e-10
  // cm-1 of nu_max_cm1.
  static WavenumberGrid FromRange(double nu_min_cm1, double nu_max_cm1, double step_cm1);
};

// How the cross-section is computed (settings that change the output).
struct CrossSectionOptions {
  // Wing half-width in units of max(gamma_L, gamma_D) of each line
  // [dimensionless]; default 50 (HAPI's WavenumberWingHW). >= 0.
  double wing_half_widths = 50.0;
  // Minimum wing half-width [cm-1]; default 0 (HAPI's WavenumberWing). >= 0.
  // A fixed cutoff of C cm-1: wing_cm1 = C, wing_half_widths = 0.
  double wing_cm1 = 0.0;
  // Apply the pressure shift of line centres; default true (HAPI's LineShift).
  bool line_shift = true;
  // Lines with S(T) below this are skipped [cm/molecule]; default 0
  // (HAPI's IntensityThreshold). >= 0.
  double min_intensity = 0.0;

  // Throws std::invalid_argument (what, value, accepted range); at least one
  // of wing_half_widths and wing_cm1 must be > 0.
  void Check() const;
};

// Settings that do not change the output.
struct ComputeSettings {
  int num_threads = 0;  // worker threads; default 0 = all cores
};

// sigma on a uniform grid, written to out[0 .. grid.size) [cm2/molecule].
void ComputeCrossSection(const LineList& lines, const GasConditions& conditions,
                         const WavenumberGrid& grid, const CrossSectionOptions& options,
                         double* out, const ComputeSettings& settings = ComputeSettings(),
                         const RunControl* control = nullptr);
// sigma at arbitrary strictly increasing wavenumbers nu_cm1[0 .. n).
void ComputeCrossSection(const LineList& lines, const GasConditions& conditions,
                         const double* nu_cm1, std::size_t n, const CrossSectionOptions& options,
                         double* out, const ComputeSettings& settings = ComputeSettings(),
                         const RunControl* control = nullptr);

// Convenience forms returning a vector.
std::vector<double> CrossSection(const LineList& lines, const GasConditions& conditions,
                                 const WavenumberGrid& grid,
                                 const CrossSectionOptions& options = CrossSectionOptions(),
                                 const ComputeSettings& settings = ComputeSettings(),
                                 const RunControl* control = nullptr);
std::vector<double> CrossSection(const LineList& lines, const GasConditions& conditions,
                                 const std::vector<double>& nu_cm1,
                                 const CrossSectionOptions& options = CrossSectionOptions(),
                                 const ComputeSettings& settings = ComputeSettings(),
                                 const RunControl* control = nullptr);

// Absorption coefficient k(nu) = sigma(nu) x n [cm-1] of the absorber at mole
// fraction conditions.self_fraction, n = x p / (k_B T) its number density.
std::vector<double> AbsorptionCoefficient(
    const LineList& lines, const GasConditions& conditions, const WavenumberGrid& grid,
    const CrossSectionOptions& options = CrossSectionOptions(),
    const ComputeSettings& settings = ComputeSettings(), const RunControl* control = nullptr);

}  // namespace qogi
