// Per-pixel inversion on a plume's mixing line: one unknown per pixel.
//
// A released gas that mixes with ambient air (adiabatically, as in a plume)
// has at every point a temperature excess proportional to its volume
// fraction, T - T_amb = k X, and a known composition x_s = w_s X. With the
// scene's slope k and the Gaussian depth sigma given, each pixel's band
// contrasts depend on the total peak fraction X alone; it is the
// least-squares solution of
//
//   min_X  sum_c ((Delta L_c(w X, T_amb + k X, sigma) - y_c) / n_c)^2,
//
// found by a coarse scan in ln X followed by safeguarded Gauss-Newton in
// ln X on the per-scene table (SceneTable::Contrast). Where the line runs out
// of the table's temperature range, T is held at the range's end.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "engine/camera/radiometric_table.h"
#include "engine/inversion/scene_table.h"
#include "engine/util/parallel.h"

namespace qogi {

struct MixingLineOptions {
  double slope_K_per_fraction = 0.0;  // k: T_peak = T_amb + k X [K per unit volume fraction]
  std::vector<double> composition;    // w_s >= 0 per species of the table (x_s = w_s X), sum > 0
  std::vector<double> netd_K;         // per channel (or one value for all) [K]
  double detection_sigma = 3.0;  // below detection: |y_c| < detection_sigma n_c in every channel
  // Below detection X is 0 (default), or with this set the thin-limit
  // least-squares X from the contrasts, signed and noisy (unbiased summed
  // over pixels; InversionOptions::signed_below_detection).
  bool signed_below_detection = false;
  double min_fraction = 1e-9;  // lower bound of X
  double max_fraction = 1.0;  // upper bound of X (every x_s <= 1 as well)
  int max_iterations = 50;  // Gauss-Newton iterations per pixel (>= 1)
  // Pixels sharing a plume depth (e.g. one control surface) are solved on a
  // tabulation of the line's contrast in ln X with this many nodes per unit
  // (cubic Hermite from the table's values and slopes; the table's contrast
  // is affine in the background), when that is cheaper than evaluating the
  // table per pixel. 0 = always evaluate the table. [0, 256].
  int line_nodes_per_unit = 16;
  int num_threads = 0;  // 0 = all hardware threads

  // Throws std::invalid_argument naming the field.
  void Check(std::size_t num_species, std::size_t num_channels) const;
};

// Inputs per pixel i (row-major): radiance[i * C + c], background_radiance
// [i * C + c] [W/(m2 sr)], sigma_m[i] [m]. Outputs (caller-allocated, N
// values): the total peak fraction X and its 1-sigma (from the curvature of
// the chi2 along the line; for pixels below detection the 1-sigma of X in
// the optically thin limit), the peak temperature on the line, chi2 and the
// status (PixelStatus: converged, at bound, below detection, failed),
// and the Gauss-Newton iterations. Status values are PixelStatus (inversion.h).
struct MixingLineOutput {
  double* fraction = nullptr;
  double* fraction_sigma = nullptr;
  double* peak_temperature_K = nullptr;
  double* chi2 = nullptr;
  std::int32_t* status = nullptr;
  std::int32_t* iterations = nullptr;
};

// Holds the scene table and each channel's band table (radiance <->
// temperature, built once).
class MixingLineInverter {
 public:
  explicit MixingLineInverter(std::shared_ptr<const SceneTable> table);
  const SceneTable& table() const { return *table_; }
  // Each channel's band table (radiance <-> temperature) [W/(m2 sr)], [K].
  const std::vector<RadiometricTable>& bands() const { return bands_; }
  void Invert(const MixingLineOptions& options, std::size_t num_pixels, const double* radiance,
              const double* background_radiance, const double* sigma_m, const MixingLineOutput& out,
              const RunControl* control = nullptr) const;

 private:
  std::shared_ptr<const SceneTable> table_;
  std::vector<RadiometricTable> bands_;
};

}  // namespace qogi
