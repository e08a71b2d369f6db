// Registration: bring frames to a common geometry (a vibrating tripod) and a
// common time (a filter wheel that sees each channel at its own instant).
//
// Rigid registration of a frame to a reference of the static scene:
//
//   the frame's content at W(x; p) equals the reference's at x, with
//   W(x; p) = R(angle) (x - c) + c + (dx, dy),
//
// x in pixels (x right, y down, origin at the top-left pixel centre), c the
// image centre, angle positive from +x towards +y (clockwise on screen). p is
// estimated by robust inverse-compositional Gauss-Newton (Baker & Matthews
// 2004, "Lucas-Kanade 20 years on", sec. 3.2, with iteratively reweighted
// least squares, their sec. 4.1 of part 2): Tukey's biweight on the residual
// in units of its robust spread leaves out what moves on its own (the gas).
// Its covariance sigma^2 H^-1 says how well the scene's texture fixes each
// parameter: a sky with only a vertical gradient fixes dy but not dx.
//
// Usage:
//   qogi::FrameRegistration reg(reference, cv::Mat(), qogi::RegistrationOptions{});
//   qogi::RegistrationResult r = reg.Register(frame);
//   cv::Mat stable;
//   qogi::WarpToReference(frame, r.shift, &stable);   // frame in the reference's geometry
#pragma once

#include <opencv2/core.hpp>

namespace qogi {

// A rigid motion of the image (see the top of this file).
struct RigidShift {
  double dx_px = 0.0;      // shift to the right [px]
  double dy_px = 0.0;      // shift downwards [px]
  double angle_rad = 0.0;  // rotation about the image centre [rad], +x towards +y
};

struct RegistrationOptions {
  // Also estimate a rotation about the image centre (default true).
  bool rotation = true;
  // Gauss-Newton iterations at most, 1-200 (default 30).
  int max_iterations = 30;
  // Stop when an update moves no pixel by more than this [px], > 0 (default 1e-3).
  double tolerance_px = 1e-3;
  // Tukey biweight cut-off in units of the residual's robust spread, > 0
  // (default 4.685: 95 % efficiency on Gaussian noise).
  double robust_scale = 4.685;
  // Pixels along each image edge left out of the fit, >= 0 (default 4):
  // resampling near the edge replicates the border.
  int border_px = 4;
  // A frame whose shift exceeds this is reported not converged [px], > 0 (default 8).
  double max_shift_px = 8.0;
  // Gaussian smoothing of reference and frame before the fit [px sigma], >= 0
  // (default 1): interpolation smooths a frame by an amount that depends on
  // its fractional shift, which pulls unsmoothed estimates towards whole
  // pixels ("pixel locking"); smoothing first removes the detail it acts on.
  double smoothing_px = 1.0;

  // Throws std::invalid_argument naming the first bad field.
  void Check() const;
};

struct RegistrationResult {
  RigidShift shift;              // the estimate
  RigidShift sigma;              // its 1-sigma precision (same units)
  double residual_sigma = 0.0;  // robust spread of the residual after registration [image units]
  double inlier_fraction = 0.0;  // fraction of the fitted pixels with nonzero weight
  int iterations = 0;
  bool converged = false;  // the update fell below tolerance_px within max_shift_px
};

// Registers frames of one scene to its reference.
class FrameRegistration {
 public:
  // `reference`: CV_32F or CV_64F single-channel image of the static scene
  // (e.g. a temporal median); `mask`: empty or CV_8U of the same size, nonzero
  // where pixels may be used. Throws std::invalid_argument on bad input.
  FrameRegistration(const cv::Mat& reference, const cv::Mat& mask,
                    const RegistrationOptions& options);

  // The rigid motion of `frame` (same size and type family as the reference)
  // relative to the reference, starting from `start`.
  RegistrationResult Register(const cv::Mat& frame, const RigidShift& start = {}) const;

  // The 1-sigma precision of each parameter for white noise of
  // `noise_sigma` [image units] per pixel in the frame (all pixels inliers):
  // sqrt(diag(noise_sigma^2 H^-1)); a parameter the texture does not fix
  // comes out large (infinite when the scene is uniform).
  RigidShift Precision(double noise_sigma) const;

  const RegistrationOptions& options() const { return options_; }

 private:
  RegistrationOptions options_;
  cv::Mat ref_;  // CV_32F
  cv::Mat jac_[3];  // steepest-descent images: d ref / d (dx, dy, angle * radius)
  cv::Mat use_;  // CV_8U, the pixels fitted
  double radius_px_ = 1.0;  // scale of the angle parameter (half the diagonal)
};

// `frame` resampled into the reference's geometry: out(x) = frame(W(x; shift))
// (bicubic; outside the frame the border is replicated). CV_32F in and out;
// out may not alias frame.
void WarpToReference(const cv::Mat& frame, const RigidShift& shift, cv::Mat* out);

// `frame` moved along a displacement field: out(x) = frame(x + scale * (u, v)(x))
// (bicubic, border replicated). u, v [px] CV_32F of the frame's size. With
// (u, v) the gas's displacement per frame interval and scale = the channel's
// time offset / the frame interval, this brings a channel seen `offset`
// after (before, negative) the frame's time to the frame's time.
void WarpAlongFlow(const cv::Mat& frame, const cv::Mat& u, const cv::Mat& v, double scale,
                   cv::Mat* out);

}  // namespace qogi
