#include "engine/inversion/band_table.h"

#include <algorithm>
#include <cmath>

#include "engine/util/check.h"

namespace qogi {

BandTable::BandTable(const SpectralResponse& channel, double t_min, double t_max, double step) {
  CheckInRange(t_min, 10.0, 5000.0, "band table min_temperature_K", "K");
  CheckInRange(t_max, t_min + 2.0, 5000.0, "band table max_temperature_K", "K");
  CheckInRange(step, 0.01, 10.0, "band table step_K", "K");
  const int n = std::max(4, static_cast<int>(std::ceil((t_max - t_min) / step - 1e-9)) + 1);
  const double h = (t_max - t_min) / (n - 1);
  node_log_l_.resize(n);
  for (int k = 0; k < n; ++k) {
    const double l = channel.BandRadiance(t_min + k * h);
    Require(l > 0, "channel '" + channel.name() + "' has zero band radiance at " +
                       FormatNumber(t_min + k * h) + " K; its response must be positive somewhere");
    node_log_l_[k] = std::log(l);
  }
  log_l_ = UniformSpline(t_min, h, n, 1, node_log_l_);
}

double BandTable::Radiance(double t) const { return std::exp(log_l_.Value(t)); }

double BandTable::Derivative(double t) const {
  double v, s;
  log_l_.Evaluate(t, &v, &s);
  return std::exp(v) * s;
}

void BandTable::RadianceAndDerivative(double t, double* l, double* dl) const {
  double v, s;
  log_l_.Evaluate(t, &v, &s);
  *l = std::exp(v);
  *dl = *l * s;
}

bool BandTable::Temperature(double l, double* t_out) const {
  if (!(l > 0) || !std::isfinite(l)) return false;
  const double y = std::log(l);
  if (y < node_log_l_.front() || y > node_log_l_.back()) return false;
  const auto it = std::upper_bound(node_log_l_.begin(), node_log_l_.end(), y);
  std::size_t k = static_cast<std::size_t>(it - node_log_l_.begin());
  k = std::min<std::size_t>(std::max<std::size_t>(k, 1), node_log_l_.size() - 1) - 1;
  const double h = log_l_.step();
  const double lo = log_l_.x0() + k * h;
  // Linear start inside the bracketing interval, then Newton on the spline.
  const double y0 = node_log_l_[k], y1 = node_log_l_[k + 1];
  double t = lo + h * (y - y0) / (y1 - y0);
  for (int it_n = 0; it_n < 8; ++it_n) {
    double v, s;
    log_l_.Evaluate(t, &v, &s);
    const double dt = (y - v) / s;
    t += dt;
    t = std::min(std::max(t, lo), lo + h);
    if (std::abs(dt) < 1e-10) break;
  }
  *t_out = t;
  return true;
}

}  // namespace qogi
