// The common interface: input checks with clear messages, option checks,
// units, masks, large displacements, warm starts and reproducibility.
#include "engine/velocimetry/flow.h"

#include <gtest/gtest.h>

#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "engine/velocimetry/fluid_flow.h"
#include "engine/velocimetry/horn_schunck.h"
#include "engine/velocimetry/lucas_kanade.h"
#include "engine/velocimetry/moving_texture_test.h"
#include "engine/velocimetry/opencv_flow.h"
#include "engine/velocimetry/piv.h"

namespace qogi {
namespace {

using testing_scenes::Motion;
using testing_scenes::Scene;
using testing_scenes::Texture;

std::vector<std::unique_ptr<OpticalFlow>> AllMethods() {
  std::vector<std::unique_ptr<OpticalFlow>> m;
  m.push_back(std::make_unique<HornSchunckFlow>());
  m.push_back(std::make_unique<LucasKanadeFlow>());
  m.push_back(std::make_unique<FarnebackFlow>());
  m.push_back(std::make_unique<DisFlow>());
  m.push_back(std::make_unique<PivFlow>());
  m.push_back(std::make_unique<FluidFlow>());
  return m;
}

void ExpectInvalidArgument(const std::function<void()>& f, const std::string& words) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one mentioning '" << words << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

// Expects Options, as `edit` changes them, to fail Check() with `words`.
template <typename Options, typename Edit>
void ExpectCheckFails(Edit edit, const std::string& words) {
  ExpectInvalidArgument(
      [&] {
        Options o;
        edit(o);
        o.Check();
      },
      words);
}

TEST(FlowMethod, NamesRoundTrip) {
  for (auto& m : AllMethods()) EXPECT_EQ(ParseFlowMethod(FlowMethodName(m->method())), m->method());
  ExpectInvalidArgument([] { ParseFlowMethod("tvl1"); }, "horn_schunck, lucas_kanade");
}

TEST(Units, PixelsPerFrameToMetresPerSecond) {
  // 3 m away, 1 mrad pixels (3 mm at the plume), 15 Hz: 1 px/frame = 4.5 cm/s.
  EXPECT_DOUBLE_EQ(MetresPerSecondPerPixelPerFrame(3.0, 1e-3, 15.0), 0.045);
  ExpectInvalidArgument([] { MetresPerSecondPerPixelPerFrame(0.0, 1e-3, 15.0); },
                        "distance_m must be finite and > 0 m; got 0 m");
  ExpectInvalidArgument([] { MetresPerSecondPerPixelPerFrame(3.0, -1e-3, 15.0); }, "ifov_rad");
  ExpectInvalidArgument([] { MetresPerSecondPerPixelPerFrame(3.0, 1e-3, std::nan("")); },
                        "frame_rate_hz");
}

TEST(Calc, RejectsBadFramesAndMasksWithClearMessages) {
  FluidFlow flow;
  FlowField f;
  const cv::Mat a = cv::Mat::ones(32, 40, CV_32F);
  ExpectInvalidArgument([&] { flow.Calc(cv::Mat::ones(32, 40, CV_64F), a, f); },
                        "prev must be a float32 single-channel image");
  ExpectInvalidArgument([&] { flow.Calc(a, cv::Mat::ones(32, 41, CV_32F), f); },
                        "same size; got 40 x 32 and 41 x 32");
  ExpectInvalidArgument(
      [&] { flow.Calc(cv::Mat::ones(8, 8, CV_32F), cv::Mat::ones(8, 8, CV_32F), f); },
      "at least 16 x 16 px; got 8 x 8");
  cv::Mat nan = a.clone();
  nan.at<float>(3, 3) = std::numeric_limits<float>::quiet_NaN();
  ExpectInvalidArgument([&] { flow.Calc(a, nan, f); }, "next contains NaN");
  ExpectInvalidArgument([&] { flow.Calc(a, a, f, cv::Mat::ones(32, 40, CV_32F)); },
                        "mask must be empty or an 8-bit");
  ExpectInvalidArgument([&] { flow.Calc(a, a, f, cv::Mat::ones(10, 10, CV_8U)); },
                        "mask must have the frames' size 40 x 32; got 10 x 10");
  flow.set_source_mask(cv::Mat::ones(10, 10, CV_8U));
  ExpectInvalidArgument([&] { flow.Calc(a, a, f); }, "source_mask must have");
}

TEST(Options, OutOfRangeFieldsAreNamed) {
  ExpectCheckFails<HornSchunckOptions>([](auto& o) { o.alpha = 0; }, "HornSchunckOptions.alpha");
  ExpectCheckFails<FluidFlowOptions>([](auto& o) { o.levels = 0; },
                                     "FluidFlowOptions.levels must be within [1, 12]; got 0");
  ExpectCheckFails<FluidFlowOptions>([](auto& o) { o.alpha_div = -1; },
                                     "FluidFlowOptions.alpha_div");
  ExpectCheckFails<LucasKanadeOptions>([](auto& o) { o.window_sigma = 0.1; },
                                       "LucasKanadeOptions.window_sigma");
  ExpectCheckFails<FarnebackOptions>([](auto& o) { o.poly_n = 6; },
                                     "FarnebackOptions.poly_n must be 5 or 7; got 6");
  ExpectCheckFails<DisOptions>([](auto& o) { o.patch_stride = 8; },
                               "DisOptions.patch_stride must be < patch_size");
  ExpectCheckFails<PivOptions>([](auto& o) { o.window_size = 15; },
                               "PivOptions.window_size must be even; got 15");
  ExpectCheckFails<PivOptions>([](auto& o) { o.initial_window_size = 8; },
                               "PivOptions.initial_window_size must be >= window_size");
  // Constructors check too.
  EXPECT_THROW(PivFlow([] {
                 PivOptions o;
                 o.overlap = 0.95;
                 return o;
               }()),
               std::invalid_argument);
}

TEST(Calc, ConstantFramesGiveNoValidVectors) {
  const cv::Mat a(48, 48, CV_32F, cv::Scalar(2.5));
  for (auto& m : AllMethods()) {
    FlowField f;
    m->Calc(a, a, f);
    EXPECT_EQ(cv::countNonZero(f.valid), 0) << FlowMethodName(m->method());
  }
}

TEST(Calc, VectorsOutsideTheGasMaskAreInvalid) {
  const Scene s = testing_scenes::RenderTexture(cv::Size(96, 80), Texture::Make(3),
                                                Motion::Translation(1.0, 0.5), 0.01, 1);
  cv::Mat mask = cv::Mat::zeros(s.prev.size(), CV_8U);
  mask(cv::Rect(20, 10, 50, 50)).setTo(1);
  for (auto& m : AllMethods()) {
    FlowField f;
    m->Calc(s.prev, s.next, f, mask);
    EXPECT_EQ(cv::countNonZero(f.valid & (mask == 0)), 0) << FlowMethodName(m->method());
    EXPECT_GT(cv::countNonZero(f.valid), 0.8 * 50 * 50) << FlowMethodName(m->method());
  }
}

// 24 px/frame (the 15 Hz case near the exit) from a cold start: the pyramids
// of the variational methods reach it on 320 x 256 frames.
TEST(Calc, LargeDisplacementFromAColdStart) {
  const Scene s = testing_scenes::RenderTexture(cv::Size(320, 256), Texture::Make(5),
                                                Motion::Translation(-23.0, 6.5), 0.01, 2);
  std::vector<std::unique_ptr<OpticalFlow>> methods;
  methods.push_back(std::make_unique<HornSchunckFlow>());
  methods.push_back(std::make_unique<FluidFlow>());
  for (auto& m : methods) {
    FlowField f;
    m->Calc(s.prev, s.next, f);
    EXPECT_LT(testing_scenes::MeanEndPointError(f.u, f.v, f.valid, s, 32), 0.1)
        << FlowMethodName(m->method());
  }
}

// Beyond the pyramid's reach, a warm start close to the motion (e.g. the
// previous frame pair's result) is refined by every method.
TEST(Calc, WarmStartIsUsedByEveryMethod) {
  const Scene s = testing_scenes::RenderTexture(cv::Size(192, 160), Texture::Make(5),
                                                Motion::Translation(20.0, -3.0), 0.01, 2);
  for (auto& m : AllMethods()) {
    FlowField f;
    f.Reset(s.prev.size());
    f.u.setTo(19.2);
    f.v.setTo(-2.5);
    m->Calc(s.prev, s.next, f);
    EXPECT_LT(testing_scenes::MeanEndPointError(f.u, f.v, f.valid, s, 32), 0.1)
        << FlowMethodName(m->method());
  }
}

// A smooth ridge (a plume column) with faint texture moving along it at 2
// px/frame: Lucas-Kanade's windows hardly constrain the motion along the
// ridge (aperture problem) and gas leaves through the top border. Over a
// warm-started sequence such vectors must stay near the motion; they used to
// drift and grow without bound (> 100 px/frame after 60 frames).
TEST(Calc, LucasKanadeWarmStartsStayBoundedOnAFaintlyTexturedRidge) {
  const int W = 96, H = 128;
  const Texture tex = Texture::Make(11, 64, 8.0, 48.0);
  cv::RNG rng(7);
  auto frame = [&](int t, cv::Mat& out) {
    out.create(H, W, CV_32F);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const double ridge = std::exp(-0.5 * std::pow((x - 48.0) / 4.0, 2));
        out.at<float>(y, x) =
            static_cast<float>(ridge * (1.0 + 0.02 * tex(x, y + 2.0 * t)) + rng.gaussian(1e-4));
      }
  };
  LucasKanadeFlow lk;
  FlowField f;
  cv::Mat prev, next;
  frame(0, prev);
  double worst = 0;
  for (int t = 1; t <= 60; ++t) {
    frame(t, next);
    lk.Calc(prev, next, f);  // warm-started from the previous pair after t = 1
    double lo, hi;
    cv::minMaxLoc(f.v, &lo, &hi);
    worst = std::max({worst, std::abs(lo), std::abs(hi)});
    std::swap(prev, next);
  }
  EXPECT_LT(worst, 10.0);
}

TEST(Calc, FluidIsReproducibleWhateverTheThreadCount) {
  const Scene s = testing_scenes::RenderTexture(cv::Size(192, 160), Texture::Make(9),
                                                Motion::Rotation(0.02, 90, 70), 0.01, 4);
  const int threads = cv::getNumThreads();
  FlowField a, b;
  cv::setNumThreads(1);
  FluidFlow().Calc(s.prev, s.next, a);
  cv::setNumThreads(std::max(2, threads));
  FluidFlow().Calc(s.prev, s.next, b);
  cv::setNumThreads(threads);
  EXPECT_EQ(cv::norm(a.u, b.u, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.v, b.v, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace qogi
