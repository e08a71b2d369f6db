#include "engine/optics/spectral_response.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

// 3-point Gauss-Legendre on [-1, 1].
constexpr double kGLx[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
constexpr double kGLw[3] = {0.5555555555555556, 0.8888888888888888, 0.5555555555555556};

std::string At(const char* what, std::size_t i, double v) {
  return std::string(what) + "[" + std::to_string(i) + "] = " + FormatNumber(v);
}

}  // namespace

SpectralResponse::SpectralResponse(std::vector<double> nu_cm1, std::vector<double> response,
                                   std::string name)
    : name_(std::move(name)), nu_(std::move(nu_cm1)), response_(std::move(response)) {
  const std::string who = "SpectralResponse" + (name_.empty() ? "" : " '" + name_ + "'");
  CheckSameLength(nu_.size(), response_.size(), "nu_cm1", "response");
  Require(nu_.size() >= 2, who + ": needs at least 2 samples; got " + std::to_string(nu_.size()));
  for (std::size_t i = 0; i < nu_.size(); ++i) {
    Require(std::isfinite(nu_[i]) && nu_[i] >= 0,
            who + ": wavenumbers must be finite and >= 0 cm-1; " + At("nu_cm1", i, nu_[i]));
    Require(std::isfinite(response_[i]) && response_[i] >= 0,
            who + ": response must be finite and >= 0; " + At("response", i, response_[i]));
    if (i > 0)
      Require(nu_[i] > nu_[i - 1], who + ": nu_cm1 must be strictly increasing; " +
                                       At("nu_cm1", i, nu_[i]) + " is not above " +
                                       At("nu_cm1", i - 1, nu_[i - 1]));
  }
  // Quadrature: each linear piece split into sub-pieces of <= kMaxPiece_cm1.
  double moment1 = 0;
  for (std::size_t i = 0; i + 1 < nu_.size(); ++i) {
    const double a = nu_[i], b = nu_[i + 1];
    const double ra = response_[i], rb = response_[i + 1];
    if (ra == 0 && rb == 0) continue;
    const int m = std::max(1, static_cast<int>(std::ceil((b - a) / kMaxPiece_cm1)));
    const double h = (b - a) / m;
    for (int j = 0; j < m; ++j) {
      const double lo = a + j * h;
      for (int k = 0; k < 3; ++k) {
        const double x = lo + 0.5 * h * (1.0 + kGLx[k]);
        const double r = ra + (rb - ra) * (x - a) / (b - a);
        const double w = 0.5 * h * kGLw[k] * r;
        if (w <= 0) continue;
        q_nu_.push_back(x);
        q_w_.push_back(w);
        integral_ += w;
        moment1 += w * x;
      }
    }
  }
  Require(integral_ > 0, who +
                             ": response is zero everywhere; a channel must "
                             "transmit somewhere");
  centroid_ = moment1 / integral_;
}

double SpectralResponse::Evaluate(double nu_cm1) const {
  if (!(nu_cm1 >= nu_.front() && nu_cm1 <= nu_.back())) return 0.0;
  const auto it = std::upper_bound(nu_.begin(), nu_.end(), nu_cm1);
  if (it == nu_.end()) return response_.back();
  const std::size_t i = static_cast<std::size_t>(it - nu_.begin()) - 1;
  const double t = (nu_cm1 - nu_[i]) / (nu_[i + 1] - nu_[i]);
  return response_[i] + t * (response_[i + 1] - response_[i]);
}

double SpectralResponse::BandRadianceUnchecked(double t) const {
  double sum = 0;
  for (std::size_t k = 0; k < q_nu_.size(); ++k) sum += q_w_[k] * PlanckUnchecked(q_nu_[k], t);
  return sum;
}

double SpectralResponse::BandRadianceDerivativeUnchecked(double t) const {
  double sum = 0;
  for (std::size_t k = 0; k < q_nu_.size(); ++k) {
    const double x = constants::kC2 * q_nu_[k] / t;
    if (x > 700.0) continue;
    sum += q_w_[k] * PlanckUnchecked(q_nu_[k], t) * x / (t * -std::expm1(-x));
  }
  return sum;
}

double SpectralResponse::BandRadiance(double temperature_K) const {
  CheckPositive(temperature_K, "temperature_K", "K");
  return BandRadianceUnchecked(temperature_K);
}

double SpectralResponse::BandRadianceDerivative(double temperature_K) const {
  CheckPositive(temperature_K, "temperature_K", "K");
  return BandRadianceDerivativeUnchecked(temperature_K);
}

double SpectralResponse::RadiometricTemperature(double band_radiance) const {
  const double l_min = BandRadianceUnchecked(kMinTemperature_K);
  const double l_max = BandRadianceUnchecked(kMaxTemperature_K);
  if (!(std::isfinite(band_radiance) && band_radiance > l_min && band_radiance < l_max))
    throw std::invalid_argument(
        "band_radiance must be finite and within (" + FormatNumber(l_min) + ", " +
        FormatNumber(l_max) + ") W/(m2 sr), the radiances of blackbodies at " +
        FormatNumber(kMinTemperature_K) + "-" + FormatNumber(kMaxTemperature_K) +
        " K through channel '" + name_ + "'; got " + FormatNumber(band_radiance));
  const double log_target = std::log(band_radiance);
  // Initial guess: invert Planck at the band centroid as if it were
  // monochromatic.
  const double nu_c = centroid_;
  double t = constants::kC2 * nu_c /
             std::log1p(constants::kC1 * nu_c * nu_c * nu_c * integral_ / band_radiance);
  if (!(t > kMinTemperature_K && t < kMaxTemperature_K)) t = 300.0;
  // f(T) = ln L(T) - ln L_target is increasing in T. Bracket, then
  // safeguarded Newton.
  auto f = [&](double temp) { return std::log(BandRadianceUnchecked(temp)) - log_target; };
  double lo = t, hi = t;
  while (lo > kMinTemperature_K && f(lo) > 0) lo = std::max(kMinTemperature_K, lo * 0.5);
  while (hi < kMaxTemperature_K && f(hi) < 0) hi = std::min(kMaxTemperature_K, hi * 2.0);
  for (int iter = 0; iter < 200; ++iter) {
    const double l = BandRadianceUnchecked(t);
    const double ft = std::log(l) - log_target;
    if (ft > 0)
      hi = std::min(hi, t);
    else
      lo = std::max(lo, t);
    const double dl = BandRadianceDerivativeUnchecked(t);
    double next = (l > 0 && dl > 0) ? t - ft * l / dl : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - t) <= 1e-13 * t || hi - lo <= 1e-13 * t) return next;
    t = next;
  }
  return t;
}

}  // namespace qogi
