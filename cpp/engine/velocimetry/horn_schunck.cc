#include "engine/velocimetry/horn_schunck.h"

#include "engine/util/check.h"

namespace qogi {

void HornSchunckOptions::Check() const {
  CheckPositive(alpha, "HornSchunckOptions.alpha");
  CheckInRange(levels, 1, 12, "HornSchunckOptions.levels");
  CheckInRange(min_level_size, 4, 4096, "HornSchunckOptions.min_level_size", "px");
  CheckInRange(finest_level, 0, 10, "HornSchunckOptions.finest_level");
  CheckInRange(warm_levels, 0, 12, "HornSchunckOptions.warm_levels");
  CheckInRange(warps, 1, 50, "HornSchunckOptions.warps");
  CheckInRange(iterations, 1, 1000, "HornSchunckOptions.iterations");
  CheckInRange(tolerance, 0, 0.999999, "HornSchunckOptions.tolerance");
}

HornSchunckFlow::HornSchunckFlow(const HornSchunckOptions& options) : options_(options) {
  options_.Check();
}

void HornSchunckFlow::CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask,
                                  bool warm, FlowField& flow) {
  flow_ops::VariationalSettings s;
  s.data = flow_ops::DataModel::kBrightness;
  s.alpha = options_.alpha;
  s.levels = options_.levels;
  s.min_level_size = options_.min_level_size;
  s.finest_level = options_.finest_level;
  s.warps = options_.warps;
  s.warm_levels = options_.warm_levels;
  s.iterations = options_.iterations;
  s.tolerance = options_.tolerance;
  solver_.Solve(prev, next, mask, cv::Mat(), warm, s, flow);
}

}  // namespace qogi
