// Internal to engine/inversion (not installed): the per-pixel state and
// per-thread scratch of the Inverter, and the constants they are sized by,
// shared by its implementation files (inversion_*.cc, bounded_lm.h).
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/inversion/bspline.h"
#include "engine/inversion/inversion.h"
#include "engine/inversion/scene_table.h"
#include "engine/optics/planck.h"

namespace qogi {
namespace inversion_detail {

constexpr std::size_t kMaxChannels = 16;
constexpr std::size_t kMaxParams = 8;  // species + 2
constexpr double kConditionCap = 1e16;
constexpr double kLogEps = 1e-9;  // fractions enter the solver as ln(x + kLogEps)
const double kSqrt2Pi = std::sqrt(2.0 * constants::kPi);

}  // namespace inversion_detail
// ---------------------------------------------------------------------------

struct Inverter::Pixel {
  std::size_t nc = 0, ns = 0, np = 0;
  double y[inversion_detail::kMaxChannels], noise[inversion_detail::kMaxChannels],
      tbg[inversion_detail::kMaxChannels];
  const double* phi = nullptr;
  double nominal[inversion_detail::kMaxParams], lower[inversion_detail::kMaxParams],
      upper[inversion_detail::kMaxParams], prior_sigma[inversion_detail::kMaxParams];
  bool est[inversion_detail::kMaxParams];
  double scale[inversion_detail::kMaxParams];
  int tie_ref[inversion_detail::kMaxParams];      // species index this fraction follows, or -1
  double tie_ratio[inversion_detail::kMaxParams];
  bool has_ties = false;
  // x_s = ratio x_ref for tied fractions.
  void ApplyTies(double* theta) const {
    if (!has_ties) return;
    for (std::size_t s = 0; s < ns; ++s)
      if (tie_ref[s] >= 0) theta[s] = tie_ratio[s] * theta[tie_ref[s]];
  }
  // Moves tied fractions' Jacobian columns [c * np + p] onto their references.
  void FoldJacobian(double* jac, std::size_t rows) const {
    if (!has_ties) return;
    for (std::size_t s = 0; s < ns; ++s)
      if (tie_ref[s] >= 0)
        for (std::size_t c = 0; c < rows; ++c) {
          jac[c * np + tie_ref[s]] += tie_ratio[s] * jac[c * np + s];
          jac[c * np + s] = 0.0;
        }
  }
  // Results.
  double theta[inversion_detail::kMaxParams];
  PixelStatus status = PixelStatus::kFailed;
  std::uint8_t bound_mask = 0;
  std::uint8_t flags = 0;
  double prior_chi2 = 0;  // sum of squared prior residuals at the solution
  double log_det = 0;     // ln det of the estimated parameters' covariance
  int iterations = 0;
  double curvature = 0;  // of the chi2 profile over T_peak at the solution (ProfileLm)
  double chi2 = 0, cond = 0;
  double cov[inversion_detail::kMaxParams * inversion_detail::kMaxParams];
  double psig[inversion_detail::kMaxParams];
  double col[inversion_detail::kMaxParams], col_sig[inversion_detail::kMaxParams],
      ppm[inversion_detail::kMaxParams], ppm_sig[inversion_detail::kMaxParams];
  bool solved() const {
    return status == PixelStatus::kConverged || status == PixelStatus::kAtBound;
  }
};

struct Inverter::Workspace {
  std::vector<double> phi;
  // The T_peak profile: cost and parameters per temperature.
  std::vector<double> profile_cost;
  std::vector<std::array<double, inversion_detail::kMaxParams>> profile_theta;
  std::vector<double> profile_predicted;  // per local minimum
  // Newton curve cache.
  std::size_t curve_channel = static_cast<std::size_t>(-1), curve_species = 0;
  double curve_t = -1, curve_sigma = -1;
  int curve_r1 = 0;
  std::vector<double> curve_nodes;  // [node * r1 + r]
  std::vector<double> curve_u;      // u at the nodes [m]
  UniformSpline curve;
  SceneTable::PeakTerms peak;  // the table's terms at the last T_peak evaluated
  // Profile integral cache.
  double int_t = -1, int_i = 0, int_di = 0;
  std::vector<Inverter::GuessCandidate> guesses;
  std::vector<Inverter::Pixel> solutions;
  // Warm start of the neighbour path.
  double last_theta[inversion_detail::kMaxParams];
  double last_curvature = 0;
  bool last_ok = false;
  void Integral(double tp, double ta) {
    if (tp != int_t) {
      GaussianProfileIntegral(tp, ta, &int_i, &int_di);
      int_t = tp;
    }
  }
};

}  // namespace qogi
