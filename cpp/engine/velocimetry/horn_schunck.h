// Horn-Schunck optical flow, coarse to fine with warping (own implementation;
// OpenCV 4 has none).
//
// Brightness constancy I1(x + w) = I0(x), linearised around the current flow
// at each warp, with a quadratic smoothness term (Horn & Schunck, "Determining
// optical flow", Artificial Intelligence 17, 1981), embedded in an image
// pyramid with warping ("classic" method of Sun, Roth & Black, "Secrets of
// optical flow estimation and their principles", CVPR 2010). Each warp solves
//
//   min_dw  sum W (I1(x+w0) - I0 + grad I . dw)^2 + alpha sum |grad(w0+dw)|^2
//
// by preconditioned conjugate gradients. Intensities are in units of the frame
// pair's standard deviation (over the gas mask when given), gradients per px.
//
// Use it for: textured radiance or column-density frames, small to moderate
// motion. It tracks texture (brightness patterns), so in a spreading or
// diluting plume it is biased; prefer FluidFlow on column density.
//
// quality: exp(-r^2 / 2 s^2), r = local |I1(x+w) - I0(x)|, s = robust scale of
// r over the frame. valid: inside the gas mask and x + w inside the frame.
#pragma once

#include "engine/velocimetry/flow.h"
#include "engine/velocimetry/variational.h"

namespace qogi {

struct HornSchunckOptions {
  // Smoothness weight: multiplies sum |grad u|^2 + |grad v|^2 (intensities in
  // units of the pair's standard deviation). Larger = smoother, slower to
  // follow sharp velocity changes. > 0. Default 0.3.
  double alpha = 0.3;
  // Maximum number of pyramid levels (1 = no pyramid); each level halves the
  // size. The motion a level can recover is ~1-2 px, i.e. ~2^(levels-1) px at
  // full resolution. [1, 12]. Default 5.
  int levels = 5;
  // Smallest side of the coarsest level [px]: fewer levels are used when the
  // frame is small. [4, 4096]. Default 16.
  int min_level_size = 16;
  // Finest level solved (0 = full resolution, 1 = half, ...); the result is
  // interpolated to full resolution. Trades resolution for speed. [0, 10],
  // clipped to the coarsest level. Default 0.
  int finest_level = 0;
  // Levels solved when the call is warm-started (e.g. by the previous frame
  // pair in a sequence): the warm start already holds the large motion, so
  // only the finest warm_levels levels (from finest_level up) refine it;
  // 0 = all levels, as from a cold start. [0, 12]. Default 3.
  int warm_levels = 3;
  // Warps (re-linearisations) per level (three times this on the coarsest
  // level, where the motion is largest in its pixels). [1, 50]. Default 3.
  int warps = 3;
  // Conjugate-gradient iterations per warp (at most) on the finest level
  // solved; each coarser level gets twice as many, up to 8x (a level costs a
  // quarter of the next finer one). [1, 1000]. Default 20.
  int iterations = 20;
  // Conjugate gradients stop early when the residual norm falls below this
  // fraction of the right-hand side's. [0, 1). Default 1e-3.
  double tolerance = 1e-3;

  // Throws std::invalid_argument naming the first field out of range.
  void Check() const;
};

class HornSchunckFlow : public OpticalFlow {
 public:
  explicit HornSchunckFlow(const HornSchunckOptions& options = {});
  FlowMethod method() const override { return FlowMethod::kHornSchunck; }
  const HornSchunckOptions& options() const { return options_; }

 protected:
  void CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                   FlowField& flow) override;

 private:
  HornSchunckOptions options_;
  flow_ops::VariationalSolver solver_;
};

}  // namespace qogi
