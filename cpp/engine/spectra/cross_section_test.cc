#include "engine/spectra/cross_section.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "engine/spectra/test_data.h"
#include "engine/spectra/voigt.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kAtm = 101325.0;

LineList OneLine(double nu, double s, double gair) {
  LineList l;
  l.molecule = {6};
  l.isotopologue = {1};
  l.nu_cm1 = {nu};
  l.intensity = {s};
  l.einstein_a = {0};
  l.gamma_air = {gair};
  l.gamma_self = {gair};
  l.elower_cm1 = {0};
  l.n_air = {0.7};
  l.n_self = {0.7};
  l.delta_air = {-0.01};
  l.delta_self = {-0.01};
  return l;
}

const LineList& Ch4() {
  static const LineList l = ReadLineFile(testing_util::HitranDir() + "/CH4.par.gz");
  return l;
}

// The documented sum, line by line and point by point, with VoigtProfile.
std::vector<double> BruteForce(const LineList& lines, const GasConditions& c,
                               const std::vector<double>& nu, const CrossSectionOptions& o) {
  const LineParameters p = ComputeLineParameters(lines, c, o.line_shift);
  std::vector<double> out(nu.size(), 0.0);
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double w =
        std::max(o.wing_cm1, o.wing_half_widths * std::max(p.gamma_lorentz[i], p.gamma_doppler[i]));
    for (std::size_t j = 0; j < nu.size(); ++j)
      if (nu[j] > p.nu_cm1[i] - w && nu[j] <= p.nu_cm1[i] + w)
        out[j] += p.intensity[i] *
                  VoigtProfile(nu[j] - p.center_cm1[i], p.gamma_doppler[i], p.gamma_lorentz[i]);
  }
  return out;
}

TEST(WavenumberGrid, FromRangeFollowsHapi) {
  const WavenumberGrid g = WavenumberGrid::FromRange(2800, 3200, 0.01);
  EXPECT_EQ(g.size, 40001u);
  EXPECT_NEAR(g.last_cm1(), 3200.0, 1e-9);
  EXPECT_EQ(WavenumberGrid::FromRange(2850, 3200, 0.01).size, 35001u);
  EXPECT_EQ(WavenumberGrid::FromRange(0, 1, 0.3).size, 4u);  // 0, .3, .6, .9
  EXPECT_THROW(WavenumberGrid::FromRange(10, 5, 0.1), std::invalid_argument);
  EXPECT_THROW(WavenumberGrid::FromRange(0, 5, 0.0), std::invalid_argument);
}

TEST(CrossSection, SingleLineIntegratesToItsIntensity) {
  const LineList l = OneLine(3000.0, 1e-20, 0.06);
  CrossSectionOptions o;
  o.wing_half_widths = 0, o.wing_cm1 = 400;
  const WavenumberGrid g = WavenumberGrid::FromRange(2500, 3500, 0.005);
  const std::vector<double> s = CrossSection(l, GasConditions{}, g, o);
  double sum = 0;
  for (double v : s) sum += v * g.step_cm1;
  // Lorentz area beyond the 400 cm-1 cutoff is missing: (2/pi) atan(400/0.06).
  EXPECT_NEAR(sum / 1e-20, 2 / kPi * std::atan(400 / 0.06), 2e-6);
  // Peak at the shifted centre.
  const std::size_t peak = std::max_element(s.begin(), s.end()) - s.begin();
  EXPECT_NEAR(g[peak], 3000.0 - 0.01, g.step_cm1);
}

TEST(CrossSection, HapiWindowRule) {
  const LineList l = OneLine(3000.0, 1e-20, 0.05);
  const WavenumberGrid g = WavenumberGrid::FromRange(2990, 3010, 0.01);
  // 1 atm: gamma_L = 0.05 > gamma_D, window (nu - 2.5, nu + 2.5] around the unshifted line.
  std::vector<double> s = CrossSection(l, GasConditions{}, g);
  for (std::size_t j = 0; j < g.size; ++j) {
    const double d = g[j] - 3000.0;
    if (d > -2.5 + 1e-9 && d < 2.5 - 1e-9) {
      EXPECT_GT(s[j], 0.0) << d;
    } else if (d < -2.5 - 1e-9 || d > 2.5 + 1e-9) {
      EXPECT_EQ(s[j], 0.0) << d;
    }
  }
  // 0.001 atm: Doppler HWHM (0.0046 cm-1 at 296 K) dominates.
  const LineParameters p = ComputeLineParameters(l, GasConditions{296.0, 0.001 * kAtm, 0.0});
  const double w = 50 * p.gamma_doppler[0];
  s = CrossSection(l, GasConditions{296.0, 0.001 * kAtm, 0.0}, g);
  for (std::size_t j = 0; j < g.size; ++j) {
    const double d = g[j] - 3000.0;
    if (std::abs(d) < w - 0.011) {
      EXPECT_GT(s[j], 0.0) << d;
    } else if (std::abs(d) > w + 0.011) {
      EXPECT_EQ(s[j], 0.0) << d;
    }
  }
  // A fixed cutoff.
  CrossSectionOptions o;
  o.wing_half_widths = 0, o.wing_cm1 = 1.0;
  s = CrossSection(l, GasConditions{}, g, o);
  EXPECT_GT(s[g.size / 2 + 99], 0.0);
  EXPECT_EQ(s[g.size / 2 + 101], 0.0);
}

TEST(CrossSection, MatchesBruteForceSumOnRealLines) {
  LineSelection sel;
  sel.nu_min_cm1 = 3040, sel.nu_max_cm1 = 3060;
  const LineList l = Ch4().Select(sel);
  ASSERT_GT(l.size(), 500u);
  std::vector<double> nu;
  const WavenumberGrid g = WavenumberGrid::FromRange(3045, 3055, 0.01);
  for (std::size_t j = 0; j < g.size; ++j) nu.push_back(g[j]);
  for (double t : {250.0, 700.0})
    for (double p : {0.05, 1.0, 3.0}) {
      const GasConditions c{t, p * kAtm, 0.2};
      const std::vector<double> ref = BruteForce(l, c, nu, CrossSectionOptions());
      const std::vector<double> fast = CrossSection(l, c, g);
      const std::vector<double> arr = CrossSection(l, c, nu);
      for (std::size_t j = 0; j < nu.size(); ++j) {
        ASSERT_NEAR(fast[j], ref[j], 1e-9 * ref[j] + 1e-40) << t << " " << p << " " << nu[j];
        ASSERT_NEAR(arr[j], ref[j], 1e-9 * ref[j] + 1e-40);
      }
    }
}

TEST(CrossSection, IrregularGrid) {
  LineSelection sel;
  sel.nu_min_cm1 = 3000, sel.nu_max_cm1 = 3010;
  const LineList l = Ch4().Select(sel);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(2999.0, 3011.0);
  std::vector<double> nu(3000);
  for (double& v : nu) v = u(rng);
  std::sort(nu.begin(), nu.end());
  nu.erase(std::unique(nu.begin(), nu.end()), nu.end());
  CrossSectionOptions o;
  o.wing_half_widths = 0, o.wing_cm1 = 5;
  const std::vector<double> ref = BruteForce(l, GasConditions{}, nu, o);
  const std::vector<double> s = CrossSection(l, GasConditions{}, nu, o);
  for (std::size_t j = 0; j < nu.size(); ++j) ASSERT_NEAR(s[j], ref[j], 1e-9 * ref[j]);
  std::vector<double> bad = {3000.0, 2999.0};
  EXPECT_THROW(CrossSection(l, GasConditions{}, bad, o), std::invalid_argument);
}

TEST(CrossSection, BandIntegralEqualsSumOfLineIntensities) {
  // With wide wings, the integral of sigma over a grid that holds every line
  // equals the sum of S_i(T); what is lost is the Lorentz area beyond 100
  // cm-1 (about 2 gamma / (pi 100) ~ 3e-4).
  const LineList& l = Ch4();
  CrossSectionOptions o;
  o.wing_half_widths = 0, o.wing_cm1 = 100;
  const WavenumberGrid g = WavenumberGrid::FromRange(2700, 3400, 0.01);
  for (double t : {296.0, 600.0}) {
    const GasConditions c{t, kAtm, 0.0};
    const std::vector<double> s = CrossSection(l, c, g, o);
    double integral = 0, lines = 0;
    for (double v : s) integral += v * g.step_cm1;
    for (double v : ComputeLineParameters(l, c).intensity) lines += v;
    EXPECT_NEAR(integral / lines, 1.0, 2e-3) << t;
    EXPECT_GT(integral / lines, 0.999) << t;
  }
}

TEST(CrossSection, ThreadCountDoesNotChangeTheResult) {
  const WavenumberGrid g = WavenumberGrid::FromRange(2900, 3100, 0.01);
  ComputeSettings one, two, five;
  one.num_threads = 1, two.num_threads = 2, five.num_threads = 5;
  const std::vector<double> a = CrossSection(Ch4(), GasConditions{}, g, {}, one);
  const std::vector<double> b = CrossSection(Ch4(), GasConditions{}, g, {}, two);
  const std::vector<double> c = CrossSection(Ch4(), GasConditions{}, g, {}, five);
  EXPECT_EQ(a, b);
  EXPECT_EQ(a, c);
}

TEST(CrossSection, AbsorptionCoefficientAndControl) {
  const LineList l = OneLine(3000.0, 1e-20, 0.05);
  const WavenumberGrid g = WavenumberGrid::FromRange(2999, 3001, 0.01);
  const GasConditions c{300.0, kAtm, 0.02};
  const std::vector<double> s = CrossSection(l, c, g);
  const std::vector<double> k = AbsorptionCoefficient(l, c, g);
  const double n = 0.02 * kAtm / (1.380649e-23 * 300.0) * 1e-6;
  for (std::size_t j = 0; j < g.size; ++j) EXPECT_NEAR(k[j], s[j] * n, 1e-12 * k[j]);
  RunControl stop;
  stop.cancelled = [] { return true; };
  EXPECT_THROW(CrossSection(Ch4(), GasConditions{}, WavenumberGrid::FromRange(2900, 3100, 0.01), {},
                            {}, &stop),
               Cancelled);
  CrossSectionOptions bad;
  bad.wing_half_widths = 0;
  EXPECT_THROW(CrossSection(l, c, g, bad), std::invalid_argument);
  bad.wing_half_widths = -1;
  EXPECT_THROW(CrossSection(l, c, g, bad), std::invalid_argument);
}

TEST(CrossSection, IntensityThresholdSkipsWeakLines) {
  const WavenumberGrid g = WavenumberGrid::FromRange(3000, 3010, 0.01);
  CrossSectionOptions o;
  o.min_intensity = 1e-21;
  LineSelection strong;
  strong.min_intensity = 1e-21;
  // At 296 K, S(T) = S(296): the threshold equals selecting the strong lines.
  const std::vector<double> a = CrossSection(Ch4(), GasConditions{}, g, o);
  const std::vector<double> b = CrossSection(Ch4().Select(strong), GasConditions{}, g);
  for (std::size_t j = 0; j < g.size; ++j) EXPECT_NEAR(a[j], b[j], 1e-12 * b[j]);
}

}  // namespace
}  // namespace qogi
