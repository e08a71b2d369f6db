#include "engine/velocimetry/flow.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "engine/util/check.h"

namespace qogi {

namespace {
constexpr int kMinFrameSide = 16;

std::string SizeText(const cv::Mat& m) {
  return std::to_string(m.cols) + " x " + std::to_string(m.rows);
}
}  // namespace

const char* FlowMethodName(FlowMethod method) {
  switch (method) {
    case FlowMethod::kHornSchunck: return "horn_schunck";
    case FlowMethod::kLucasKanade: return "lucas_kanade";
    case FlowMethod::kFarneback: return "farneback";
    case FlowMethod::kDis: return "dis";
    case FlowMethod::kPiv: return "piv";
    case FlowMethod::kFluid: return "fluid";
  }
  return "unknown";
}

FlowMethod ParseFlowMethod(const std::string& name) {
  for (FlowMethod m : {FlowMethod::kHornSchunck, FlowMethod::kLucasKanade, FlowMethod::kFarneback,
                       FlowMethod::kDis, FlowMethod::kPiv, FlowMethod::kFluid})
    if (name == FlowMethodName(m)) return m;
  throw std::invalid_argument(
      "method must be one of horn_schunck, lucas_kanade, farneback, dis, piv, "
      "fluid; got '" +
      name + "'");
}

bool FlowField::HasSize(cv::Size size) const {
  return u.type() == CV_32FC1 && v.type() == CV_32FC1 && u.size() == size && v.size() == size;
}

void FlowField::Reset(cv::Size size) {
  u.create(size, CV_32FC1);
  v.create(size, CV_32FC1);
  quality.create(size, CV_32FC1);
  valid.create(size, CV_8UC1);
  u.setTo(0);
  v.setTo(0);
  quality.setTo(0);
  valid.setTo(0);
  residual_ratio = std::numeric_limits<double>::quiet_NaN();
}

void OpticalFlow::Calc(const cv::Mat& prev, const cv::Mat& next, FlowField& flow,
                       const cv::Mat& mask) {
  Require(prev.type() == CV_32FC1, "prev must be a float32 single-channel image (CV_32FC1)");
  Require(next.type() == CV_32FC1, "next must be a float32 single-channel image (CV_32FC1)");
  Require(prev.size() == next.size(), "prev and next must have the same size; got " +
                                          SizeText(prev) + " and " + SizeText(next));
  Require(prev.cols >= kMinFrameSide && prev.rows >= kMinFrameSide,
          "frames must be at least " + std::to_string(kMinFrameSide) + " x " +
              std::to_string(kMinFrameSide) + " px; got " + SizeText(prev));
  // One pass: the sum of a frame is finite exactly when all its values are
  // (barring overflow, which the checkRange fallback then tells apart).
  auto finite = [](const cv::Mat& m) { return std::isfinite(cv::sum(m)[0]) || cv::checkRange(m); };
  Require(finite(prev),
          "prev contains NaN or infinite values; replace "
          "them (e.g. by the background) before velocimetry");
  Require(finite(next),
          "next contains NaN or infinite values; replace "
          "them (e.g. by the background) before velocimetry");
  if (!mask.empty()) {
    Require(mask.type() == CV_8UC1,
            "mask must be empty or an 8-bit single-channel image (CV_8UC1)");
    Require(mask.size() == prev.size(),
            "mask must have the frames' size " + SizeText(prev) + "; got " + SizeText(mask));
  }
  const bool warm = flow.HasSize(prev.size()) && finite(flow.u) && finite(flow.v);
  if (!warm) {
    flow.Reset(prev.size());
  } else {
    flow.quality.create(prev.size(), CV_32FC1);
    flow.valid.create(prev.size(), CV_8UC1);
  }
  flow.residual_ratio = std::numeric_limits<double>::quiet_NaN();
  CalcChecked(prev, next, mask, warm, flow);
}

double MetresPerSecondPerPixelPerFrame(double distance_m, double ifov_rad, double frame_rate_hz) {
  CheckPositive(distance_m, "distance_m", "m");
  CheckPositive(ifov_rad, "ifov_rad", "rad");
  CheckPositive(frame_rate_hz, "frame_rate_hz", "Hz");
  return distance_m * ifov_rad * frame_rate_hz;
}

}  // namespace qogi
