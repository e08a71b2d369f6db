#include "engine/velocimetry/opencv_flow.h"

#include <opencv2/imgproc.hpp>

#include "engine/util/check.h"
#include "engine/velocimetry/image_ops.h"

namespace qogi {

using namespace flow_ops;

namespace {

void Merge(const cv::Mat& u, const cv::Mat& v, cv::Mat& uv) {
  cv::Mat parts[] = {u, v};
  cv::merge(parts, 2, uv);
}

void Split(const cv::Mat& uv, FlowField& flow) {
  cv::Mat parts[] = {flow.u, flow.v};
  cv::split(uv, parts);
  flow.u = parts[0];
  flow.v = parts[1];
}

void Finish(const cv::Mat& i0, const cv::Mat& i1, const cv::Mat& mask, FlowField& flow) {
  flow.valid.setTo(1);
  ApplyMask(mask, flow.u, flow.v, flow.valid);
  FinishWithBrightnessResidual(i0, i1, flow);
}

}  // namespace

void FarnebackOptions::Check() const {
  CheckInRange(pyr_scale, 0.1, 0.9, "FarnebackOptions.pyr_scale");
  CheckInRange(levels, 1, 12, "FarnebackOptions.levels");
  CheckInRange(winsize, 3, 101, "FarnebackOptions.winsize", "px");
  CheckInRange(iterations, 1, 50, "FarnebackOptions.iterations");
  Require(poly_n == 5 || poly_n == 7,
          "FarnebackOptions.poly_n must be 5 or 7; got " + std::to_string(poly_n));
  CheckInRange(poly_sigma, 0.5, 5, "FarnebackOptions.poly_sigma", "px");
}

FarnebackFlow::FarnebackFlow(const FarnebackOptions& options) : options_(options) {
  options_.Check();
}

void FarnebackFlow::CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask,
                                bool warm, FlowField& flow) {
  if (!NormalisePair(prev, next, mask, i0n_, i1n_, flow)) return;
  const FarnebackOptions& o = options_;
  int flags = o.gaussian_window ? cv::OPTFLOW_FARNEBACK_GAUSSIAN : 0;
  if (warm) {
    Merge(flow.u, flow.v, flow2_);
    flags |= cv::OPTFLOW_USE_INITIAL_FLOW;
  }
  // Farneback's solver adds a fixed 1e-3 to its determinants, tuned for
  // 8-bit intensities: feed it the frames at 40 grey levels per std.
  i0n_.convertTo(i08_, CV_32F, 40.0);
  i1n_.convertTo(i18_, CV_32F, 40.0);
  cv::calcOpticalFlowFarneback(i08_, i18_, flow2_, o.pyr_scale, o.levels, o.winsize, o.iterations,
                               o.poly_n, o.poly_sigma, flags);
  Split(flow2_, flow);
  Finish(i0n_, i1n_, mask, flow);
}

void DisOptions::Check() const {
  CheckInRange(finest_scale, 0, 10, "DisOptions.finest_scale");
  flow_ops::CheckPatchGrid(patch_size, patch_stride, "DisOptions");
  CheckInRange(gradient_descent_iterations, 1, 1000, "DisOptions.gradient_descent_iterations");
  CheckInRange(variational_refinement_iterations, 0, 1000,
               "DisOptions.variational_refinement_iterations");
  CheckPositive(variational_refinement_alpha, "DisOptions.variational_refinement_alpha");
  CheckPositive(variational_refinement_delta, "DisOptions.variational_refinement_delta");
  CheckNonNegative(variational_refinement_gamma, "DisOptions.variational_refinement_gamma");
}

DisFlow::DisFlow(const DisOptions& options) : options_(options) {
  options_.Check();
  dis_ = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM);
  dis_->setFinestScale(options_.finest_scale);
  dis_->setPatchSize(options_.patch_size);
  dis_->setPatchStride(options_.patch_stride);
  dis_->setGradientDescentIterations(options_.gradient_descent_iterations);
  dis_->setVariationalRefinementIterations(options_.variational_refinement_iterations);
  dis_->setVariationalRefinementAlpha(static_cast<float>(options_.variational_refinement_alpha));
  dis_->setVariationalRefinementDelta(static_cast<float>(options_.variational_refinement_delta));
  dis_->setVariationalRefinementGamma(static_cast<float>(options_.variational_refinement_gamma));
  dis_->setUseMeanNormalization(options_.use_mean_normalization);
  dis_->setUseSpatialPropagation(options_.use_spatial_propagation);
}

void DisFlow::CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                          FlowField& flow) {
  double mean = 0;
  if (!NormalisePair(prev, next, mask, i0n_, i1n_, flow, &mean)) return;
  // 8-bit frames: 40 grey levels per standard deviation around the mean.
  i0n_.convertTo(i08_, CV_8U, 40.0, 128.0 - 40.0 * mean);
  i1n_.convertTo(i18_, CV_8U, 40.0, 128.0 - 40.0 * mean);
  if (warm) {
    Merge(flow.u, flow.v, flow2_);
  } else {
    flow2_.release();
  }
  dis_->calc(i08_, i18_, flow2_);
  Split(flow2_, flow);
  Finish(i0n_, i1n_, mask, flow);
}

}  // namespace qogi
