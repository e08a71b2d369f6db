// Moving-texture tests: every method recovers the known motion of a
// band-limited random texture (translation, rotation, a jet-like shear layer)
// at 1-3 px/frame, with 1 % seeded noise, to better than 0.1 px mean
// end-point error.
#include <gtest/gtest.h>

#include <memory>
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

const cv::Size kSize(192, 160);
constexpr int kMargin = 16;  // border strip left out (texture enters/leaves)

std::unique_ptr<OpticalFlow> MakeMethod(FlowMethod m) {
  switch (m) {
    case FlowMethod::kHornSchunck: return std::make_unique<HornSchunckFlow>();
    case FlowMethod::kLucasKanade: return std::make_unique<LucasKanadeFlow>();
    case FlowMethod::kFarneback: return std::make_unique<FarnebackFlow>();
    case FlowMethod::kDis: return std::make_unique<DisFlow>();
    case FlowMethod::kPiv: return std::make_unique<PivFlow>();
    case FlowMethod::kFluid: return std::make_unique<FluidFlow>();
  }
  return nullptr;
}

struct MotionCase {
  const char* name;
  Motion motion;
};

const std::vector<MotionCase>& Motions() {
  static const std::vector<MotionCase> cases = {
      {"translation_1px", Motion::Translation(0.8, -0.6)},
      {"translation_3px", Motion::Translation(2.4, 1.8)},
      // 3 px/frame at the corners
      {"rotation", Motion::Rotation(3.0 / 125.0, 96, 80)},
      {"jet_shear", Motion::JetShear(2.5, 80, 25)},
  };
  return cases;
}

const Scene& SceneFor(int i) {
  static std::vector<Scene> scenes;
  if (scenes.empty()) {
    const Texture t = Texture::Make(7);
    for (const auto& c : Motions())
      scenes.push_back(testing_scenes::RenderTexture(kSize, t, c.motion, 0.01, 3));
  }
  return scenes[i];
}

class MovingTexture : public ::testing::TestWithParam<std::tuple<FlowMethod, int>> {};

TEST_P(MovingTexture, MeanEndPointErrorBelowATenthOfAPixel) {
  const auto [method, motion] = GetParam();
  const Scene& s = SceneFor(motion);
  auto flow = MakeMethod(method);
  FlowField f;
  flow->Calc(s.prev, s.next, f);
  double valid_fraction = 0;
  const double epe =
      testing_scenes::MeanEndPointError(f.u, f.v, f.valid, s, kMargin, &valid_fraction);
  EXPECT_LT(epe, 0.1) << FlowMethodName(method) << " on " << Motions()[motion].name;
  EXPECT_GT(valid_fraction, 0.95);
  double qmin, qmax;
  cv::minMaxLoc(f.quality, &qmin, &qmax);
  EXPECT_GE(qmin, 0.0);
  EXPECT_LE(qmax, 1.0);
  EXPECT_LT(f.residual_ratio, 0.2);  // the motion explains the change
}

INSTANTIATE_TEST_SUITE_P(
    AllMethods, MovingTexture,
    ::testing::Combine(::testing::Values(FlowMethod::kHornSchunck, FlowMethod::kLucasKanade,
                                         FlowMethod::kFarneback, FlowMethod::kDis, FlowMethod::kPiv,
                                         FlowMethod::kFluid),
                       ::testing::Range(0, 4)),
    [](const ::testing::TestParamInfo<std::tuple<FlowMethod, int>>& info) {
      return std::string(FlowMethodName(std::get<0>(info.param))) + "_" +
             Motions()[std::get<1>(info.param)].name;
    });

}  // namespace
}  // namespace qogi
