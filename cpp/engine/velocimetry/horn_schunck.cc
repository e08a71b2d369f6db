#include "engine/velocimetry/horn_schunck.h"

#include "engine/util/check.h"

namespace qogi {

void HornSchunckOptions::Check() const {
  CheckPositive(alpha, "HornSchunckOptions.alpha");
  flow_ops::CheckPyramidFields(*this, "HornSchunckOptions");
}

HornSchunckFlow::HornSchunckFlow(const HornSchunckOptions& options) : options_(options) {
  options_.Check();
}

void HornSchunckFlow::CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask,
                                  bool warm, FlowField& flow) {
  const flow_ops::VariationalSettings s =
      flow_ops::PyramidSettings(options_, flow_ops::DataModel::kBrightness);
  solver_.Solve(prev, next, mask, cv::Mat(), warm, s, flow);
}

}  // namespace qogi
