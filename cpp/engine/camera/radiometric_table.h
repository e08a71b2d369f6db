// Fast two-way conversion between blackbody temperature and band radiance
// through one channel, for whole frame stacks:
//
//   L(T) = integral r(nu) B(nu, T) dnu      (thesis eq. 14, blackbody scene)
//   T    = L^-1(L)                          (radiometric temperature)
//
// SpectralResponse evaluates both exactly (quadrature, safeguarded Newton) at
// microseconds to milliseconds a value; a video holds ~1e8 values. The table
// interpolates ln L as a cubic Hermite polynomial of u = 1/T on a uniform grid
// in u (in the Wien limit ln L is linear in u, so the cubic only absorbs the
// band's spread), and u as a cubic Hermite polynomial of ln L on a uniform
// grid in ln L; node slopes are exact derivatives. Values outside the table go
// to the exact SpectralResponse calls (never clamped).
#pragma once

#include <cstddef>

#include "engine/optics/spectral_response.h"
#include "engine/util/parallel.h"

namespace qogi {

class RadiometricTable {
 public:
  // channel: the channel's response; [t_min_K, t_max_K] the tabulated range
  // (10 < t_min_K < t_max_K < 1e5 K); nodes per direction (>= 16).
  // Building costs ~3 nodes x the channel's quadrature size exponentials.
  explicit RadiometricTable(SpectralResponse channel, double t_min_K = 150.0,
                            double t_max_K = 1500.0, int nodes = 512, int num_threads = 0);

  const SpectralResponse& channel() const { return channel_; }
  double t_min_K() const { return t_min_; }
  double t_max_K() const { return t_max_; }
  double radiance_min() const { return l_min_; }  // L(t_min_K) [W/(m2 sr)]
  double radiance_max() const { return l_max_; }  // L(t_max_K) [W/(m2 sr)]

  // Band radiance [W/(m2 sr)] of a blackbody at temperature_K. NaN for NaN
  // or a temperature <= 0.
  double Radiance(double temperature_K) const;
  // dL/dT [W/(m2 sr K)] at temperature_K (the forward cubic's slope:
  // dL/dT = -L u^2 d(ln L)/du); NaN like Radiance.
  double Derivative(double temperature_K) const;
  // Radiance and Derivative at once.
  void RadianceAndDerivative(double temperature_K, double* radiance, double* derivative) const;
  // Radiometric temperature [K] of a band radiance [W/(m2 sr)]. NaN for NaN
  // or a radiance no blackbody of 10 K - 1e5 K gives (e.g. <= 0): such a
  // pixel is flagged, not clamped.
  double Temperature(double band_radiance) const;

  // Elementwise over n float32 values, in parallel (in and out may alias).
  void Radiance(const float* temperature_K, float* out, std::size_t n, int num_threads = 0,
                const RunControl* control = nullptr) const;
  void Temperature(const float* band_radiance, float* out, std::size_t n, int num_threads = 0,
                   const RunControl* control = nullptr) const;

 private:
  struct Cubic {
    double x0 = 0, dx = 1;
    std::vector<double> c;  // 4 coefficients per interval, in s in [0, 1]
    double Eval(double x) const;
    double Eval(double x, double* slope) const;  // slope: d/dx
  };
  static Cubic Hermite(double x0, double dx, const std::vector<double>& v,
                       const std::vector<double>& slope);

  SpectralResponse channel_;
  double t_min_, t_max_, l_min_, l_max_, l_floor_, l_ceil_;
  Cubic forward_;  // ln L of u = 1/T
  Cubic inverse_;  // u = 1/T of ln L
};

}  // namespace qogi
