#include "engine/velocimetry/fluid_flow.h"

#include <algorithm>
#include <cmath>

#include "engine/util/check.h"
#include "engine/velocimetry/image_ops.h"

namespace qogi {

void FluidFlowOptions::Check() const {
  CheckPositive(alpha, "FluidFlowOptions.alpha");
  CheckNonNegative(alpha_div, "FluidFlowOptions.alpha_div");
  CheckNonNegative(alpha_curl, "FluidFlowOptions.alpha_curl");
  CheckPositive(div_curl_scale, "FluidFlowOptions.div_curl_scale", "px");
  CheckNonNegative(smoothness_scale, "FluidFlowOptions.smoothness_scale", "px");
  CheckInRange(patch_search_scale, -1, 10, "FluidFlowOptions.patch_search_scale");
  flow_ops::CheckPatchGrid(patch_size, patch_stride, "FluidFlowOptions");
  CheckInRange(patch_iterations, 1, 1000, "FluidFlowOptions.patch_iterations");
  flow_ops::CheckPyramidFields(*this, "FluidFlowOptions");
}

FluidFlow::FluidFlow(const FluidFlowOptions& options) : options_(options) {
  options_.Check();
  if (options_.patch_search_scale >= 0) {
    search_ = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_ULTRAFAST);
    search_->setFinestScale(options_.patch_search_scale);
    search_->setPatchSize(options_.patch_size);
    search_->setPatchStride(options_.patch_stride);
    search_->setGradientDescentIterations(options_.patch_iterations);
    search_->setVariationalRefinementIterations(0);  // the continuity solve refines
    search_->setUseMeanNormalization(true);
    search_->setUseSpatialPropagation(true);
  }
}

void FluidFlow::set_source_mask(const cv::Mat& source_mask) {
  Require(source_mask.empty() || source_mask.type() == CV_8UC1,
          "source_mask must be empty or an 8-bit single-channel mask (CV_8UC1)");
  source_mask_ = source_mask.clone();
}

void FluidFlow::CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask,
                            bool warm, FlowField& flow) {
  Require(source_mask_.empty() || source_mask_.size() == prev.size(),
          "source_mask must have the frames' size " + std::to_string(prev.cols) + " x " +
              std::to_string(prev.rows) + "; got " + std::to_string(source_mask_.cols) + " x " +
              std::to_string(source_mask_.rows));
  flow_ops::VariationalSettings s =
      flow_ops::PyramidSettings(options_, flow_ops::DataModel::kContinuity);
  s.alpha_div = options_.alpha_div;
  s.alpha_curl = options_.alpha_curl;
  s.div_curl_scale = options_.div_curl_scale;
  s.smoothness_scale = options_.smoothness_scale;
  // The mask only marks valid output here: the scaling (hence the balance of
  // data and regularisation) must not depend on it either.
  s.scale_over_mask = false;
  if (search_ && (!warm || options_.patch_search_warm)) {
    if (!warm) {
      // From rest: the continuity solve's coarser levels find the large
      // motion, from which the search starts. They cost a sixteenth of the
      // finest level and up: four times the iterations, which a 24 px/frame
      // motion needs from rest on 320 x 256 (flow_test.cc).
      flow_ops::VariationalSettings coarse = s;
      coarse.finest_level = s.finest_level + 1;
      coarse.iterations = 4 * s.iterations;
      solver_.Solve(prev, next, mask, source_mask_, false, coarse, flow);
    }
    if (PatchSearch(prev, next, flow)) {
      // The search holds the motion down to its patches' scale: the
      // continuity solve refines it on the finest level only (its coarser
      // levels would replace the search's detail with their own, coarser
      // solution).
      s.warm_levels = 1;
      warm = true;
    }
  }
  solver_.Solve(prev, next, mask, source_mask_, warm, s, flow);
}

bool FluidFlow::PatchSearch(const cv::Mat& prev, const cv::Mat& next, FlowField& flow) {
  // 8-bit frames spanning the pair's range (the search's patches are mean-
  // normalised, so only the contrast matters; a column field's plume must
  // not saturate).
  double lo0, hi0, lo1, hi1;
  cv::minMaxLoc(prev, &lo0, &hi0);
  cv::minMaxLoc(next, &lo1, &hi1);
  const double lo = std::min(lo0, lo1), hi = std::max(hi0, hi1);
  if (!(hi > lo) || !std::isfinite(hi - lo)) return false;
  const double scale = 255.0 / (hi - lo);
  prev.convertTo(i08_, CV_8U, scale, -lo * scale);
  next.convertTo(i18_, CV_8U, scale, -lo * scale);
  cv::Mat start[] = {flow.u, flow.v};
  cv::merge(start, 2, flow2_);
  search_->calc(i08_, i18_, flow2_);
  cv::Mat parts[] = {flow.u, flow.v};
  cv::split(flow2_, parts);
  return true;
}

}  // namespace qogi
