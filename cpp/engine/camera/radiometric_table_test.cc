#include "engine/camera/radiometric_table.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "engine/camera/camera.h"

namespace qogi {
namespace {

TEST(RadiometricTable, MatchesTheExactQuadratureBothWays) {
  // A narrow filter, the whole InSb band, and a preset channel.
  std::vector<SpectralResponse> channels = {
      SpectralResponse({2941.18, 3125.0}, {1.0, 1.0}, "3.2-3.4 um"),
      SpectralResponse({1852.0, 6667.0}, {1.0, 1.0}, "InSb"),
      CameraPreset("fast-m150").channels[1]};
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(150.0, 1500.0);
  for (const auto& ch : channels) {
    const RadiometricTable table(ch);
    double worst_l = 0, worst_t = 0;
    for (int i = 0; i < 2000; ++i) {
      const double t = i < 2 ? (i == 0 ? 150.0 : 1500.0) : u(rng);
      const double l = ch.BandRadiance(t);
      worst_l = std::max(worst_l, std::abs(table.Radiance(t) / l - 1.0));
      worst_t = std::max(worst_t, std::abs(table.Temperature(l) - t));
    }
    EXPECT_LT(worst_l, 2e-9) << ch.name();
    EXPECT_LT(worst_t, 1e-6) << ch.name();  // K; float32 resolves 2e-5 K at 300 K
  }
}

TEST(RadiometricTable, OutsideTheTableFallsBackAndFlagsTheImpossible) {
  const SpectralResponse ch({2941.18, 3125.0}, {1.0, 1.0});
  const RadiometricTable table(ch, 250.0, 400.0, 32);
  for (double t : {60.0, 249.0, 401.0, 3000.0}) {
    EXPECT_NEAR(table.Radiance(t) / ch.BandRadiance(t), 1.0, 1e-12);
    EXPECT_NEAR(table.Temperature(ch.BandRadiance(t)), t, 1e-9 * t);
  }
  EXPECT_TRUE(std::isnan(table.Temperature(-1.0)));
  EXPECT_TRUE(std::isnan(table.Temperature(0.0)));
  EXPECT_TRUE(std::isnan(table.Temperature(std::nan(""))));
  EXPECT_TRUE(std::isnan(table.Radiance(-5.0)));
  EXPECT_THROW(RadiometricTable(ch, 400.0, 300.0), std::invalid_argument);
  EXPECT_THROW(RadiometricTable(ch, 200.0, 300.0, 4), std::invalid_argument);
}

TEST(RadiometricTable, FrameConversionsRoundTrip) {
  const SpectralResponse ch({2941.18, 3125.0}, {1.0, 1.0});
  const RadiometricTable table(ch);
  std::vector<float> t(10000), l(t.size()), back(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = 250.0f + 0.01f * i;
  table.Radiance(t.data(), l.data(), t.size());
  table.Temperature(l.data(), back.data(), t.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(l[i], ch.BandRadiance(t[i]), 2e-7 * l[i]);  // float32 rounding
    EXPECT_NEAR(back[i], t[i], 1e-4);
  }
}

}  // namespace
}  // namespace qogi
