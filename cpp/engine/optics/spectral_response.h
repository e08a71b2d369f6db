// A channel's spectral response (filter x lens x detector) and the band
// radiance seen through it (thesis eq. 14 for a blackbody):
//
//   L(T) = integral response(nu) B(nu, T) dnu        [W/(m2 sr)]
//
// The response is piecewise linear between its samples and zero outside them.
// The integral is evaluated by Gauss-Legendre quadrature on pieces of at most
// kMaxPiece_cm1, which is exact for the piecewise-linear response and accurate
// to ~1e-10 relative for the smooth Planck function.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace qogi {

class SpectralResponse {
 public:
  // nu_cm1: strictly increasing, finite, >= 0 wavenumbers [cm-1], at least 2.
  // response: same length, finite, >= 0, not all zero [dimensionless].
  // Throws std::invalid_argument naming the first offending element.
  SpectralResponse(std::vector<double> nu_cm1, std::vector<double> response, std::string name = "");

  const std::string& name() const { return name_; }
  const std::vector<double>& nu_cm1() const { return nu_; }
  const std::vector<double>& response() const { return response_; }
  double min_nu_cm1() const { return nu_.front(); }
  double max_nu_cm1() const { return nu_.back(); }

  // Response at nu (linear interpolation, 0 outside the grid).
  double Evaluate(double nu_cm1) const;
  // Integral of the response over wavenumber [cm-1].
  double Integral() const { return integral_; }
  // Response-weighted mean wavenumber [cm-1].
  double CentroidWavenumber() const { return centroid_; }

  // Quadrature such that integral response f dnu ~= sum_k w_k f(nu_k) for any
  // smooth f; the weights include the response.
  const std::vector<double>& quadrature_nu_cm1() const { return q_nu_; }
  const std::vector<double>& quadrature_weights() const { return q_w_; }

  // Band radiance L(T) of a blackbody at temperature_K [W/(m2 sr)].
  double BandRadiance(double temperature_K) const;
  // dL/dT [W/(m2 sr K)].
  double BandRadianceDerivative(double temperature_K) const;
  // Inverse of BandRadiance: the radiometric temperature [K] of a band
  // radiance. Accepts radiances of blackbodies between kMinTemperature_K and
  // kMaxTemperature_K; throws std::invalid_argument outside.
  double RadiometricTemperature(double band_radiance) const;

  static constexpr double kMaxPiece_cm1 = 10.0;
  static constexpr double kMinTemperature_K = 10.0;
  static constexpr double kMaxTemperature_K = 1e5;

 private:
  double BandRadianceUnchecked(double temperature_K) const;
  double BandRadianceDerivativeUnchecked(double temperature_K) const;

  std::string name_;
  std::vector<double> nu_, response_;
  std::vector<double> q_nu_, q_w_;
  double integral_ = 0, centroid_ = 0;
};

}  // namespace qogi
