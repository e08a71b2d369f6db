#include "engine/camera/camera.h"

#include <cmath>
#include <string>

#include "engine/util/check.h"

namespace qogi {

void CameraModel::Check() const {
  Require(!name.empty(), "camera name is empty");
  Require(width > 0 && height > 0, "camera resolution must be positive; got " +
                                       std::to_string(width) + "x" + std::to_string(height));
  CheckInRange(ifov_rad, 1e-6, 0.1, "ifov_rad", "rad");
  CheckInRange(frame_rate_hz, 1e-3, 1e5, "frame_rate_hz", "Hz");
  CheckInRange(netd_K, 1e-4, 10.0, "netd_K", "K");
  Require(!channels.empty(), "camera '" + name + "' has no channel");
}

namespace {
// Logistic step rising through 0.5 at x0 with 10-90 % width w (in x units).
double Step(double x, double x0, double w) {
  const double k = 2.0 * std::log(9.0) / w;  // 10-90 % over w
  return 1.0 / (1.0 + std::exp(-k * (x - x0)));
}
}  // namespace

std::vector<double> BandpassTransmittance(const std::vector<double>& nu, double lo_um, double hi_um,
                                          double peak, double edge_um) {
  Require(lo_um > 0 && hi_um > lo_um, "band-pass edges must satisfy 0 < lo < hi um");
  std::vector<double> out(nu.size());
  for (std::size_t i = 0; i < nu.size(); ++i) {
    const double wl = 1e4 / nu[i];
    out[i] = peak * Step(wl, lo_um, edge_um) * (1.0 - Step(wl, hi_um, edge_um));
  }
  return out;
}

std::vector<double> MwirLensTransmittance(const std::vector<double>& nu) {
  std::vector<double> out(nu.size());
  for (std::size_t i = 0; i < nu.size(); ++i) {
    const double wl = 1e4 / nu[i];
    const double d = (wl - 3.9) / 1.6;  // 0 at the design band's centre
    out[i] = std::max(0.70, 0.92 - 0.17 * d * d * d * d);
  }
  return out;
}

std::vector<double> InSbDetectorResponse(const std::vector<double>& nu) {
  std::vector<double> out(nu.size());
  for (std::size_t i = 0; i < nu.size(); ++i) {
    const double wl = 1e4 / nu[i];
    out[i] = Step(wl, 1.5, 0.05) * (1.0 - Step(wl, 5.4, 0.05));
  }
  return out;
}

}  // namespace qogi
