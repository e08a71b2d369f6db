// Dense pyramidal Lucas-Kanade optical flow (own implementation).
//
// At every pixel, the displacement that best satisfies brightness constancy
// I1(x + w) = I0(x) in the least-squares sense over a Gaussian window of
// standard deviation window_sigma, assuming w constant in the window (Lucas &
// Kanade, "An iterative image registration technique ...", IJCAI 1981; the
// pyramid after Bouguet, "Pyramidal implementation of the Lucas Kanade
// feature tracker", Intel 2000). Each iteration solves, per pixel,
//
//   [Sxx Sxy; Sxy Syy] dw = -[G*(Ix It); G*(Iy It)],  S = G * (grad I0 grad I0^T)
//
// with G the Gaussian window and It = I1(x + w) - I0(x).
//
// Use it for: well-textured frames, quick local estimates; it needs texture
// in every window (aperture problem) and, like every brightness-constancy
// method, is biased where the plume spreads or dilutes.
//
// quality: lambda_min / (lambda_min + min_eigenvalue), lambda_min the smaller
// eigenvalue of the window's structure tensor S (0.5 at the threshold).
// valid: lambda_min >= min_eigenvalue, inside the gas mask, x + w in frame.
// Where lambda_min < min_eigenvalue the vector keeps its start (the warm
// start, or 0): the window does not determine it.
#pragma once

#include "engine/velocimetry/flow.h"

#include <vector>

namespace qogi {

struct LucasKanadeOptions {
  // Standard deviation of the Gaussian window [px] on every pyramid level.
  // Larger = more robust and smoother, less resolution. [0.5, 50].
  // Default 3.
  double window_sigma = 3.0;
  // Maximum number of pyramid levels (1 = none). [1, 12]. Default 5.
  int levels = 5;
  // Smallest side of the coarsest level [px]: a level must be several
  // windows wide, or its estimates near the border go astray and the finer
  // levels cannot recover. [4, 4096]. Default 32.
  int min_level_size = 32;
  // Finest level solved (0 = full resolution). [0, 10]. Default 0.
  int finest_level = 0;
  // Iterations (warps) per level. [1, 50]. Default 4.
  int iterations = 4;
  // Smallest eigenvalue of the structure tensor for a valid vector, in
  // (intensity / pair standard deviation / px)^2. > 0. Default 1e-3.
  double min_eigenvalue = 1e-3;

  void Check() const;
};

class LucasKanadeFlow : public OpticalFlow {
 public:
  explicit LucasKanadeFlow(const LucasKanadeOptions& options = {});
  FlowMethod method() const override { return FlowMethod::kLucasKanade; }
  const LucasKanadeOptions& options() const { return options_; }

 protected:
  void CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                   FlowField& flow) override;

 private:
  LucasKanadeOptions options_;
  cv::Mat i0n_, i1n_, u_, v_, un_, vn_, warped_, gx_, gy_, sxx_, sxy_, syy_, bx_, by_;
  cv::Mat start_u_, start_v_, inside_;
  std::vector<cv::Mat> p0_, p1_;
};

}  // namespace qogi
