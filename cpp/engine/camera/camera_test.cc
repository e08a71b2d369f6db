#include "engine/camera/camera.h"

#include "engine/optics/planck.h"

#include <gtest/gtest.h>

#include <cmath>

namespace qogi {
namespace {

TEST(CameraPresets, AllPresetsAreValidAndNamed) {
  for (const auto& name : CameraPresetNames()) {
    const CameraModel c = CameraPreset(name);
    EXPECT_EQ(c.name, name);
    EXPECT_FALSE(c.description.empty());
  }
  EXPECT_THROW(CameraPreset("gf999"), std::invalid_argument);
}

TEST(CameraPresets, Gf320MatchesItsDatasheet) {
  const CameraModel c = CameraPreset("gf320");
  EXPECT_EQ(c.width, 320);
  EXPECT_EQ(c.height, 240);
  EXPECT_NEAR(c.ifov_rad * 320, 24.0 * constants::kPi / 180.0, 1e-12);
  ASSERT_EQ(c.channels.size(), 1u);
  // Half-power points at 3.2 and 3.4 um.
  const SpectralResponse& ch = c.channels[0];
  const double peak = ch.Evaluate(1e4 / 3.3);
  EXPECT_NEAR(ch.Evaluate(1e4 / 3.2) / peak, 0.5, 0.02);
  EXPECT_NEAR(ch.Evaluate(1e4 / 3.4) / peak, 0.5, 0.02);
  EXPECT_LT(ch.Evaluate(1e4 / 3.1), 1e-3 * peak);
}

TEST(CameraPresets, ThesisTable4ThroughTheOpenChannel) {
  // A 288.7 K blackbody over 1852-6667 cm-1 is 2.09 W/(m2 sr) without the lens;
  // the open channel (lens x detector) sees less.
  const CameraModel c = CameraPreset("fast-m150");
  const double l = c.channels[0].BandRadiance(288.7);
  EXPECT_LT(l, 2.09);
  EXPECT_GT(l, 0.7 * 2.09);
  const SpectralResponse no_lens({1852, 6667}, {1, 1});
  EXPECT_NEAR(no_lens.BandRadiance(288.7), 2.09, 0.005);
}

}  // namespace
}  // namespace qogi
