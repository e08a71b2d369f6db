// The fluid flow's start: a dense inverse patch search between the coarse
// continuity levels and the finest one resolves rotation and shear of weakly
// textured column fields (issue 20), and its options are checked on entry.
#include <gtest/gtest.h>

#include <stdexcept>

#include "engine/velocimetry/fluid_flow.h"
#include "engine/velocimetry/moving_texture_test.h"

namespace qogi {
namespace {

using testing_scenes::Motion;
using testing_scenes::Scene;
using testing_scenes::Texture;

// A plume-like column (Gaussian envelope of 50 px, texture +-20 %, 0.5 %
// noise) on 192 x 160, moved by an exact mass-conserving map.
Scene Blob(const Motion& m) {
  return testing_scenes::RenderDensity(cv::Size(192, 160), Texture::Make(11), m, 96, 80, 50, 0.005,
                                       5, 0.2);
}

double Epe(OpticalFlow& method, const Scene& s) {
  FlowField f;
  method.Calc(s.prev, s.next, f);
  return testing_scenes::MeanEndPointError(f.u, f.v, f.valid, s, 32);
}

// Rotation and shear of a weakly textured column, from a cold start: the
// search's start brings the continuity solve to 0.03-0.04 px (without it:
// 0.17, 0.09 and 0.11 px, its CG under-converged on the weak texture).
TEST(FluidFlow, PatchSearchStartResolvesRotationAndShearOfAWeakTexture) {
  const Motion motions[] = {Motion::Rotation(0.02, 96, 80),
                            Motion::DriftingVortex(1.5, 96, 80, 30, 1.0, 0.5),
                            Motion::JetShear(2.5, 80, 20)};
  for (const Motion& m : motions) {
    const Scene s = Blob(m);
    FluidFlow with_search;
    FluidFlowOptions o;
    o.patch_search_scale = -1;
    FluidFlow without_search(o);
    const double e = Epe(with_search, s);
    EXPECT_LT(e, 0.05);
    EXPECT_LT(e, Epe(without_search, s));
  }
}

// The vorticity term (off by default) penalises only vorticity that varies
// on short scales: a rotation (uniform vorticity) is followed with it at
// least as well as without, from a cold start and when a warm start is
// refined on the warm_levels finest levels (which read 0.03 / 0.17 px
// without the term, 0.02 / 0.10 px with it). Both paths of the solver's
// curl buffers (written only with the term on) are exercised.
TEST(FluidFlow, VorticityTermLeavesARotationFree) {
  const Scene s = Blob(Motion::Rotation(0.02, 96, 80));
  double cold[2], warm[2];
  for (const int with_curl : {0, 1}) {
    FluidFlowOptions o;
    o.alpha_curl = with_curl;
    FluidFlow flow(o);
    FlowField f;
    flow.Calc(s.prev, s.next, f);
    cold[with_curl] = testing_scenes::MeanEndPointError(f.u, f.v, f.valid, s, 32);
    flow.Calc(s.prev, s.next, f);  // warm start: the result above
    warm[with_curl] = testing_scenes::MeanEndPointError(f.u, f.v, f.valid, s, 32);
    EXPECT_LT(cold[with_curl], 0.05) << with_curl;
    EXPECT_LT(warm[with_curl], 0.25) << with_curl;
  }
  EXPECT_LE(cold[1], cold[0]);
  EXPECT_LE(warm[1], warm[0]);
}

TEST(FluidFlow, PatchSearchOptionsAreChecked) {
  FluidFlowOptions o;
  o.patch_stride = o.patch_size;
  EXPECT_THROW(FluidFlow{o}, std::invalid_argument);
  o = FluidFlowOptions{};
  o.patch_search_scale = -2;
  EXPECT_THROW(FluidFlow{o}, std::invalid_argument);
  o = FluidFlowOptions{};
  o.patch_size = 3;
  EXPECT_THROW(FluidFlow{o}, std::invalid_argument);
  o = FluidFlowOptions{};
  o.patch_iterations = 0;
  EXPECT_THROW(FluidFlow{o}, std::invalid_argument);
}

}  // namespace
}  // namespace qogi
