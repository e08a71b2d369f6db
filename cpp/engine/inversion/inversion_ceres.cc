// The full-model path (spectrally overlapping species, or no table): Ceres
// on the binned model.
#include "engine/inversion/inversion.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "engine/inversion/bounded_lm_internal.h"
#include "engine/inversion/full_model.h"
#include "engine/inversion/inversion_internal.h"
#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {

using namespace inversion_detail;  // NOLINT: the module's own internals

void Inverter::SolveFull(Pixel* px, const double* start, Workspace* ws) const {
  const std::size_t ns = px->ns, np = px->np;
  double theta[kMaxParams];
  if (start) {
    for (std::size_t p = 0; p < np; ++p) theta[p] = start[p];
  } else {
    FullModelGuess(*px, theta);
  }
  for (std::size_t p = 0; p < np; ++p) {
    if (!px->est[p]) {
      theta[p] = px->nominal[p];
      continue;
    }
    // Strictly inside: a fraction at exactly 0 has no derivative in the full model.
    const double lo =
        p < ns ? std::max(px->lower[p], std::min(1e-7, 0.5 * px->upper[p])) : px->lower[p];
    theta[p] = std::min(std::max(theta[p], lo), px->upper[p]);
  }
  FullModelProblem fp;
  fp.model = model_.get();
  fp.ambient_temperature_K = t_amb_;
  fp.num_channels = px->nc;
  fp.num_species = ns;
  fp.measured_contrast = px->y;
  fp.noise = px->noise;
  fp.background_temperature_K = px->tbg;
  fp.estimated = px->est;
  fp.lower = px->lower;
  fp.upper = px->upper;
  fp.prior_mean = px->nominal;
  fp.prior_sigma = px->prior_sigma;
  fp.tie_ref = px->tie_ref;
  fp.tie_ratio = px->tie_ratio;
  fp.max_iterations = options_.max_iterations;
  int it = 0;
  const bool ok = SolveFullModel(fp, theta, &it);
  px->iterations += it;
  px->ApplyTies(theta);
  for (std::size_t p = 0; p < np; ++p) px->theta[p] = theta[p];
  if (!ok || !std::all_of(theta, theta + np, [](double v) { return std::isfinite(v); })) {
    px->status = PixelStatus::kFailed;
    return;
  }
  px->bound_mask = 0;
  for (std::size_t p = 0; p < np; ++p) {
    if (!px->est[p]) continue;
    const double tol = 1e-9 * std::max(1.0, std::abs(px->upper[p] - px->lower[p]));
    if (theta[p] <= px->lower[p] + tol || theta[p] >= px->upper[p] - tol)
      px->bound_mask |= static_cast<std::uint8_t>(1u << p);
  }
  px->status = px->bound_mask ? PixelStatus::kAtBound : PixelStatus::kConverged;
  double con[kMaxChannels], jac[kMaxChannels * kMaxParams];
  FullModelContrast(*model_, t_amb_, px->theta, px->tbg, con, jac);
  FinishWith(px, con, jac, ws);
}

}  // namespace qogi
