// A channel's band radiance as a function of blackbody temperature,
// tabulated for per-pixel use: L(T), dL/dT and the radiometric temperature
// T(L), each in tens of nanoseconds (SpectralResponse integrates the Planck
// function over the whole response for every call).
//
// ln L(T) is a cubic spline in T on a 0.5 K grid (relative error < 1e-8 over
// 150-700 K, tested against SpectralResponse); T(L) inverts it by Newton's
// method from the bracketing grid interval.
#pragma once

#include <cmath>
#include <vector>

#include "engine/inversion/bspline.h"
#include "engine/optics/spectral_response.h"

namespace qogi {

class BandTable {
 public:
  BandTable() = default;
  // Table of `channel` over [min_temperature_K, max_temperature_K] (within
  // 10-5000 K), grid step step_K.
  BandTable(const SpectralResponse& channel, double min_temperature_K, double max_temperature_K,
            double step_K = 0.5);

  double min_temperature_K() const { return log_l_.x0(); }
  double max_temperature_K() const { return log_l_.x_max(); }
  double min_radiance() const { return node_log_l_.empty() ? 0 : std::exp(node_log_l_.front()); }
  double max_radiance() const { return node_log_l_.empty() ? 0 : std::exp(node_log_l_.back()); }

  // Band radiance [W/(m2 sr)] and its derivative [W/(m2 sr K)] at T (inside the table).
  double Radiance(double temperature_K) const;
  double Derivative(double temperature_K) const;
  // Both at once.
  void RadianceAndDerivative(double temperature_K, double* radiance, double* derivative) const;
  // Radiometric temperature [K] of band radiance L; false when L is not
  // finite or outside [min_radiance(), max_radiance()].
  bool Temperature(double band_radiance, double* temperature_K) const;

 private:
  UniformSpline log_l_;
  std::vector<double> node_log_l_;  // ln L at the grid nodes (ascending)
};

}  // namespace qogi
