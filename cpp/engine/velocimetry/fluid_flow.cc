#include "engine/velocimetry/fluid_flow.h"

#include "engine/util/check.h"

namespace qogi {

void FluidFlowOptions::Check() const {
  CheckPositive(alpha, "FluidFlowOptions.alpha");
  CheckNonNegative(alpha_div, "FluidFlowOptions.alpha_div");
  CheckNonNegative(alpha_curl, "FluidFlowOptions.alpha_curl");
  CheckPositive(div_curl_scale, "FluidFlowOptions.div_curl_scale", "px");
  CheckNonNegative(smoothness_scale, "FluidFlowOptions.smoothness_scale", "px");
  CheckInRange(levels, 1, 12, "FluidFlowOptions.levels");
  CheckInRange(min_level_size, 4, 4096, "FluidFlowOptions.min_level_size", "px");
  CheckInRange(finest_level, 0, 10, "FluidFlowOptions.finest_level");
  CheckInRange(warm_levels, 0, 12, "FluidFlowOptions.warm_levels");
  CheckInRange(warps, 1, 50, "FluidFlowOptions.warps");
  CheckInRange(iterations, 1, 1000, "FluidFlowOptions.iterations");
  CheckInRange(tolerance, 0, 0.999999, "FluidFlowOptions.tolerance");
}

FluidFlow::FluidFlow(const FluidFlowOptions& options) : options_(options) {
  options_.Check();
}

void FluidFlow::set_source_mask(const cv::Mat& source_mask) {
  Require(source_mask.empty() || source_mask.type() == CV_8UC1,
          "source_mask must be empty or an 8-bit single-channel mask (CV_8UC1)");
  source_mask_ = source_mask.clone();
}

void FluidFlow::CalcChecked(const cv::Mat& prev, const cv::Mat& next,
                            const cv::Mat& mask, bool warm, FlowField& flow) {
  Require(source_mask_.empty() || source_mask_.size() == prev.size(),
          "source_mask must have the frames' size " + std::to_string(prev.cols) + " x " +
              std::to_string(prev.rows) + "; got " + std::to_string(source_mask_.cols) +
              " x " + std::to_string(source_mask_.rows));
  flow_ops::VariationalSettings s;
  s.data = flow_ops::DataModel::kContinuity;
  s.alpha = options_.alpha;
  s.alpha_div = options_.alpha_div;
  s.alpha_curl = options_.alpha_curl;
  s.div_curl_scale = options_.div_curl_scale;
  s.smoothness_scale = options_.smoothness_scale;
  s.levels = options_.levels;
  s.min_level_size = options_.min_level_size;
  s.finest_level = options_.finest_level;
  s.warps = options_.warps;
  s.warm_levels = options_.warm_levels;
  s.iterations = options_.iterations;
  s.tolerance = options_.tolerance;
  // The mask only marks valid output here: the scaling (hence the balance of
  // data and regularisation) must not depend on it either.
  s.scale_over_mask = false;
  solver_.Solve(prev, next, mask, source_mask_, warm, s, flow);
}

}  // namespace qogi
