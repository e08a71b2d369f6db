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

// The inversion's use: background radiance L(T_bg) enters the contrast
// y = L - L(T_bg), the background temperature T(L_bg) the forward model, and
// the noise NETD dL/dT. A 0.02 K NETD is a contrast of ~1e-3 L at 300 K in
// the MWIR, so a table error of 1e-8 L, 1e-6 K and 1e-6 relative in dL/dT is
// at least ~1e4 below any contrast or noise the inversion resolves.
TEST(RadiometricTable, ServesTheInversionsBackgroundRangeToItsTolerances) {
  std::vector<double> nu, r;
  for (double x = 2800; x <= 3300; x += 1.0) {
    nu.push_back(x);
    r.push_back(0.8 / (1 + std::exp(-(x - 2950) / 4.0)) / (1 + std::exp((x - 3150) / 4.0)));
  }
  std::vector<SpectralResponse> channels = {SpectralResponse(nu, r, "logistic 2950-3150 cm-1"),
                                            SpectralResponse({1852.0, 6667.0}, {1.0, 1.0}, "InSb"),
                                            CameraPreset("fast-m150").channels[1]};
  for (const auto& ch : channels) {
    const RadiometricTable table(ch, 150.0, 700.0);  // the scene table's default range
    double worst_l = 0, worst_d = 0, worst_t = 0;
    for (double t = 150.0; t <= 700.0; t += 0.37) {
      const double l = ch.BandRadiance(t), dl = ch.BandRadianceDerivative(t);
      double tl, tdl;
      table.RadianceAndDerivative(t, &tl, &tdl);
      worst_l = std::max(worst_l, std::abs(tl / l - 1.0));
      worst_d = std::max(worst_d, std::abs(tdl / dl - 1.0));
      EXPECT_EQ(table.Derivative(t), tdl);
      worst_t = std::max(worst_t, std::abs(table.Temperature(l) - t));
    }
    EXPECT_LT(worst_l, 1e-8) << ch.name();
    EXPECT_LT(worst_d, 1e-6) << ch.name();
    EXPECT_LT(worst_t, 1e-6) << ch.name();  // K
    // Outside the table the slope is the exact one.
    for (double t : {100.0, 900.0})
      EXPECT_NEAR(table.Derivative(t) / ch.BandRadianceDerivative(t), 1.0, 1e-12) << ch.name();
    EXPECT_TRUE(std::isnan(table.Derivative(0.0)));
    EXPECT_TRUE(std::isnan(table.Derivative(std::nan(""))));
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
