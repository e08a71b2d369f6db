// Forward models against radiative-transfer physics, on synthetic line
// tables (Lorentz lines with temperature-dependent strengths), so that the
// checks depend on nothing but the RTE itself.
#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "engine/optics/planck.h"
#include "engine/optics/spectral_response.h"
#include "engine/rte/binned_model.h"
#include "engine/rte/exact_model.h"
#include "engine/rte/path.h"
#include "engine/rte/synthetic_spectra_test.h"

namespace qogi {
namespace {

// Lorentz lines between 2950 and 3100 cm-1, strengths S296 up to 2e-19
// cm/molecule, lower-state energies 0-2000 cm-1 (hot lines grow with T).
AbsorberTable SyntheticTable(const std::string& species, double nu0, double nu1, unsigned seed,
                             bool with_self) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::vector<testing_support::TestLine> lines;
  for (int l = 0; l < 300; ++l)
    lines.push_back({nu0 + 5 + (nu1 - nu0 - 10) * u01(rng), 2e-19 * std::pow(10.0, -4 * u01(rng)),
                     2000 * u01(rng)});
  return testing_support::LorentzAbsorberTable(species, nu0, nu1, 800, lines, with_self);
}

SpectralResponse Bandpass(double lo, double hi, const std::string& name) {
  return testing_support::TestBandpass(lo, hi, name);
}

struct Fixture {
  std::vector<SpectralResponse> channels{Bandpass(2960, 3090, "A"), Bandpass(2990, 3030, "B")};
  std::vector<AbsorberTable> tables{SyntheticTable("CH4", 2940, 3110, 1, true),
                                    SyntheticTable("CO2", 2940, 3110, 2, false)};
};

const Fixture& F() {
  static const Fixture f;
  return f;
}

GaussianPlume Plume(double x1, double x2, double tp, double ta, double sigma) {
  GaussianPlume p;
  p.peak_fractions = {x1, x2};
  p.peak_temperature_K = tp;
  p.ambient_temperature_K = ta;
  p.sigma_m = sigma;
  return p;
}

TEST(ExactModel, ZeroContrastWhenEverythingIsAtTheBackgroundTemperature) {
  ExactModelOptions o;
  o.num_nodes = 101;
  const ExactModel m(F().channels, F().tables, o);
  for (double t : {260.0, 300.0, 340.0}) {
    const auto l = m.BandRadiance(Plume(0.5, 0.3, t, t, 0.05), {t});
    for (std::size_t c = 0; c < l.size(); ++c) {
      const double bg = F().channels[c].BandRadiance(t);
      EXPECT_NEAR(l[c] / bg - 1.0, 0.0, 1e-9);
    }
  }
}

TEST(ExactModel, WhitePlumeWhenWarmerBlackPlumeWhenColder) {
  ExactModelOptions o;
  o.num_nodes = 101;
  const ExactModel m(F().channels, F().tables, o);
  const auto warm = m.BandRadiance(Plume(0.1, 0, 320, 300, 0.05), {290});
  const auto cold = m.BandRadiance(Plume(0.1, 0, 280, 280, 0.05), {300});
  for (std::size_t c = 0; c < 2; ++c) {
    EXPECT_GT(warm[c], F().channels[c].BandRadiance(290));
    EXPECT_LT(cold[c], F().channels[c].BandRadiance(300));
  }
}

TEST(ExactModel, IsothermalPlumeIsBeerLambertAtEveryWavenumber) {
  ExactModelOptions o;
  o.num_nodes = 201;
  const ExactModel m(F().channels, F().tables, o);
  const double tg = 330, tb = 290, x = 0.02, sigma = 0.03;
  const Path path = m.GaussianPath(Plume(x, 0, tg, tg, sigma));
  std::vector<double> nu, dl;
  m.SpectralContrast(0, path, tb, &nu, &dl);
  // tau = n x sigma_cross(T) * sigma sqrt(2 pi); exact Gaussian column.
  const AbsorberTable& t = F().tables[0];
  const TemperatureStencil st = MakeTemperatureStencil(t.temperatures_K, tg);
  const std::vector<double> log_air = LogValues(t.sigma_air), log_self = LogValues(t.sigma_self);
  const double col =
      NumberDensityCm3(constants::kAtm, tg) * 100 * x * sigma * std::sqrt(2 * constants::kPi);
  double worst = 0;
  for (std::size_t i = 0; i < nu.size(); i += 37) {
    const std::size_t j = static_cast<std::size_t>(std::round((nu[i] - t.nu0_cm1) / t.dnu_cm1));
    const double sa = SigmaAt(t.sigma_air, log_air, t.n_nu, st, j);
    const double ss = SigmaAt(t.sigma_self, log_self, t.n_nu, st, j);
    // Local self fraction varies along the path: average of (1-x g) and x g
    // weighted by g: int g (1 - x g) / int g = 1 - x / sqrt(2).
    const double xs = x / std::sqrt(2.0);
    const double tau = col * ((1 - xs) * sa + xs * ss);
    const double expect =
        (PlanckRadiance(nu[i], tg) - PlanckRadiance(nu[i], tb)) * -std::expm1(-tau);
    if (std::abs(expect) > 1e-12) worst = std::max(worst, std::abs(dl[i] / expect - 1));
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(ExactModel, OpticallyThinLimitIsTheLinearisedBeerLambert) {
  ExactModelOptions o;
  o.num_nodes = 201;
  const ExactModel m(F().channels, F().tables, o);
  // Non-isothermal, very thin: Delta L = int (B(T(s)) - B_bg) kappa ds.
  const double ta = 290, tp = 350, tb = 280;
  for (double x : {1e-7, 1e-6}) {
    const Path path = m.GaussianPath(Plume(x, 0, tp, ta, 0.02));
    std::vector<double> nu, dl;
    m.SpectralContrast(0, path, tb, &nu, &dl);
    const AbsorberTable& t = F().tables[0];
    const std::vector<double> logs = LogValues(t.sigma_air);
    double worst = 0;
    for (std::size_t i = 0; i < nu.size(); i += 53) {
      const std::size_t j = static_cast<std::size_t>(std::round((nu[i] - t.nu0_cm1) / t.dnu_cm1));
      double lin = 0;  // fine trapezoid of (B - B_bg) kappa over s
      const int n = 4001;
      for (int k = 0; k < n; ++k) {
        const double z = -8 + 16.0 * k / (n - 1), g = std::exp(-0.5 * z * z);
        const double temp = ta + (tp - ta) * g;
        const TemperatureStencil st = MakeTemperatureStencil(t.temperatures_K, temp);
        const double sa = SigmaAt(t.sigma_air, logs, t.n_nu, st, j);
        const double kappa = NumberDensityCm3(constants::kAtm, temp) * 100 * x * g * sa;
        lin += (PlanckRadiance(nu[i], temp) - PlanckRadiance(nu[i], tb)) * kappa * 0.02 * 16.0 /
               (n - 1);
      }
      worst = std::max(worst, std::abs(dl[i] / lin - 1));
    }
    // Second-order terms are O(tau); tau < 1e-4 here.
    EXPECT_LT(worst, 2e-4) << "x = " << x;
  }
}

TEST(ExactModel, ContrastSaturatesMonotonically) {
  ExactModelOptions o;
  o.num_nodes = 101;
  const ExactModel m(F().channels, F().tables, o);
  const double tg = 320, tb = 290;
  double prev = 0;
  for (double x = 1e-6; x <= 1.0; x *= 3) {
    const double dl =
        m.BandRadiance(Plume(x, 0, tg, tg, 0.1), {tb})[0] - F().channels[0].BandRadiance(tb);
    EXPECT_GT(dl, prev);
    prev = dl;
  }
  // The opaque limit: (B_g - B_bg) over the absorbing points, an upper bound.
  const ChannelGrid g = MakeChannelGrid(F().channels[0], F().tables);
  double limit = 0;
  for (std::size_t i = 0; i < g.nu_cm1.size(); ++i)
    limit += g.weight[i] * (PlanckRadiance(g.nu_cm1[i], tg) - PlanckRadiance(g.nu_cm1[i], tb));
  EXPECT_LT(prev, limit);
}

TEST(ExactModel, ConvergesUnderLineOfSightRefinement) {
  for (double tp : {300.0, 480.0}) {
    const GaussianPlume p = Plume(0.3, 0.2, tp, 290, 0.2);
    std::vector<double> prev;
    double change = 1, change_contrast = 1;
    for (int n : {ExactModelOptions().num_nodes, 2 * ExactModelOptions().num_nodes - 1}) {
      ExactModelOptions o;
      o.num_nodes = n;
      const ExactModel m(F().channels, F().tables, o);
      const auto l = m.BandRadiance(p, {270});
      if (!prev.empty()) {
        change = change_contrast = 0;
        for (std::size_t c = 0; c < l.size(); ++c) {
          const double contrast = l[c] - F().channels[c].BandRadiance(270);
          change = std::max(change, std::abs(l[c] / prev[c] - 1));
          change_contrast =
              std::max(change_contrast, std::abs(l[c] - prev[c]) / std::abs(contrast));
        }
      }
      prev = l;
    }
    // The criterion: halving the step changes L by < 1e-4. Relative to
    // the contrast (stricter) the change is held below 1e-3.
    EXPECT_LT(change, 1e-4) << "T_peak = " << tp;
    EXPECT_LT(change_contrast, 1e-3) << "T_peak = " << tp;
  }
}

TEST(ColumnDensity, IsothermalGaussianIsAnalytic) {
  GaussianPlume p = Plume(0.25, 0.5, 300, 300, 0.04);
  const auto c = GaussianColumnDensity(p, {16.0425e-3, 44.0095e-3});
  const double n = constants::kAtm / (constants::kBoltzmann * 300);
  EXPECT_NEAR(
      c[0] / (16.0425e-3 / constants::kAvogadro * 0.25 * n * 0.04 * std::sqrt(2 * constants::kPi)),
      1.0, 1e-12);
  EXPECT_NEAR(c[1] / c[0], 2 * 44.0095 / 16.0425, 1e-12);
}

TEST(BinnedModel, AgreesWithExactOverRandomPlumes) {
  const ExactModel exact(F().channels, F().tables);
  const BinnedModel fast(F().channels, F().tables);
  EXPECT_LT(fast.planck_interpolation_error(), 1e-7);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  double worst_contrast = 0, worst_l = 0;
  for (int draw = 0; draw < 24; ++draw) {
    const double ta = 250 + 70 * u(rng), tp = ta - 30 + 230 * u(rng);
    const double x1 = std::pow(10.0, -5 + 5 * u(rng)) * (u(rng) < 0.8);
    const double x2 = (1 - x1) * std::pow(10.0, -5 + 5 * u(rng)) * (u(rng) < 0.5);
    const double sigma = std::pow(10.0, -3 + 2.7 * u(rng)), tb = 250 + 100 * u(rng);
    const GaussianPlume p = Plume(x1, x2, tp, ta, sigma);
    const auto le = exact.BandRadiance(p, {tb});
    const auto lf = fast.BandRadiance(p, {tb});
    for (std::size_t c = 0; c < le.size(); ++c) {
      const double bg = F().channels[c].BandRadiance(tb);
      // Relative to the contrast, with a floor of 1e-4 of the background
      // (0.1 mK-equivalent): near-cancelling contrasts are judged absolutely.
      const double scale = std::max(std::abs(le[c] - bg), 1e-4 * bg);
      worst_contrast = std::max(worst_contrast, std::abs(lf[c] - le[c]) / scale);
      worst_l = std::max(worst_l, std::abs(lf[c] / le[c] - 1));
    }
  }
  std::printf("binned vs exact, synthetic lines: worst contrast error %.3g, worst L error %.3g\n",
              worst_contrast, worst_l);
  EXPECT_LT(worst_contrast, 0.01);
  EXPECT_LT(worst_l, 0.003);
}

TEST(BinnedModel, JetDerivativesMatchFiniteDifferences) {
  const BinnedModel fast(F().channels, F().tables);
  using J = ceres::Jet<double, 4>;
  const double ta = 290, tb = 280;
  const double p0[4] = {0.2, 0.1, 340, 0.05};  // x1, x2, T_peak, sigma
  J x[2] = {J(p0[0], 0), J(p0[1], 1)};
  const J tp(p0[2], 2), sg(p0[3], 3);
  const PathT<J> path = fast.GaussianPath<J>(x, tp, ta, sg);
  J tbg[2] = {J(tb), J(tb)};
  J out[2];
  fast.Contrast<J>(path, tbg, out);
  auto eval = [&](const double* q, int c) {
    const double xx[2] = {q[0], q[1]};
    const Path pd = fast.GaussianPath<double>(xx, q[2], ta, q[3]);
    double tbd[2] = {tb, tb}, o[2];
    fast.Contrast<double>(pd, tbd, o);
    return o[c];
  };
  for (int c = 0; c < 2; ++c)
    for (int k = 0; k < 4; ++k) {
      double qp[4], qm[4];
      std::copy(p0, p0 + 4, qp);
      std::copy(p0, p0 + 4, qm);
      const double h = 1e-5 * std::max(1.0, std::abs(p0[k]));
      qp[k] += h;
      qm[k] -= h;
      const double fd = (eval(qp, c) - eval(qm, c)) / (2 * h);
      EXPECT_NEAR(out[c].v[k], fd, 1e-5 * std::abs(fd) + 1e-12) << "c " << c << " k " << k;
    }
}

TEST(Models, RejectBadInput) {
  ExactModelOptions o;
  o.num_nodes = 51;
  const ExactModel m(F().channels, F().tables, o);
  EXPECT_THROW(m.BandRadiance(Plume(0.5, 0.7, 300, 300, 0.1), {290}), std::invalid_argument);
  EXPECT_THROW(m.BandRadiance(Plume(0.1, 0, 300, 300, -1), {290}), std::invalid_argument);
  EXPECT_THROW(m.BandRadiance(Plume(0.1, 0, 900, 300, 0.1), {290}), std::invalid_argument);
  EXPECT_THROW(m.BandRadiance(Plume(0.1, 0, 300, 300, 0.1), {290, 280, 270}),
               std::invalid_argument);
  AbsorberTable bad = F().tables[0];
  bad.sigma_air.pop_back();
  EXPECT_THROW(ExactModel({F().channels[0]}, {bad}), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
