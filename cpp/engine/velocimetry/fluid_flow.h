// "Fluid" optical flow: the continuity (transport) equation on column density
// instead of brightness constancy.
//
// Integrating the 3-D continuity equation along the line of sight gives, for
// the column density rho [kg/m2] and the column-density-weighted mean velocity
// u_bar projected on the image plane (Liu & Shen, "Fluid flow and optical
// flow", J. Fluid Mech. 614, 253-291, 2008, the "projected motion equation"):
//
//   d(rho)/dt + div(rho u_bar) = 0.
//
// u_bar is exactly the velocity the flux needs (flux = integral rho u_bar.n dl).
// Unlike brightness constancy, the equation stays true where the plume
// spreads or dilutes, and where the plume is steady and featureless it keeps
// the mass flux rho w constant along the flow (div(rho w) = 0), carrying the
// flux measured on textured parts into them instead of leaving the motion to
// the smoothness term. Over one frame interval we use its exact Lagrangian
// form for the displacement map x -> x + w(x):
//
//   rho1(x + w) det(1 + grad w) = rho0(x)                (mass conservation)
//
// (the Lagrangian form of mass conservation of continuum mechanics, also the
// basis of mass-preserving image registration; Corpetti, Memin & Perez,
// "Dense estimation of fluid flows", IEEE PAMI 24, 2002, use the
// approximation det ~ exp(div w)). It is linearised at each warp of a coarse-to-fine pyramid as
// det(1 + grad w0) div(rho1(x + w0) dw) and solved with
//
//   min  sum W (rho1(x+w) det(1+grad w) - rho0)^2 + alpha sum |grad (w - G(w))|^2
//          + alpha_div sum (div w - xi)^2 + alpha_curl sum (curl w - zeta)^2
//
// where G(w) is the flow smoothed over smoothness_scale and xi, zeta are the
// divergence and vorticity of the flow smoothed over div_curl_scale
// (auxiliary fields updated at each warp): the auxiliary-field
// form of the second-order div-curl regulariser of Suter (CVPR 1994) and
// Corpetti et al. (2002). Why it matters here: mass conservation alone fixes
// only div(rho w), so any w + (1/rho) curl(psi) fits the data as well; those
// spurious solutions carry divergence on the scale of the texture, which the
// div term suppresses while leaving plume-scale spreading free.
//
// Input: column density, or any quantity proportional to it with zero where
// there is no gas (e.g. radiance contrast against the background in the
// optically thin limit). An offset (raw radiance) breaks the equation. Values
// are divided by the pair's standard deviation (over the gas mask when given).
//
// The gas mask does not restrict the data term (mass conservation holds with
// or without gas; where there is none it says nothing): it marks the valid
// output. Gas may enter or leave the image only through the frame's border
// ring and the source mask (set_source_mask), e.g. the stack exit.
//
// quality: exp(-r^2 / 2 s^2), r = local mass-conservation residual, s its
// robust scale over the frame. valid: inside the gas mask, x + w in the frame.
#pragma once

#include <opencv2/video/tracking.hpp>

#include "engine/velocimetry/flow.h"
#include "engine/velocimetry/variational.h"

namespace qogi {

struct FluidFlowOptions {
  // First-order smoothness weight: multiplies sum |grad u|^2 + |grad v|^2
  // (column density in units of the pair's standard deviation). Larger =
  // smoother and less sensitive to noise, but also pulls the velocity of a
  // featureless stretch of plume towards that of its surroundings instead of
  // the one mass conservation carries into it. > 0. Default 0.1.
  double alpha = 0.1;
  // Div-curl regularisation (Corpetti et al. 2002, auxiliary-field form):
  // weight of sum (div w - xi)^2, where xi is the divergence of the current
  // flow smoothed over div_curl_scale. It suppresses divergence on small
  // scales (which the continuity equation alone cannot tell from motion:
  // any w + (1/rho) curl(psi) fits the data equally) while leaving smooth
  // spreading free. >= 0; 0 = off. Default 3.
  double alpha_div = 3.0;
  // Weight of sum (curl w - zeta)^2, zeta the smoothed vorticity. >= 0;
  // 0 = off. Default 0.
  double alpha_curl = 0.0;
  // Scale [px at full resolution] below which divergence and vorticity are
  // penalised (Gaussian sigma of xi and zeta). > 0. Default 8.
  double div_curl_scale = 8.0;
  // Scale [px at full resolution] above which the flow is not smoothed: the
  // smoothness term penalises the gradient of w - G(w) (G a Gaussian of this
  // sigma, taken at the start of each warp, an auxiliary field like the
  // div-curl targets), so that the plume-scale acceleration and deceleration
  // of the gas are left to mass conservation instead of being pulled towards
  // a uniform flow (that pull read the flux 20-30 % lower on the synthetic
  // plume presets; docs/velocimetry.md, "The plume study"). 0 = classic
  // first-order smoothness of w. >= 0. Default 8.
  double smoothness_scale = 8.0;
  // Initialisation by a dense inverse patch search (Kroeger et al., "Fast
  // optical flow using dense inverse search", ECCV 2016; OpenCV's
  // DISOpticalFlow without its variational refinement) before the
  // continuity solve: the search finds the motion of textured parts
  // (rotation, shear, large displacements) at little cost, and the
  // continuity solve then only refines it on its warm_levels finest levels.
  // The search starts from the warm start when there is one; the continuity
  // solve corrects what brightness constancy gets wrong (dilution,
  // spreading, featureless parts). Finest scale of the search (0 = full
  // resolution, 1 = half, ...); -1 = no search (the continuity solve alone,
  // from the warm start or from rest on all levels). [-1, 10]. Default 0.
  int patch_search_scale = 0;
  // Side of the search's square patches [px at the search's scale]. [4, 64].
  // Default 8.
  int patch_size = 8;
  // Distance between neighbouring patches [px at the search's scale];
  // < patch_size. [1, 63]. Default 4.
  int patch_stride = 4;
  // Gradient-descent iterations of each patch. [1, 1000]. Default 16.
  int patch_iterations = 16;
  // Run the search also when warm-started (e.g. in a sequence). When false
  // (the default), a warm-started call refines the warm start on its
  // warm_levels finest levels: the search, blind to mass conservation, reads
  // a steady featureless plume base as at rest and would undo the flux the
  // continuity solve carried into it over the previous pairs (on the 100 Hz
  // CH4 lab plume of tests/python/test_velocimetry_plume.py the fluid flow
  // alone then read -86, -80, -50 and -23 % at 2, 4, 8 and 12 cm instead of
  // -25, -25, -24 and -22 %). Default false.
  bool patch_search_warm = false;
  // Maximum number of pyramid levels (1 = no pyramid); each level halves the
  // size, so ~2^(levels-1) px/frame of motion can be recovered. [1, 12].
  // Default 5.
  int levels = 5;
  // Smallest side of the coarsest level [px]. [4, 4096]. Default 16.
  int min_level_size = 16;
  // Finest level solved (0 = full resolution, 1 = half, ...); the result is
  // interpolated to full resolution. The default, half resolution, resolves
  // velocity on ~2 px and runs ~4x faster than 0. [0, 10], clipped to the
  // coarsest level. Default 1.
  int finest_level = 1;
  // Levels solved when the call starts from the patch search or a warm
  // start (e.g. the previous frame pair in a sequence): the start already
  // holds the large motion, so only the finest warm_levels levels (from
  // finest_level up) refine it; 0 = all levels, as from rest. [0, 12].
  // Default 3.
  int warm_levels = 3;
  // Warps (re-linearisations) per level (three times this on the coarsest
  // level, where the motion is largest in its pixels). [1, 50]. Default 2.
  int warps = 2;
  // Conjugate-gradient iterations per warp (at most) on the finest level
  // solved; each coarser level gets twice as many, up to 8x (a level costs a
  // quarter of the next finer one). [1, 1000]. Default 10.
  int iterations = 10;
  // Early stop of the conjugate gradients (relative residual). [0, 1).
  // Default 1e-3.
  double tolerance = 1e-3;

  void Check() const;
};

class FluidFlow : public OpticalFlow {
 public:
  explicit FluidFlow(const FluidFlowOptions& options = {});
  FlowMethod method() const override { return FlowMethod::kFluid; }
  const FluidFlowOptions& options() const { return options_; }

  // Where gas enters the image (CV_8U, nonzero; empty = nowhere but the
  // frame border): the stack exit, a leak point. Mass conservation is not
  // enforced there (nor on its 4-neighbours), so the flux can come from it.
  // Without it, gas leaving a source inside the frame violates the
  // equation and the velocity right above the source reads low. Kept for
  // the following calls; must have the frames' size.
  void set_source_mask(const cv::Mat& source_mask);
  const cv::Mat& source_mask() const { return source_mask_; }

 protected:
  void CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                   FlowField& flow) override;

 private:
  // Dense inverse search starting from flow.u/v, into flow.u/v; false (flow
  // unchanged) for constant frames.
  bool PatchSearch(const cv::Mat& prev, const cv::Mat& next, FlowField& flow);

  FluidFlowOptions options_;
  cv::Mat source_mask_;
  flow_ops::VariationalSolver solver_;
  cv::Ptr<cv::DISOpticalFlow> search_;
  cv::Mat i08_, i18_, flow2_;
};

}  // namespace qogi
