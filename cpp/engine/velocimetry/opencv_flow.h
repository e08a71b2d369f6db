// OpenCV's dense optical-flow methods behind the qogi interface: Farneback
// (polynomial expansion) and DIS (dense inverse search).
//
// Both assume brightness constancy and track texture. Farneback: G.
// Farneback, "Two-frame motion estimation based on polynomial expansion",
// SCIA 2003. DIS: T. Kroeger et al., "Fast optical flow using dense inverse
// search", ECCV 2016 (OpenCV's cv::DISOpticalFlow, with its variational
// refinement). Both are tuned for 8-bit intensities, so frames are scaled to
// 40 grey levels per standard deviation of the pair; DIS needs 8-bit frames:
// value = 128 + 40 (I - mean) / std, clipped to [0, 255] (+-3.2 std).
//
// quality: exp(-r^2 / 2 s^2) of the brightness residual r (see
// QualityFromResidual). valid: inside the gas mask, x + w inside the frame.
#pragma once

#include <opencv2/video/tracking.hpp>

#include "engine/velocimetry/flow.h"

namespace qogi {

struct FarnebackOptions {
  // Scale between pyramid levels (< 1). [0.1, 0.9]. Default 0.5.
  double pyr_scale = 0.5;
  // Number of pyramid levels including the full resolution. [1, 12].
  // Default 5.
  int levels = 5;
  // Averaging window [px]: larger = more robust to noise and faster motion,
  // blurrier motion field. [3, 101]. Default 15.
  int winsize = 15;
  // Iterations per level. [1, 50]. Default 3.
  int iterations = 3;
  // Neighbourhood of the polynomial expansion [px]: 5 or 7. Default 5.
  int poly_n = 5;
  // Gaussian sigma of the polynomial expansion [px]; ~1.1 for poly_n = 5,
  // ~1.5 for 7. [0.5, 5]. Default 1.1.
  double poly_sigma = 1.1;
  // Gaussian (true) or box (false) averaging window. Default true.
  bool gaussian_window = true;

  void Check() const;
};

class FarnebackFlow : public OpticalFlow {
 public:
  explicit FarnebackFlow(const FarnebackOptions& options = {});
  FlowMethod method() const override { return FlowMethod::kFarneback; }
  const FarnebackOptions& options() const { return options_; }

 protected:
  void CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                   FlowField& flow) override;

 private:
  FarnebackOptions options_;
  cv::Mat i0n_, i1n_, i08_, i18_, flow2_;
};

struct DisOptions {
  // Finest pyramid level computed (0 = full resolution; the flow is
  // interpolated above it). [0, 10]. Default 0.
  int finest_scale = 0;
  // Patch size [px]. [4, 64]. Default 8.
  int patch_size = 8;
  // Stride between patches [px], < patch_size. [1, 63]. Default 3.
  int patch_stride = 3;
  // Gradient-descent iterations per patch. [1, 1000]. Default 25.
  int gradient_descent_iterations = 25;
  // Variational refinement iterations per level (0 = none). [0, 1000].
  // Default 5.
  int variational_refinement_iterations = 5;
  // Smoothness weight of the variational refinement. > 0. Default 20.
  double variational_refinement_alpha = 20.0;
  // Colour-constancy weight of the refinement. > 0. Default 5.
  double variational_refinement_delta = 5.0;
  // Gradient-constancy weight of the refinement. >= 0. Default 10.
  double variational_refinement_gamma = 10.0;
  // Normalise each patch's mean (robust to illumination change). Default true.
  bool use_mean_normalization = true;
  // Propagate good patch estimates to neighbours. Default true.
  bool use_spatial_propagation = true;

  void Check() const;
};

class DisFlow : public OpticalFlow {
 public:
  explicit DisFlow(const DisOptions& options = {});
  FlowMethod method() const override { return FlowMethod::kDis; }
  const DisOptions& options() const { return options_; }

 protected:
  void CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                   FlowField& flow) override;

 private:
  DisOptions options_;
  cv::Ptr<cv::DISOpticalFlow> dis_;
  cv::Mat i0n_, i1n_, i08_, i18_, flow2_;
};

}  // namespace qogi
