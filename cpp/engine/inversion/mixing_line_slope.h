// The slope of a scene's mixing line, T - T_amb = k X, from its pixels.
//
// One k holds for a whole scene (mixing_line.h), so it is measured once, as
// a profile likelihood: a sample of the detected pixel-frames (contrast >=
// min_snr x noise in some channel) is solved on the line for each k of a
// grid spanning the scene table's temperature range, k minimises the summed
// chi2 (each pixel's capped, so that a few pixels that no temperature fits do
// not decide it), refined by a parabola through the grid's best three nodes;
// its 1-sigma is where the (linearly interpolated) profile rises by the
// reduced chi2 (>= 1: model error widens Delta chi2 = 1) from its minimum,
// on the flatter side. Pixel-by-pixel free temperatures are too weakly
// determined (and two-branched) to average into k.
//
// The three steps are separate so that a caller with its own per-pixel
// solver on the line (e.g. fixed-temperature passes for an unknown
// composition) reuses the sample and the profile statistics:
//   MixingLineSlopeSample            the sample of pixel-frames,
//   MixingLineSlopeFromProfile       k and its 1-sigma from chi2(k, pixel),
//   FindMixingLineSlope              both around MixingLineInverter::Invert.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/inversion/mixing_line.h"
#include "engine/util/parallel.h"

namespace qogi {

struct MixingLineSlopeOptions {
  // The per-pixel solve on the line (its slope_K_per_fraction is ignored;
  // composition, netd_K, detection_sigma, ... are used as given).
  MixingLineOptions line;
  double min_snr = 10.0;          // sampled: max_c |L_c - L_bg,c| / n_c >= min_snr [1], >= 0
  std::size_t max_samples =
      3000; // at most this many pixel-frames: a seeded random subset of the candidates (>= 1)
  std::uint64_t seed = 0;         // of that subset (splitmix64; the same on every platform)
  std::size_t min_samples = 5;    // fewer candidates: no search, k = 0 (found = false) (>= 1)
  double grid_step_K = 10.0;      // step of the k grid [K per unit fraction], > 0
  double chi2_cap = 50.0;         // each pixel's chi2 capped at this in the total [1], > 0

  // Throws std::invalid_argument naming the field.
  void Check(std::size_t num_species, std::size_t num_channels) const;
};

struct MixingLineSlope {
  bool found = false;  // false: fewer than min_samples candidates (k = 0, sigma 0)
  double slope_K_per_fraction = 0.0;  // k [K per unit volume fraction]
  double sigma_K_per_fraction = 0.0;  // its 1-sigma [K per unit volume fraction]
  std::size_t num_candidates = 0;  // pixel-frames at or above min_snr
  std::size_t num_samples = 0;  // of them, solved on the line for each k
  std::size_t num_fitted = 0;  // samples with a finite chi2 at every k (in the total)
  std::vector<double> grid_K_per_fraction;  // the k grid
  std::vector<double> total_chi2;  // the capped chi2 summed over the fitted samples, per k
};

// The pixel-frames (rows of radiance and background_radiance [W/(m2 sr)],
// N x C row-major) whose contrast reaches options.min_snr times the noise in
// some channel (noise: options.line.netd_K times dL/dT at the channel's
// median background temperature), at most options.max_samples of them (a
// random subset seeded by options.seed, in index order); *num_candidates:
// how many reached min_snr.
std::vector<std::size_t> MixingLineSlopeSample(const MixingLineInverter& inverter,
                                               const MixingLineSlopeOptions& options,
                                               std::size_t num_pixels, const double* radiance,
                                               const double* background_radiance,
                                               std::size_t* num_candidates = nullptr);

// k and its 1-sigma from the chi2 of P pixels at each of K grid values
// (chi2[k * P + p], row-major; pixels with a non-finite chi2 at any k are
// left out). grid: K >= 1 increasing, evenly spaced values. found = false
// when no pixel is left.
MixingLineSlope MixingLineSlopeFromProfile(const std::vector<double>& grid, std::size_t num_pixels,
                                           const double* chi2, double chi2_cap);

// The whole search over the pixel-frames (rows of radiance and
// background_radiance [W/(m2 sr)], N x C row-major; sigma_m (N,) [m]).
// Progress runs over the grid's per-pixel solves; control may cancel.
MixingLineSlope FindMixingLineSlope(const MixingLineInverter& inverter,
                                    const MixingLineSlopeOptions& options, std::size_t num_pixels,
                                    const double* radiance, const double* background_radiance,
                                    const double* sigma_m, const RunControl* control = nullptr);

}  // namespace qogi
