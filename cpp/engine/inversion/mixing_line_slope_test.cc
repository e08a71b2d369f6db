// The mixing line's slope against ground truth: pixels made by the scene
// table itself on T = T_amb + k X with seeded NETD noise give back k within
// the 1-sigma the search states; the profile statistics on an analytic chi2
// profile; the sample; flat input and bad options.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "engine/inversion/mixing_line.h"
#include "engine/inversion/mixing_line_slope.h"
#include "engine/inversion/scene_fixture_test.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

using testing_support::F;
using testing_support::Fixture;

struct Pixels {
  std::size_t n = 0;
  std::vector<double> rad, bg, sigma, fraction;
};

// n pixel-frames on the line of slope k (x = (0.5, 0.5) X), X log-uniform
// over [3e-3, 0.3], depths 2-6 cm, backgrounds 280-295 K, NETD noise netd_K
// (seeded); every fifth pixel has no gas (its contrast is noise).
Pixels OnTheLine(const Fixture& f, double k, std::size_t n, double netd_K, unsigned seed) {
  const SceneTable& t = *f.table;
  const std::size_t nc = t.num_channels();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Pixels p;
  p.n = n;
  p.rad.resize(n * nc);
  p.bg.resize(n * nc);
  p.sigma.resize(n);
  p.fraction.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double big_x = i % 5 == 4 ? 0.0 : std::pow(10.0, -2.5 + 2.0 * u01(rng));
    p.fraction[i] = big_x;
    p.sigma[i] = 0.02 + 0.04 * u01(rng);
    const double t_bg = 280.0 + 15.0 * u01(rng);
    std::vector<double> tbg(nc, t_bg), phi(t.background_size()), m(nc, 0.0);
    t.Background(tbg.data(), phi.data());
    const double x[2] = {0.5 * big_x, 0.5 * big_x};
    const double tp =
        std::clamp(f.t_amb + k * big_x, t.min_peak_temperature_K(), t.max_peak_temperature_K());
    if (big_x > 0) t.Contrast(x, tp, p.sigma[i], phi.data(), m.data(), nullptr);
    for (std::size_t c = 0; c < nc; ++c) {
      const SpectralResponse& channel = t.model().channels()[c];
      const double l_bg = channel.BandRadiance(t_bg);
      p.bg[i * nc + c] = l_bg;
      p.rad[i * nc + c] = l_bg + m[c] + netd_K * channel.BandRadianceDerivative(t_bg) * gauss(rng);
    }
  }
  return p;
}

MixingLineSlopeOptions SlopeOptions(double netd_K) {
  MixingLineSlopeOptions o;
  o.line.composition = {0.5, 0.5};
  o.line.netd_K = {netd_K};
  o.line.num_threads = 2;
  return o;
}

// Three slopes (one on the table's range end side, one negative: gas cooler
// than ambient) off the 10 K grid: k within 3 of its stated 1-sigma, and
// that 1-sigma neither absurdly small nor as wide as the grid.
TEST(MixingLineSlope, RecoversAKnownSlopeFromNoisyPixelsOnTheLine) {
  const Fixture& f = F();
  MixingLineInverter inv(f.table);
  for (const double k_true : {-25.0, 72.0, 131.0}) {
    const Pixels p = OnTheLine(f, k_true, 1500, 0.03, 11);
    const MixingLineSlopeOptions o = SlopeOptions(0.03);
    const MixingLineSlope r =
        FindMixingLineSlope(inv, o, p.n, p.rad.data(), p.bg.data(), p.sigma.data());
    ASSERT_TRUE(r.found) << k_true;
    EXPECT_GT(r.num_candidates, 300u);
    EXPECT_EQ(r.num_samples, r.num_candidates);  // fewer than max_samples
    EXPECT_EQ(r.num_fitted, r.num_samples);
    EXPECT_GT(r.sigma_K_per_fraction, 0.0);
    EXPECT_LT(r.sigma_K_per_fraction, 15.0);
    EXPECT_LT(std::abs(r.slope_K_per_fraction - k_true), 3.0 * r.sigma_K_per_fraction)
        << "k " << r.slope_K_per_fraction << " +- " << r.sigma_K_per_fraction << " truth "
        << k_true;
    // The profile's minimum is the grid node nearest the estimate.
    ASSERT_EQ(r.total_chi2.size(), r.grid_K_per_fraction.size());
    const std::size_t i = static_cast<std::size_t>(
        std::min_element(r.total_chi2.begin(), r.total_chi2.end()) - r.total_chi2.begin());
    EXPECT_LE(std::abs(r.grid_K_per_fraction[i] - r.slope_K_per_fraction), 5.0 + 1e-9);
    std::printf("k truth %.1f: %.2f +- %.2f K per unit fraction (%zu samples)\n", k_true,
                r.slope_K_per_fraction, r.sigma_K_per_fraction, r.num_samples);
  }
}

// A capped sample is a seeded random subset of the candidates (the same for
// a seed, another for another seed) and gives the same k within its
// 1-sigma; progress reaches 1 and a cancel stops the search.
TEST(MixingLineSlope, SamplesAtRandomReportsProgressAndCancels) {
  const Fixture& f = F();
  MixingLineInverter inv(f.table);
  const Pixels p = OnTheLine(f, 72.0, 1500, 0.03, 12);
  MixingLineSlopeOptions o = SlopeOptions(0.03);
  std::size_t all = 0;
  const std::vector<std::size_t> every =
      MixingLineSlopeSample(inv, o, p.n, p.rad.data(), p.bg.data(), &all);
  ASSERT_EQ(every.size(), all);
  o.max_samples = all / 3;
  std::size_t again = 0;
  const std::vector<std::size_t> some =
      MixingLineSlopeSample(inv, o, p.n, p.rad.data(), p.bg.data(), &again);
  EXPECT_EQ(again, all);
  ASSERT_EQ(some.size(), all / 3);
  for (std::size_t j = 0; j < some.size(); ++j) {
    EXPECT_TRUE(std::binary_search(every.begin(), every.end(), some[j])) << some[j];
    if (j > 0) {
      EXPECT_LT(some[j - 1], some[j]);
    }
  }
  EXPECT_EQ(MixingLineSlopeSample(inv, o, p.n, p.rad.data(), p.bg.data()), some);
  MixingLineSlopeOptions other = o;
  other.seed = 1;
  EXPECT_NE(MixingLineSlopeSample(inv, other, p.n, p.rad.data(), p.bg.data()), some);
  // Every pixel without gas (contrast = noise, < 10 sigma) is left out.
  for (std::size_t i : every) EXPECT_GT(p.fraction[i], 0.0) << i;

  double last = -1;
  bool monotone = true;
  RunControl control;
  control.progress = [&](double v) {
    monotone = monotone && v >= last - 1e-12;
    last = v;
  };
  const MixingLineSlope r =
      FindMixingLineSlope(inv, o, p.n, p.rad.data(), p.bg.data(), p.sigma.data(), &control);
  ASSERT_TRUE(r.found);
  EXPECT_EQ(r.num_samples, all / 3);
  EXPECT_LT(std::abs(r.slope_K_per_fraction - 72.0), 3.0 * r.sigma_K_per_fraction);
  EXPECT_TRUE(monotone);
  EXPECT_NEAR(last, 1.0, 1e-9);

  RunControl stop;
  stop.cancelled = [] { return true; };
  EXPECT_THROW(FindMixingLineSlope(inv, o, p.n, p.rad.data(), p.bg.data(), p.sigma.data(), &stop),
               Cancelled);
}

// No gas anywhere: no candidate, no search, a flagged result (not a k).
TEST(MixingLineSlope, FlatInputIsFlaggedNotFitted) {
  const Fixture& f = F();
  MixingLineInverter inv(f.table);
  Pixels p = OnTheLine(f, 72.0, 200, 0.0, 13);
  p.rad = p.bg;
  const MixingLineSlope r =
      FindMixingLineSlope(inv, SlopeOptions(0.03), p.n, p.rad.data(), p.bg.data(), p.sigma.data());
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.num_candidates, 0u);
  EXPECT_EQ(r.slope_K_per_fraction, 0.0);
  EXPECT_EQ(r.sigma_K_per_fraction, 0.0);
}

// A quadratic profile sum_p ((k - k0) / s_p)^2 (the chi2 of linear pixels):
// the parabola through the best three nodes is exact, and Delta chi2 = 1
// lies at k0 +- 1 / sqrt(sum 1 / s_p^2) (to the interpolation's 0.5 K
// sampling); a pixel with a non-finite chi2 is left out; a pixel far off
// counts as its capped chi2 (and, through the reduced chi2, widens sigma).
TEST(MixingLineSlope, ProfileOfLinearPixelsGivesTheirMinimumAndDeltaChi2OfOne) {
  const double k0 = 53.7;
  const std::vector<double> s{30.0, 45.0, 60.0};
  std::vector<double> grid;
  for (double k = -10; k <= 150 + 1e-9; k += 10) grid.push_back(k);
  auto profile = [&](double far) {
    const std::size_t np = s.size() + 2;
    std::vector<double> chi2(grid.size() * np);
    for (std::size_t k = 0; k < grid.size(); ++k) {
      for (std::size_t p = 0; p < s.size(); ++p)
        chi2[k * np + p] = std::pow((grid[k] - k0) / s[p], 2);
      chi2[k * np + s.size()] = k == 3 ? std::numeric_limits<double>::quiet_NaN() : 0.0;
      chi2[k * np + s.size() + 1] = far;
    }
    return MixingLineSlopeFromProfile(grid, np, chi2.data(), 50.0);
  };
  const MixingLineSlope r = profile(0.0);
  ASSERT_TRUE(r.found);
  EXPECT_EQ(r.num_fitted, s.size() + 1);
  EXPECT_NEAR(r.slope_K_per_fraction, k0, 1e-9);
  double info = 0;
  for (double v : s) info += 1 / (v * v);
  // Linear interpolation of a convex profile lies above it: the bracket is
  // at most one fine step (0.5 K) narrower.
  EXPECT_NEAR(r.sigma_K_per_fraction, 1 / std::sqrt(info), 0.6);
  const MixingLineSlope capped = profile(1e4), at_cap = profile(50.0);
  EXPECT_NEAR(capped.slope_K_per_fraction, k0, 1e-9);
  EXPECT_EQ(capped.sigma_K_per_fraction, at_cap.sigma_K_per_fraction);
  EXPECT_GT(capped.sigma_K_per_fraction, r.sigma_K_per_fraction);
  std::vector<double> dummy(10, 0.0);
  EXPECT_THROW(MixingLineSlopeFromProfile({0.0}, 1, dummy.data(), 50.0), std::invalid_argument);
  EXPECT_THROW(MixingLineSlopeFromProfile({0.0, 1.0, 3.0}, 1, dummy.data(), 50.0),
               std::invalid_argument);
}

TEST(MixingLineSlopeOptions, RejectBadValuesByName) {
  MixingLineSlopeOptions o = SlopeOptions(0.03);
  EXPECT_NO_THROW(o.Check(2, 4));
  auto message = [](const MixingLineSlopeOptions& b) {
    try {
      b.Check(2, 4);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  MixingLineSlopeOptions b = o;
  b.grid_step_K = 0;
  EXPECT_NE(message(b).find("grid_step_K"), std::string::npos);
  b = o;
  b.min_snr = -1;
  EXPECT_NE(message(b).find("min_snr"), std::string::npos);
  b = o;
  b.chi2_cap = 0;
  EXPECT_NE(message(b).find("chi2_cap"), std::string::npos);
  b = o;
  b.max_samples = 0;
  EXPECT_NE(message(b).find("max_samples"), std::string::npos);
  b = o;
  b.line.composition = {1.0};
  EXPECT_NE(message(b).find("composition"), std::string::npos);
}

}  // namespace
}  // namespace qogi
