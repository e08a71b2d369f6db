// The coarse-to-fine warping solver shared by HornSchunckFlow (brightness
// constancy) and FluidFlow (continuity equation). Internal to the module.
//
// On each pyramid level, from the coarsest to `finest_level`, and for each of
// `warps` warps, the data term is linearised around the current flow w0 and
// the increment dw minimises the quadratic energy
//
//   E(dw) = sum_x W(x) (r0(x) + A dw (x))^2 + R(w0 + dw)
//
// by preconditioned conjugate gradients (block-Jacobi preconditioner).
//
//   brightness:  r0 = I1(x + w0) - I0(x),
//                A dw = grad I . dw  (grad I = mean of the five-point gradients
//                of I0 and of the warped I1)
//   continuity:  r0 = rho1(x + w0) det(1 + grad w0) - rho0(x)   (exact mass
//                conservation for the map x -> x + w0: no assumption on how
//                the velocity varies during the frame interval),
//                A dw = det(1 + grad w0) div(rho1(x + w0) dw)   (central
//                differences; div and its adjoint are exact transposes)
//   R(w) = alpha sum |grad (u - us)|^2 + |grad (v - vs)|^2   (forward differences)
//        + alpha_div  sum (div w - xi)^2 + alpha_curl sum (curl w - zeta)^2
//
// with (us, vs) = 0, or with smoothness_scale > 0 the current flow smoothed
// over that scale (so that only short-scale variations of the flow are
// penalised and plume-scale acceleration and spreading are left to the data),
// and where xi and zeta, the smooth parts of the divergence and the vorticity,
// are auxiliary fields updated before each warp as the Gaussian-filtered
// (sigma = div_curl_scale) divergence and curl of the current flow. This is
// the auxiliary-field form of the second-order div-curl regulariser of
// Corpetti, Memin & Perez (IEEE PAMI 24, 2002): it penalises divergence and
// vorticity that vary on scales shorter than div_curl_scale while leaving
// smooth spreading and rotation free, and every linear system stays second
// order (fast conjugate gradients).
//
// Intensities are divided by the standard deviation of the frame pair (over
// the gas mask when one is given), so the weights do not depend on units.
#pragma once

#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "engine/util/check.h"
#include "engine/velocimetry/flow.h"

namespace qogi {
namespace flow_ops {

enum class DataModel { kBrightness, kContinuity };

struct VariationalSettings {
  DataModel data = DataModel::kBrightness;
  double alpha = 0.0;
  double alpha_div = 0.0;
  double alpha_curl = 0.0;
  double div_curl_scale = 8.0;  // px at full resolution
  // > 0: the smoothness term penalises the gradient of w - G(w0) instead of
  // w (G a Gaussian of sigma smoothness_scale px at full resolution, w0 the
  // flow at the start of the warp): an auxiliary field like xi and zeta.
  // 0 = classic first-order smoothness.
  double smoothness_scale = 0.0;
  int levels = 1;
  int min_level_size = 16;
  int finest_level = 0;
  int warps = 1;
  int iterations = 10;
  int warm_levels = 0;  // levels solved after a warm start (0 = all)
  double tolerance = 1e-3;
  // Scale the frames by the pair's standard deviation over the gas mask (when
  // given) rather than over the whole frame.
  bool scale_over_mask = true;
};

// The pyramid and solver fields that the options of both variational
// methods (HornSchunckOptions, FluidFlowOptions) carry under the same names:
// their range checks (messages name "<type>.<field>") and their copy into
// the solver's settings.
template <typename Options>
void CheckPyramidFields(const Options& o, const std::string& type) {
  CheckInRange(o.levels, 1, 12, (type + ".levels").c_str());
  CheckInRange(o.min_level_size, 4, 4096, (type + ".min_level_size").c_str(), "px");
  CheckInRange(o.finest_level, 0, 10, (type + ".finest_level").c_str());
  CheckInRange(o.warm_levels, 0, 12, (type + ".warm_levels").c_str());
  CheckInRange(o.warps, 1, 50, (type + ".warps").c_str());
  CheckInRange(o.iterations, 1, 1000, (type + ".iterations").c_str());
  CheckInRange(o.tolerance, 0, 0.999999, (type + ".tolerance").c_str());
}

template <typename Options>
VariationalSettings PyramidSettings(const Options& o, DataModel data) {
  VariationalSettings s;
  s.data = data;
  s.alpha = o.alpha;
  s.levels = o.levels;
  s.min_level_size = o.min_level_size;
  s.finest_level = o.finest_level;
  s.warps = o.warps;
  s.warm_levels = o.warm_levels;
  s.iterations = o.iterations;
  s.tolerance = o.tolerance;
  return s;
}

class VariationalSolver {
 public:
  // mask: the gas mask (may be empty); source: where gas may enter the image
  // (continuity only; may be empty).
  void Solve(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, const cv::Mat& source,
             bool warm, const VariationalSettings& s, FlowField& flow);

 private:
  void SolveLevel(int level, int finest, const VariationalSettings& s);
  void Linearise(int level, const VariationalSettings& s);
  // Pass 1 of the normal operator: g (data), del (div) and kap (curl) of
  // (pu, pv); with rhs = true, of the current flow's residuals instead.
  void ForwardPass(const float* pu, const float* pv, bool rhs);
  // Pass 2: (ou, ov) = A^T g + alpha L p + alpha_div D^T del + alpha_curl C^T
  // kap; returns <p, o>.
  double AdjointPass(const float* pu, const float* pv, float* ou, float* ov);
  // Quality, residual ratio and validity of the result (solved on `level`).
  void FinalResidual(int level, FlowField& flow, const cv::Mat& mask);

  DataModel data_ = DataModel::kBrightness;
  int coarsest_ = 0;
  double alpha_ = 0, alpha_div_ = 0, alpha_curl_ = 0, div_curl_scale_ = 0;
  int W_ = 0, H_ = 0;
  cv::Mat i0n_, i1n_, maskf_, sourcef_;
  std::vector<cv::Mat> p0_, p1_, pm_, ps_;
  cv::Mat u_, v_, un_, vn_;           // current flow on the level
  cv::Mat warped_, inside_, gx_, gy_, g0x_, g0y_, ux_, uy_, vx_, vy_;
  // Per-pixel linearisation: for brightness a = Ix, b = Iy; for continuity
  // a = rho (warped next), b = det(1 + grad w0). w = data weight, r = r0.
  std::vector<float> a_, b_, w_, r_, c_;  // c = w b^2 (continuity)
  std::vector<float> g_, del_, kap_;
  std::vector<float> zero_row_;  // W zeros: the missing neighbour rows of g, del, kap
  cv::Mat smooth_u_, smooth_v_;  // w0 - share G(w0): the smoothness's rhs argument
  double smoothness_scale_ = 0;
  cv::Mat xi_, zeta_, quality_level_;  // smooth divergence and vorticity targets
  std::vector<float> pre_a_, pre_b_, pre_c_;  // inverse block preconditioner
  std::vector<float> x_, res_, p_, q_;  // conjugate-gradient vectors (u then v)
};

}  // namespace flow_ops
}  // namespace qogi
