// The inversion against ground truth: splines against polynomials, the
// per-scene table against the binned model it tabulates, and inversions of
// pixels forward-modelled with known parameters, on synthetic line tables
// (Lorentz lines) so that nothing but the numerics is tested here. The
// HITRAN round trip and the thesis's gas-temperature finding are in
// tests/python/test_inversion_hitran.py.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "engine/inversion/bspline.h"
#include "engine/inversion/full_model.h"
#include "engine/inversion/inversion.h"
#include "engine/inversion/march_kernel.h"
#include "engine/inversion/mixing_line.h"
#include "engine/inversion/scene_fixture_test.h"
#include "engine/inversion/scene_table.h"
#include "engine/optics/planck.h"
#include "engine/rte/march.h"
#include "engine/rte/synthetic_spectra_test.h"

namespace qogi {
namespace {

// ---------------------------------------------------------------------------
// Splines.

TEST(CubicSpline, ReproducesCubicsExactlyAndExtrapolatesLinearly) {
  const int n = 9;
  const double x0 = -1.0, h = 0.25;
  auto f = [](double x) { return 2.0 - 3.0 * x + 0.5 * x * x - 0.7 * x * x * x; };
  auto df = [](double x) { return -3.0 + x - 2.1 * x * x; };
  std::vector<double> v(n);
  for (int k = 0; k < n; ++k) v[k] = f(x0 + k * h);
  const UniformSpline s(x0, h, n, 1, v);
  for (double x = x0; x <= x0 + (n - 1) * h + 1e-12; x += 0.0371) {
    EXPECT_NEAR(s.Value(x), f(x), 1e-12);
    EXPECT_NEAR(s.Slope(x), df(x), 1e-11);
  }
  const double xe = x0 + (n - 1) * h;
  EXPECT_NEAR(s.Value(xe + 0.5), f(xe) + 0.5 * df(xe), 1e-11);
  EXPECT_NEAR(s.Slope(x0 - 2.0), df(x0), 1e-11);
  const UniformSpline hold(x0, h, n, 1, v, Extrapolation::kHold, Extrapolation::kHold);
  EXPECT_NEAR(hold.Value(x0 - 3.0), f(x0), 1e-12);
  EXPECT_EQ(hold.Slope(x0 - 3.0), 0.0);
}

TEST(CubicSpline, ConvergesAtFourthOrder) {
  auto err = [](int n) {
    const double h = 3.0 / (n - 1);
    std::vector<double> v(n);
    for (int k = 0; k < n; ++k) v[k] = std::sin(k * h);
    const UniformSpline s(0.0, h, n, 1, v);
    double e = 0;
    for (double x = 0; x <= 3.0; x += 0.001) e = std::max(e, std::abs(s.Value(x) - std::sin(x)));
    return e;
  };
  const double e1 = err(16), e2 = err(31);
  EXPECT_LT(e2, e1 / 12.0);  // 16 for h^4
  EXPECT_LT(e2, 1e-5);
}

TEST(CubicSpline, RejectsTwoOrThreeNodes) {
  EXPECT_THROW(CubicSplineAxis(2), std::invalid_argument);
  EXPECT_THROW(CubicSplineAxis(3), std::invalid_argument);
}

TEST(MarchKernel, ExponentialWithinTwoUlp) {
  double worst = 0;
  for (double x = 0; x < 720; x = x * 1.001 + 1e-7) {
    const double ref = std::exp(-x), v = ExpNegative(x);
    if (ref < 1e-300) {
      EXPECT_LE(v, 1e-300);
      continue;
    }
    worst = std::max(worst, std::abs(v - ref) / ref);
  }
  EXPECT_LT(worst, 4.5e-16);
  EXPECT_EQ(ExpNegative(0.0), 1.0);
  EXPECT_EQ(ExpNegative(1e5), 0.0);
}

TEST(MarchKernel, IsTheLayerSchemeOfMarchH) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u01(0, 1);
  const std::size_t n = 37;
  std::vector<double> kf(n), kn(n), df(n), dn(n), de(n, 0.1), da(n, 0.2);
  for (std::size_t j = 0; j < n; ++j) {
    kf[j] = std::pow(10.0, -8 + 10 * u01(rng));
    kn[j] = std::pow(10.0, -8 + 10 * u01(rng));
    df[j] = u01(rng);
    dn[j] = u01(rng);
  }
  std::vector<double> de2 = de, da2 = da;
  MarchLayerPair(n, kf.data(), kn.data(), df.data(), dn.data(), 0.7, 0.01, de2.data(), da2.data());
  for (std::size_t j = 0; j < n; ++j) {
    const double e = MarchLayer<double>(de[j], 0.7 * kf[j], 0.7 * kn[j], df[j], dn[j], 0.01);
    const double a = MarchLayer<double>(da[j], 0.7 * kf[j], 0.7 * kn[j], 1.0, 1.0, 0.01);
    EXPECT_NEAR(de2[j], e, 1e-14 * std::abs(e) + 1e-300);
    EXPECT_NEAR(da2[j], a, 1e-14 * std::abs(a) + 1e-300);
  }
}

// Marching the first half of a symmetric path with the mirrored half's
// contribution accumulated alongside equals marching the whole path.
TEST(MarchKernel, SymmetricHalfEqualsTheWholePath) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u01(0, 1);
  const std::size_t n = 19;
  const int nodes = 41, half = (nodes - 1) / 2;
  // Node values symmetric about the middle node, per bin.
  std::vector<double> k(nodes * n), d(nodes * n);
  for (int i = 0; i <= half; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      const double kv = std::pow(10.0, -6 + 8 * u01(rng)), dv = u01(rng);
      k[i * n + j] = k[(nodes - 1 - i) * n + j] = kv;
      d[i * n + j] = d[(nodes - 1 - i) * n + j] = dv;
    }
  for (double u : {1e-3, 0.3, 5.0}) {
    std::vector<double> de(n, 0.0), da(n, 0.0), he(n, 0.0), ha(n, 0.0), p(n, 1.0), eb(n, 0.0),
        ab(n, 0.0);
    for (int i = 0; i + 1 < nodes; ++i)
      MarchLayerPair(n, &k[i * n], &k[(i + 1) * n], &d[i * n], &d[(i + 1) * n], u, 0.05, de.data(),
                     da.data());
    for (int i = 0; i < half; ++i)
      MarchLayerPairSymmetric(n, &k[i * n], &k[(i + 1) * n], &d[i * n], &d[(i + 1) * n], u, 0.05,
                              he.data(), ha.data(), p.data(), eb.data(), ab.data());
    for (std::size_t j = 0; j < n; ++j) {
      EXPECT_NEAR(he[j] * p[j] + eb[j], de[j], 1e-13 * (1.0 + std::abs(de[j]))) << u << " " << j;
      EXPECT_NEAR(ha[j] * p[j] + ab[j], da[j], 1e-13) << u << " " << j;
    }
  }
}

// The inversion's band tables hold their tolerances (see
// RadiometricTable.ServesTheInversionsBackgroundRangeToItsTolerances) over
// the widest background range a scene table serves, not only the default.
TEST(BackgroundBandTable, HoldsTheInversionsTolerancesOverTheServedRange) {
  const std::vector<SpectralResponse> channels = {
      SpectralResponse({1852.0, 6667.0}, {1.0, 1.0}, "InSb"),
      SpectralResponse({2941.18, 3125.0}, {1.0, 1.0}, "3.2-3.4 um")};
  for (const auto& ch : channels) {
    for (const auto& range : {std::pair<double, double>{150.0, 700.0}, {50.0, 2000.0}}) {
      const RadiometricTable table =
          BackgroundBandTable(ch, range.first, range.second, /*num_threads=*/1);
      double worst_l = 0, worst_d = 0, worst_t = 0;
      for (double t = range.first; t <= range.second; t *= 1.0007) {
        const double l = ch.BandRadiance(t);
        double tl, tdl;
        table.RadianceAndDerivative(t, &tl, &tdl);
        worst_l = std::max(worst_l, std::abs(tl / l - 1.0));
        worst_d = std::max(worst_d, std::abs(tdl / ch.BandRadianceDerivative(t) - 1.0));
        worst_t = std::max(worst_t, std::abs(table.Temperature(l) - t));
      }
      EXPECT_LT(worst_l, 1e-8) << ch.name() << " " << range.first;
      EXPECT_LT(worst_d, 1e-6) << ch.name() << " " << range.first;
      EXPECT_LT(worst_t, 1e-6) << ch.name() << " " << range.first;  // K
    }
  }
}

using testing_support::Bandpass;
using testing_support::CoarseOptions;
using testing_support::F;
using testing_support::Fixture;
using testing_support::LorentzTable;

TEST(SceneTable, SeesNoOverlapAndBuildsOneTablePerAbsorbingPair) {
  const SceneTable& t = *F().table;
  EXPECT_TRUE(SceneTable::SpectralOverlaps(t.model()).empty());
  EXPECT_TRUE(t.has_table(0, 0) && t.has_table(0, 1));   // open channel sees both
  EXPECT_TRUE(!t.has_table(1, 0) && t.has_table(1, 1));  // CO2 channel: CO2 only
  EXPECT_TRUE(t.has_table(2, 0) && !t.has_table(2, 1));  // CH4 channel: CH4 only
  for (std::size_t c = 0; c < 4; ++c)
    for (std::size_t s = 0; s < 2; ++s)
      if (t.has_table(c, s)) {
        EXPECT_LE(t.basis_rank(c, s), 12);
      }
}

// Largest relative difference between a table and its binned model on the
// table's grid nodes.
double WorstNodeError(const SceneTable& t, const BinnedModel& m, double t_amb) {
  const double lu0 = t.min_log_u(), h = t.log_u_step();
  const double hx = 1.0 / (t.num_fraction_nodes() - 1);
  const double ht =
      (t.max_peak_temperature_K() - t.min_peak_temperature_K()) / (t.num_temperature_nodes() - 1);
  std::vector<double> phi(t.background_size());
  double worst = 0;
  for (int iu : {3, 17, 30, t.num_u_nodes() - 8}) {
    for (int ix : {1, 3}) {
      for (int it : {2, 9, t.num_temperature_nodes() - 3}) {
        const double u = std::exp(lu0 + iu * h);
        const double x = ix * hx, tp = t.min_peak_temperature_K() + it * ht;
        if (u / x > t.options().max_sigma_m) continue;
        // Species 0 alone (species 1 at 0), then species 1 alone.
        for (int s = 0; s < 2; ++s) {
          double xs[2] = {0, 0};
          xs[s] = x;
          const double tbg[4] = {tp - 15, tp - 12, tp - 20, tp - 11};
          t.Background(tbg, phi.data());
          std::vector<double> tab(4), ref(4);
          t.Contrast(xs, tp, u / x, phi.data(), tab.data(), nullptr);
          const Path p = m.GaussianPath<double>(xs, tp, t_amb, u / x);
          m.Contrast<double>(p, tbg, ref.data());
          for (int c = 0; c < 4; ++c) {
            if (ref[c] == 0) {
              EXPECT_EQ(tab[c], 0.0);
              continue;
            }
            worst = std::max(worst, std::abs(tab[c] / ref[c] - 1));
          }
        }
      }
    }
  }
  return worst;
}

TEST(SceneTable, EqualsTheBinnedModelOnItsNodes) {
  // On grid nodes the spline interpolates exactly, so any difference is the
  // decomposition E - sum phi_r A_r itself (and the Planck basis truncation).
  const Fixture& f = F();
  EXPECT_LT(WorstNodeError(*f.table, *f.model, f.t_amb), 2e-8);
}

// The default linear_optical_depth (1e-4) scales the bins that are linear in
// u to within 5e-5 instead of marching them: the nodes stay within that of
// the model.
TEST(SceneTable, LinearBinsStayWithinTheirBound) {
  const Fixture& f = F();
  SceneTableOptions so = f.table->options();
  so.linear_optical_depth = SceneTableOptions().linear_optical_depth;
  const SceneTable t(f.model, so);
  const double worst = WorstNodeError(t, *f.model, f.t_amb);
  EXPECT_LT(worst, 0.5 * so.linear_optical_depth);
  std::printf("scene table nodes with linear_optical_depth %.0e: worst relative error %.2e\n",
              so.linear_optical_depth, worst);
}

TEST(SceneTable, InterpolationErrorAndDerivativesAreSmall) {
  const TableErrorReport r = MeasureTableError(*F().table, 60, 7, 1e-3, true);
  EXPECT_LT(r.max_relative_error, 2e-3);
  EXPECT_LT(r.rms_relative_error, 3e-4);
  EXPECT_LT(r.max_jacobian_error, 5e-3);
}

TEST(SceneTable, ThinLimitIsLinearInTheColumn) {
  const SceneTable& t = *F().table;
  std::vector<double> phi(t.background_size());
  const double tbg[4] = {280, 280, 280, 280};
  t.Background(tbg, phi.data());
  const double u0 = t.min_column_proxy_m();
  double v1, v2, a, b, d;
  t.SpeciesContrast(2, 0, 0.5 * u0, 0.0, 320.0, phi.data(), &v1, &a, &b, &d);
  t.SpeciesContrast(2, 0, 0.25 * u0, 0.0, 320.0, phi.data(), &v2, &a, &b, &d);
  EXPECT_NEAR(v1 / v2, 2.0, 1e-12);
  EXPECT_NEAR(a, t.ThinSlope(2, 0, 320.0, phi.data()), 1e-12 * std::abs(a));
  // A negative u (a solver's trial step) continues the line.
  t.SpeciesContrast(2, 0, -0.25 * u0, 0.0, 320.0, phi.data(), &v1, &a, &b, &d);
  EXPECT_NEAR(v1, -v2, 1e-12 * std::abs(v2));
}

TEST(SceneTable, SlicesEqualTheTableAtTheirTemperature) {
  // A slice is the table contracted over T_peak: the same values and
  // fraction derivatives as Contrast() at that temperature, on a node and between nodes.
  const SceneTable& t = *F().table;
  std::vector<double> phi(t.background_size());
  const double tbg[4] = {281, 279, 283, 276};
  t.Background(tbg, phi.data());
  for (double tp :
       {t.min_peak_temperature_K() + 3 * (t.max_peak_temperature_K() - t.min_peak_temperature_K()) /
                                         (t.num_temperature_nodes() - 1),
        331.7}) {
    const SceneTable::Slice sl = t.MakeSlice(tp);
    for (double scale : {1e-4, 1e-2, 0.3}) {
      const double x[2] = {scale, 0.6 * scale}, sigma = 0.07;
      double ref[4], jac[4 * 4], val[4], d_dx[4 * 2];
      t.Contrast(x, tp, sigma, phi.data(), ref, jac);
      t.SliceContrast(sl, x, sigma, phi.data(), val, d_dx);
      for (int c = 0; c < 4; ++c) {
        EXPECT_NEAR(val[c], ref[c], 1e-12 * std::abs(ref[c]) + 1e-300) << "channel " << c;
        for (int s = 0; s < 2; ++s)
          EXPECT_NEAR(d_dx[c * 2 + s], jac[c * 4 + s], 1e-12 * std::abs(jac[c * 4 + s]) + 1e-300);
      }
    }
  }
}

TEST(SceneTable, RefusesSpectrallyOverlappingSpecies) {
  std::vector<SpectralResponse> ch{Bandpass(2960, 3090, "A")};
  std::vector<AbsorberTable> tabs{LorentzTable("CH4", 2930, 3120, 2955, 3095, 1, true, 40),
                                  LorentzTable("CO2", 2930, 3120, 2955, 3095, 2, false, 40)};
  auto m = std::make_shared<BinnedModel>(ch, tabs, CoarseOptions());
  EXPECT_FALSE(SceneTable::SpectralOverlaps(*m).empty());
  SceneTableOptions so;
  EXPECT_THROW(SceneTable(m, so), std::invalid_argument);
}

TEST(SceneTableOptions, RejectBadValues) {
  SceneTableOptions o;
  o.nodes_per_decade = 1;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o = SceneTableOptions();
  o.max_background_K = 100;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o = SceneTableOptions();
  o.ambient_temperature_K = -3;
  EXPECT_THROW(o.Check(), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Inversions of binned-model pixels with known truth.

struct Truth {
  double x[2], tp, sigma;
  double tbg[4];
};

// Radiance per channel of a plume (binned model) over blackbody backgrounds.
std::vector<double> Radiance(const BinnedModel& m, double t_amb, const Truth& t) {
  const Path p = m.GaussianPath<double>(t.x, t.tp, t_amb, t.sigma);
  std::vector<double> l(m.num_channels());
  m.Contrast<double>(p, t.tbg, l.data());
  for (std::size_t c = 0; c < l.size(); ++c) l[c] += m.channels()[c].BandRadiance(t.tbg[c]);
  return l;
}

struct Batch {
  std::size_t n = 0, nc = 0;
  std::vector<double> radiance, tbg;
  PixelBatch Make() const {
    PixelBatch b;
    b.num_pixels = n;
    b.radiance = radiance.data();
    b.background_temperature_K = tbg.data();
    return b;
  }
};

Batch MakeBatch(const BinnedModel& m, double t_amb, const std::vector<Truth>& truth) {
  Batch b;
  b.n = truth.size();
  b.nc = m.num_channels();
  b.radiance.assign(b.nc * b.n, 0.0);
  b.tbg.assign(b.nc * b.n, 0.0);
  for (std::size_t i = 0; i < b.n; ++i) {
    const auto l = Radiance(m, t_amb, truth[i]);
    for (std::size_t c = 0; c < b.nc; ++c) {
      b.radiance[c * b.n + i] = l[c];
      b.tbg[c * b.n + i] = truth[i].tbg[c];
    }
  }
  return b;
}

std::vector<Truth> RandomTruth(int n, unsigned seed, double t_amb) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::vector<Truth> out;
  for (int i = 0; i < n; ++i) {
    Truth t;
    const double total = std::pow(10.0, -3 + 2.5 * u01(rng));
    t.x[0] = total * (0.3 + 0.4 * u01(rng));
    t.x[1] = total - t.x[0];
    t.tp = t_amb + 5 + 65 * u01(rng);
    t.sigma = 0.02 + 0.1 * u01(rng);
    // Backgrounds colder than all of the gas (its edges are at ambient), so
    // that the contrast grows monotonically with the column.
    for (double& b : t.tbg) b = t_amb - 10 - 10 * u01(rng);
    out.push_back(t);
  }
  return out;
}

InversionOptions MultichannelOptions() {
  InversionOptions o;
  o.fractions = {ParameterSpec{ParameterMode::kFree, 1e-3, 0, 0, 1},
                 ParameterSpec{ParameterMode::kFree, 1e-3, 0, 0, 1}};
  o.temperature = ParameterSpec{ParameterMode::kFree, 0, 0, 250, 450};
  o.sigma = ParameterSpec{ParameterMode::kFixed, 0.05, 0, 0, 0};
  o.num_threads = 2;
  return o;
}

TEST(Inverter, RecoversMultichannelPlumesExactlyWithoutNoise) {
  const Fixture& f = F();
  auto truth = RandomTruth(40, 11, f.t_amb);
  const Batch b = MakeBatch(*f.model, f.t_amb, truth);
  InversionOptions o = MultichannelOptions();
  std::vector<double> sig(b.n);
  for (std::size_t i = 0; i < b.n; ++i) sig[i] = truth[i].sigma;
  const Inverter inv(f.model, f.table, f.t_amb, o);
  ASSERT_TRUE(inv.uses_table());
  PixelBatch pb = b.Make();
  pb.sigma_m = sig.data();
  InversionResult r;
  r.Allocate(b.n, 1, 2);
  inv.Invert(pb, r.Output());
  double worst_c = 0, worst_t = 0;
  for (std::size_t i = 0; i < b.n; ++i) {
    EXPECT_EQ(r.status[i], static_cast<int>(PixelStatus::kConverged))
        << "pixel " << i << " truth x " << truth[i].x[0] << " " << truth[i].x[1] << " T "
        << truth[i].tp << " got " << r.parameters[i * 4] << " " << r.parameters[i * 4 + 1] << " "
        << r.parameters[i * 4 + 2] << " chi2 " << r.chi2[i] << " it " << r.iterations[i];
    GaussianPlume g;
    g.peak_fractions = {truth[i].x[0], truth[i].x[1]};
    g.peak_temperature_K = truth[i].tp;
    g.ambient_temperature_K = f.t_amb;
    g.sigma_m = truth[i].sigma;
    const auto col = GaussianColumnDensity(g, f.model->molar_masses());
    for (int s = 0; s < 2; ++s)
      worst_c = std::max(worst_c, std::abs(r.column_density[i * 2 + s] / col[s] - 1));
    worst_t = std::max(worst_t, std::abs(r.parameters[i * 4 + 2] - truth[i].tp));
    // Uncertainties are finite and positive; chi2 ~ 0 without noise.
    EXPECT_GT(r.column_density_sigma[i * 2], 0.0);
    EXPECT_LT(r.chi2[i], 1e-2);
  }
  // The table's interpolation error is the only error source here.
  EXPECT_LT(worst_c, 5e-3);
  EXPECT_LT(worst_t, 0.3);
}

// Both species free, the gas temperature known: the fast path (table +
// TinySolver) and ceres::Solve on the full binned model must find the same
// solution and uncertainty; then with the temperature free, Ceres started at
// the fast solution must stay there (it is the full model's minimum too).
TEST(Inverter, FastPathAgreesWithCeresOnTheFullModel) {
  const Fixture& f = F();
  auto truth = RandomTruth(6, 12, f.t_amb);
  Batch b = MakeBatch(*f.model, f.t_amb, truth);
  std::vector<double> tp(b.n), sig(b.n);
  for (std::size_t i = 0; i < b.n; ++i) {
    tp[i] = truth[i].tp;
    sig[i] = truth[i].sigma;
  }
  std::mt19937 rng(5);
  std::normal_distribution<double> nd(0, 1);
  InversionOptions o = MultichannelOptions();
  o.temperature = ParameterSpec{ParameterMode::kFixed, 0, 0, 0, 0};
  const Inverter fast(f.model, f.table, f.t_amb, o);
  for (std::size_t c = 0; c < b.nc; ++c)
    for (std::size_t i = 0; i < b.n; ++i)
      b.radiance[c * b.n + i] += nd(rng) * fast.ChannelNoise(c, b.tbg[c * b.n + i]);
  PixelBatch pb = b.Make();
  pb.peak_temperature_K = tp.data();
  pb.sigma_m = sig.data();
  o.solver = SolverKind::kFullModel;
  const Inverter full(f.model, f.table, f.t_amb, o);
  EXPECT_FALSE(full.uses_table());
  InversionResult a, c;
  a.Allocate(b.n, 1, 2);
  c.Allocate(b.n, 1, 2);
  fast.Invert(pb, a.Output());
  full.Invert(pb, c.Output());
  for (std::size_t i = 0; i < b.n; ++i) {
    ASSERT_EQ(a.status[i], c.status[i]) << "pixel " << i;
    for (int s = 0; s < 2; ++s) {
      const double ca = a.column_density[i * 2 + s], cc = c.column_density[i * 2 + s];
      EXPECT_NEAR(ca, cc, 2e-3 * std::abs(cc) + 0.02 * c.column_density_sigma[i * 2 + s]);
      EXPECT_NEAR(a.column_density_sigma[i * 2 + s] / c.column_density_sigma[i * 2 + s], 1.0, 0.02);
    }
  }
  // Temperature free: Ceres on the full model, started at the fast solution.
  o = MultichannelOptions();
  const Inverter fast_t(f.model, f.table, f.t_amb, o);
  InversionResult at;
  at.Allocate(b.n, 1, 2);
  pb.peak_temperature_K = nullptr;
  fast_t.Invert(pb, at.Output());
  o.solver = SolverKind::kFullModel;
  o.initial_guess = InitialGuess::kGiven;
  const Inverter full_t(f.model, f.table, f.t_amb, o);
  pb.initial = at.parameters.data();
  InversionResult ct;
  ct.Allocate(b.n, 1, 2);
  full_t.Invert(pb, ct.Output());
  for (std::size_t i = 0; i < b.n; ++i) {
    if (at.status[i] != 0) continue;
    ASSERT_EQ(ct.status[i], 0) << "pixel " << i;
    EXPECT_NEAR(at.parameters[i * 4 + 2], ct.parameters[i * 4 + 2],
                0.1 * ct.parameter_sigma[i * 4 + 2] + 0.05);
    for (int s = 0; s < 2; ++s)
      EXPECT_NEAR(at.column_density[i * 2 + s], ct.column_density[i * 2 + s],
                  0.1 * ct.column_density_sigma[i * 2 + s] + 2e-3 * ct.column_density[i * 2 + s]);
  }
}

TEST(Inverter, StatusesBelowDetectionAtBoundAndFailed) {
  const Fixture& f = F();
  std::vector<Truth> truth(4);
  for (auto& t : truth) {
    t.x[0] = 0.05;
    t.x[1] = 0.05;
    t.tp = 340;
    t.sigma = 0.05;
    for (double& v : t.tbg) v = 320;
  }
  truth[0].x[0] = truth[0].x[1] = 0.0;  // no gas: below detection
  truth[2].x[1] = 0.0;                  // no CO2: CO2 fraction on its lower bound
  Batch b = MakeBatch(*f.model, f.t_amb, truth);
  b.radiance[0 * b.n + 3] = std::nan("");  // a dead pixel
  const Inverter inv(f.model, f.table, f.t_amb, MultichannelOptions());
  InversionResult r;
  r.Allocate(b.n, 1, 2);
  inv.Invert(b.Make(), r.Output());
  EXPECT_EQ(r.status[0], static_cast<int>(PixelStatus::kBelowDetection));
  EXPECT_EQ(r.column_density[0], 0.0);
  EXPECT_GT(r.column_density_sigma[0], 0.0);  // the noise-equivalent column
  EXPECT_EQ(r.status[1], static_cast<int>(PixelStatus::kConverged));
  EXPECT_EQ(r.status[2], static_cast<int>(PixelStatus::kAtBound));
  EXPECT_EQ(r.bound_mask[2], 1u << 1);
  EXPECT_EQ(r.parameters[2 * 4 + 1], 0.0);
  EXPECT_EQ(r.status[3], static_cast<int>(PixelStatus::kFailed));
  for (double v : r.column_density) EXPECT_TRUE(std::isfinite(v));
  for (double v : r.column_density_sigma) EXPECT_TRUE(std::isfinite(v));
}

// One channel, CH4 only, T_peak (320 K) and sigma (0.04 m) fixed: the
// scene of the single-channel tests (its model, table and options).
struct SingleChannelScene {
  std::shared_ptr<BinnedModel> m;
  std::shared_ptr<SceneTable> t;
  InversionOptions o;
};

SingleChannelScene MakeSingleChannelScene(const Fixture& f) {
  std::vector<SpectralResponse> ch{f.model->channels()[2]};
  std::vector<AbsorberTable> tabs{LorentzTable("CH4", 2930, 3120, 2955, 3095, 1, true)};
  SingleChannelScene sc;
  sc.m = std::make_shared<BinnedModel>(ch, tabs, CoarseOptions());
  SceneTableOptions so;
  so.ambient_temperature_K = f.t_amb;
  so.max_sigma_m = 2.0;
  sc.t = std::make_shared<SceneTable>(sc.m, so);
  sc.o.fractions = {ParameterSpec{ParameterMode::kFree, 1e-3, 0, 0, 1}};
  sc.o.temperature = ParameterSpec{ParameterMode::kFixed, 320.0, 0, 0, 0};
  sc.o.sigma = ParameterSpec{ParameterMode::kFixed, 0.04, 0, 0, 0};
  return sc;
}

// The contrast [W/(m2 sr)] a column x of the scene's gas (320 K, sigma 4 cm)
// makes against a 300 K background.
double SceneContrast(const SingleChannelScene& sc, const Fixture& f, double x) {
  const Path p = sc.m->GaussianPath<double>(&x, 320.0, f.t_amb, 0.04);
  double tbg = 300.0;
  double dl;
  sc.m->Contrast<double>(p, &tbg, &dl);
  return dl;
}

TEST(Inverter, SingleChannelNewtonMatchesTheGeneralSolvers) {
  // One channel, CH4 only, T_peak and sigma fixed: the Newton path.
  const Fixture& f = F();
  SingleChannelScene sc = MakeSingleChannelScene(f);
  const auto& m = sc.m;
  const auto& t = sc.t;
  InversionOptions& o = sc.o;
  const Inverter newton(m, t, f.t_amb, o);
  ASSERT_TRUE(newton.uses_newton());
  std::vector<double> xs = {3e-3, 1e-2, 5e-2, 0.3, 0.9};
  const std::size_t n = xs.size() + 2;
  std::vector<double> rad(n), tbg(n, 300.0);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    rad[i] = m->channels()[0].BandRadiance(300.0) + SceneContrast(sc, f, xs[i]);
  }
  // A pixel colder than its background although the gas is assumed warmer
  // needs a negative column: held at x = 0. One brighter than any column can make: x = 1.
  rad[n - 2] = m->channels()[0].BandRadiance(300.0) - 0.05;
  rad[n - 1] = m->channels()[0].BandRadiance(330.0);
  PixelBatch b;
  b.num_pixels = n;
  b.radiance = rad.data();
  b.background_temperature_K = tbg.data();
  InversionResult r;
  r.Allocate(n, 1, 1);
  newton.Invert(b, r.Output());
  for (std::size_t i = 0; i < xs.size(); ++i) {
    EXPECT_EQ(r.status[i], static_cast<int>(PixelStatus::kConverged));
    EXPECT_NEAR(r.parameters[i * 3] / xs[i], 1.0, 2e-3) << "x = " << xs[i];
  }
  EXPECT_EQ(r.status[n - 2], static_cast<int>(PixelStatus::kAtBound));
  EXPECT_EQ(r.parameters[(n - 2) * 3], 0.0);
  EXPECT_EQ(r.status[n - 1], static_cast<int>(PixelStatus::kAtBound));
  EXPECT_EQ(r.parameters[(n - 1) * 3], 1.0);
  // The same pixels through ceres::Solve on the full model.
  o.solver = SolverKind::kFullModel;
  const Inverter full(m, t, f.t_amb, o);
  InversionResult c;
  c.Allocate(n, 1, 1);
  full.Invert(b, c.Output());
  for (std::size_t i = 0; i < xs.size(); ++i) {
    EXPECT_NEAR(r.parameters[i * 3] / c.parameters[i * 3], 1.0, 2e-3);
    EXPECT_NEAR(r.column_density_sigma[i] / c.column_density_sigma[i], 1.0, 1e-2);
  }
}

TEST(Inverter, SignedBelowDetectionIsTheThinLimitColumnWithItsSign) {
  // Faint pixels below the detection test get column 0 by default; with
  // signed_below_detection their thin-limit least-squares column, which for
  // a thin plume is the column a full solve finds (detection_sigma 0), and
  // the negative of it for the opposite contrast (noise either way).
  const Fixture& f = F();
  SingleChannelScene sc = MakeSingleChannelScene(f);
  const auto& m = sc.m;
  const auto& t = sc.t;
  InversionOptions& o = sc.o;
  const std::vector<double> xs = {2e-6, 5e-6, 1e-5, 2e-5};
  const std::size_t n = 2 * xs.size();
  std::vector<double> rad(n), tbg(n, 300.0);
  const double l_bg = m->channels()[0].BandRadiance(300.0);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const double dl = SceneContrast(sc, f, xs[i]);
    rad[i] = l_bg + dl;
    rad[xs.size() + i] = l_bg - dl;  // the same contrast, the other sign
  }
  PixelBatch b;
  b.num_pixels = n;
  b.radiance = rad.data();
  b.background_temperature_K = tbg.data();
  InversionResult zero, sig, solved;
  zero.Allocate(n, 1, 1);
  sig.Allocate(n, 1, 1);
  solved.Allocate(n, 1, 1);
  Inverter(m, t, f.t_amb, o).Invert(b, zero.Output());
  o.signed_below_detection = true;
  Inverter(m, t, f.t_amb, o).Invert(b, sig.Output());
  o.signed_below_detection = false;
  o.detection_sigma = 0.0;
  Inverter(m, t, f.t_amb, o).Invert(b, solved.Output());
  int below = 0;
  for (std::size_t i = 0; i < xs.size(); ++i) {
    if (zero.status[i] != static_cast<int>(PixelStatus::kBelowDetection)) continue;
    ++below;
    const std::size_t j = xs.size() + i;
    ASSERT_EQ(sig.status[i], static_cast<int>(PixelStatus::kBelowDetection));
    ASSERT_EQ(solved.status[i], static_cast<int>(PixelStatus::kConverged)) << "x = " << xs[i];
    EXPECT_EQ(zero.column_density[i], 0.0);
    EXPECT_EQ(zero.column_density[j], 0.0);
    EXPECT_NEAR(sig.column_density[i] / solved.column_density[i], 1.0, 1e-2) << "x = " << xs[i];
    EXPECT_NEAR(sig.column_density[j] / sig.column_density[i], -1.0, 1e-2) << "x = " << xs[i];
    // The sigma stays the noise-equivalent column.
    EXPECT_EQ(sig.column_density_sigma[i], zero.column_density_sigma[i]);
  }
  EXPECT_GE(below, 2);
}

TEST(Inverter, WarmStartsReachTheSameAnswers) {
  const Fixture& f = F();
  auto truth = RandomTruth(12, 21, f.t_amb);
  const Batch b = MakeBatch(*f.model, f.t_amb, truth);
  InversionOptions o = MultichannelOptions();
  InversionResult base, nb, prev;
  base.Allocate(b.n, 1, 2);
  const Inverter a(f.model, f.table, f.t_amb, o);
  a.Invert(b.Make(), base.Output());
  o.initial_guess = InitialGuess::kNeighbour;
  const Inverter n(f.model, f.table, f.t_amb, o);
  nb.Allocate(b.n, 1, 2);
  n.Invert(b.Make(), nb.Output());
  // Two frames of the same image: the second starts from the first.
  o.initial_guess = InitialGuess::kPrevious;
  const Inverter p(f.model, f.table, f.t_amb, o);
  std::vector<double> rad2 = b.radiance;
  rad2.insert(rad2.end(), b.radiance.begin(), b.radiance.end());
  PixelBatch pb = b.Make();
  pb.num_frames = 2;
  pb.radiance = rad2.data();
  prev.Allocate(b.n, 2, 2);
  p.Invert(pb, prev.Output());
  for (std::size_t i = 0; i < b.n; ++i)
    for (int s = 0; s < 2; ++s) {
      const double ref = base.column_density[i * 2 + s];
      EXPECT_NEAR(nb.column_density[i * 2 + s], ref, 1e-6 * ref);
      EXPECT_NEAR(prev.column_density[(b.n + i) * 2 + s], ref, 1e-6 * ref);
      EXPECT_LE(prev.iterations[b.n + i], prev.iterations[i]);
    }
}

TEST(Inverter, FreeSigmaIsIllConditionedButTheColumnIsNot) {
  const Fixture& f = F();
  auto truth = RandomTruth(10, 31, f.t_amb);
  for (auto& t : truth) {
    t.x[0] *= 30;
    t.x[1] *= 30;
    const double sum = t.x[0] + t.x[1];
    if (sum > 0.9) {
      t.x[0] *= 0.9 / sum;
      t.x[1] *= 0.9 / sum;
    }
  }
  const Batch b = MakeBatch(*f.model, f.t_amb, truth);
  InversionOptions o = MultichannelOptions();
  o.temperature = ParameterSpec{ParameterMode::kFixed, 0, 0, 0, 0};  // known, per pixel
  o.sigma = ParameterSpec{ParameterMode::kPrior, 0.07, 0.03, 0.005, 1.0};
  const Inverter inv(f.model, f.table, f.t_amb, o);
  std::vector<double> tp(b.n);
  for (std::size_t i = 0; i < b.n; ++i) tp[i] = truth[i].tp;
  PixelBatch pb = b.Make();
  pb.peak_temperature_K = tp.data();
  InversionResult r;
  r.Allocate(b.n, 1, 2);
  inv.Invert(pb, r.Output());
  for (std::size_t i = 0; i < b.n; ++i) {
    ASSERT_LE(r.status[i], 1);
    // x and sigma trade off (their product is what the radiance measures):
    // strongly anti-correlated, sigma poorly determined, the column density
    // (proportional to x sigma) far better.
    const double* cv = &r.covariance[i * 16];
    const double corr = cv[0 * 4 + 3] / std::sqrt(cv[0 * 4 + 0] * cv[3 * 4 + 3]);
    EXPECT_LT(corr, -0.9);
    const double rel_sigma = r.parameter_sigma[i * 4 + 3] / r.parameters[i * 4 + 3];
    const double rel_col = r.column_density_sigma[i * 2] / r.column_density[i * 2];
    EXPECT_GT(rel_sigma, 3 * rel_col);
    EXPECT_GT(r.condition_number[i], 10.0);
  }
}

TEST(InversionOptions, RejectBadValues) {
  InversionOptions o;
  o.netd_K = {0.017, 0.02};
  EXPECT_THROW(o.Check(2, 4), std::invalid_argument);
  o = InversionOptions();
  o.fractions = {ParameterSpec{ParameterMode::kFree, 0.1, 0, 0.5, 0.2}};
  EXPECT_THROW(o.Check(1, 1), std::invalid_argument);
  o = InversionOptions();
  o.sigma = ParameterSpec{ParameterMode::kPrior, 0.05, 0.0, 0, 0};
  EXPECT_THROW(o.Check(1, 1), std::invalid_argument);
  o = InversionOptions();
  o.fractions = {ParameterSpec{ParameterMode::kFixed, 0.1, 0, 0, 1}};
  EXPECT_THROW(o.Check(1, 1), std::invalid_argument);  // nothing to estimate
  try {
    InversionOptions p;
    p.detection_sigma = -1;
    p.Check(1, 1);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("detection_sigma"), std::string::npos);
  }
}

TEST(GaussianProfileIntegral, MatchesEquation6) {
  for (double tp : {250.0, 293.0, 363.0, 500.0}) {
    GaussianPlume g;
    g.peak_fractions = {0.3};
    g.peak_temperature_K = tp;
    g.ambient_temperature_K = 293.0;
    g.sigma_m = 0.1;
    const double ref = GaussianColumnDensity(g, {16.0425e-3})[0];
    double i, di;
    GaussianProfileIntegral(tp, 293.0, &i, &di);
    const double k = 16.0425e-3 * constants::kAtm / (constants::kAvogadro * constants::kBoltzmann);
    EXPECT_NEAR(k * 0.3 * 0.1 * i / ref, 1.0, 1e-12);
    double ip, im;
    GaussianProfileIntegral(tp + 0.01, 293.0, &ip, nullptr);
    GaussianProfileIntegral(tp - 0.01, 293.0, &im, nullptr);
    EXPECT_NEAR(di, (ip - im) / 0.02, 1e-7 * std::abs(di));
  }
}

// The mixing-line inverter: contrasts made by the table itself on the line
// T = T_amb + k X (x = w X) are recovered to solver precision, on and off the
// line's temperature range; zero contrast is below detection; bad options are
// refused by name.
MixingLineOptions LineOptions(double slope_K_per_fraction) {
  MixingLineOptions o;
  o.slope_K_per_fraction = slope_K_per_fraction;
  o.composition = {0.5, 0.5};
  o.netd_K = {0.02};
  return o;
}

TEST(MixingLineInverter, RecoversTheLineFractionExactlyWithoutNoise) {
  const Fixture& f = F();
  const SceneTable& t = *f.table;
  MixingLineInverter inv(f.table);
  const MixingLineOptions o = LineOptions(120.0);
  const std::size_t nc = t.num_channels();
  const std::vector<double> xs{3e-3, 0.01, 0.02, 0.1, 0.4, 0.9, 0.0};
  const std::vector<double> sg{0.03, 0.05, 0.02, 0.01, 0.03, 0.005, 0.02};
  const double t_bg = 283.0;
  std::vector<double> tbg(nc, t_bg), phi(t.background_size()), l_bg(nc);
  t.Background(tbg.data(), phi.data());
  for (std::size_t c = 0; c < nc; ++c) l_bg[c] = t.model().channels()[c].BandRadiance(t_bg);
  const std::size_t n = xs.size();
  std::vector<double> rad(n * nc), bg(n * nc);
  for (std::size_t i = 0; i < n; ++i) {
    const double x[2] = {0.5 * xs[i], 0.5 * xs[i]};
    const double tp = std::min(f.t_amb + o.slope_K_per_fraction * xs[i], 450.0);
    std::vector<double> m(nc);
    t.Contrast(x, tp, sg[i], phi.data(), m.data(), nullptr);
    for (std::size_t c = 0; c < nc; ++c) {
      rad[i * nc + c] = l_bg[c] + m[c];
      bg[i * nc + c] = l_bg[c];
    }
  }
  std::vector<double> x(n), xsig(n), tp(n), chi2(n);
  std::vector<std::int32_t> status(n), iters(n);
  inv.Invert(o, n, rad.data(), bg.data(), sg.data(),
             {x.data(), xsig.data(), tp.data(), chi2.data(), status.data(), iters.data()});
  for (std::size_t i = 0; i + 1 < n; ++i) {
    EXPECT_EQ(status[i], static_cast<int>(PixelStatus::kConverged)) << i;
    EXPECT_NEAR(x[i] / xs[i], 1.0, 1e-5) << "X " << xs[i];
    EXPECT_LT(chi2[i], 1e-8);
    EXPECT_GT(xsig[i], 0);
  }
  EXPECT_EQ(status[n - 1], static_cast<int>(PixelStatus::kBelowDetection));
  EXPECT_EQ(x[n - 1], 0.0);
  EXPECT_GT(xsig[n - 1], 0.0);  // the thin-limit 1-sigma
  MixingLineOptions bad = o;
  bad.composition = {1.0};
  EXPECT_THROW(
      inv.Invert(bad, n, rad.data(), bg.data(), sg.data(),
                 {x.data(), xsig.data(), tp.data(), chi2.data(), status.data(), iters.data()}),
      std::invalid_argument);
  bad = o;
  bad.netd_K = {0.0};
  EXPECT_THROW(bad.Check(2, nc), std::invalid_argument);
}

// A background radiance that only a blackbody outside the scene table's
// background range gives fails the pixel (the band table would invert it,
// but the table serves no such background).
TEST(MixingLineInverter, FailsABackgroundOutsideTheTablesRange) {
  const Fixture& f = F();
  const SceneTable& t = *f.table;
  MixingLineInverter inv(f.table);
  const MixingLineOptions o = LineOptions(120.0);
  const std::size_t nc = t.num_channels();
  const std::vector<double> t_bg{t.options().min_background_K - 30.0,
                                 t.options().max_background_K + 50.0, 283.0};
  const std::size_t n = t_bg.size();
  std::vector<double> rad(n * nc), sg(n, 0.03);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t c = 0; c < nc; ++c)
      rad[i * nc + c] = t.model().channels()[c].BandRadiance(t_bg[i]);
  std::vector<double> x(n), xsig(n), tp(n), chi2(n);
  std::vector<std::int32_t> status(n), iters(n);
  inv.Invert(o, n, rad.data(), rad.data(), sg.data(),
             {x.data(), xsig.data(), tp.data(), chi2.data(), status.data(), iters.data()});
  EXPECT_EQ(status[0], static_cast<int>(PixelStatus::kFailed));
  EXPECT_EQ(status[1], static_cast<int>(PixelStatus::kFailed));
  EXPECT_EQ(status[2], static_cast<int>(PixelStatus::kBelowDetection));
}

// Pixels sharing a plume depth are solved on the line's tabulation (cubic
// Hermite in ln X): the same fractions as evaluating the table per pixel,
// to a small fraction of their 1-sigma, on noisy pixels over three decades
// of X and two depths.
TEST(MixingLineInverter, LineTablesAgreeWithTheTable) {
  const Fixture& f = F();
  const SceneTable& t = *f.table;
  MixingLineInverter inv(f.table);
  const MixingLineOptions o = LineOptions(90.0);
  const std::size_t nc = t.num_channels(), n = 4000;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<double> rad(n * nc), bg(n * nc), sg(n), truth(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double big_x = std::pow(10.0, -3.0 + 2.95 * u01(rng));
    truth[i] = big_x;
    sg[i] = i % 2 ? 0.02 : 0.045;
    const double t_bg = 280.0 + 15.0 * u01(rng);
    std::vector<double> tbg(nc, t_bg), phi(t.background_size()), m(nc);
    t.Background(tbg.data(), phi.data());
    const double x[2] = {0.5 * big_x, 0.5 * big_x};
    const double tp = std::min(f.t_amb + o.slope_K_per_fraction * big_x, 450.0);
    t.Contrast(x, tp, sg[i], phi.data(), m.data(), nullptr);
    for (std::size_t c = 0; c < nc; ++c) {
      const SpectralResponse& channel = t.model().channels()[c];
      const double l_bg = channel.BandRadiance(t_bg);
      const double noise = 0.02 * channel.BandRadianceDerivative(t_bg);
      bg[i * nc + c] = l_bg;
      rad[i * nc + c] = l_bg + m[c] + noise * gauss(rng);
    }
  }
  auto run = [&](int per_unit, std::vector<double>* x, std::vector<double>* xs,
                 std::vector<double>* chi2, std::vector<std::int32_t>* status) {
    MixingLineOptions oo = o;
    oo.line_nodes_per_unit = per_unit;
    std::vector<double> tp(n);
    std::vector<std::int32_t> iters(n);
    x->resize(n);
    xs->resize(n);
    chi2->resize(n);
    status->resize(n);
    inv.Invert(oo, n, rad.data(), bg.data(), sg.data(),
               {x->data(), xs->data(), tp.data(), chi2->data(), status->data(), iters.data()});
  };
  std::vector<double> x0, s0, c0, x1, s1, c1;
  std::vector<std::int32_t> st0, st1;
  run(0, &x0, &s0, &c0, &st0);
  run(16, &x1, &s1, &c1, &st1);
  int compared = 0, same_status = 0;
  double worst = 0;
  for (std::size_t i = 0; i < n; ++i) {
    same_status += st0[i] == st1[i];
    if (st0[i] != static_cast<int>(PixelStatus::kConverged) || st1[i] != st0[i]) continue;
    ++compared;
    // Noise-limited pixels: against sigma_X; the others (sigma_X below
    // 1e-3 X) against X.
    const double d = std::abs(x1[i] - x0[i]);
    worst = std::max(worst, s0[i] > 1e-3 * x0[i] ? d / s0[i] : d / (1e-3 * x0[i]));
    EXPECT_NEAR(c1[i], c0[i], 0.02) << i;  // Delta chi2 = 1 is one sigma
  }
  // No detected plume ends on the lower bound of X (a too-sparse scan left
  // ~1 % of the pixels with X of 0.03-0.05 there, chi2 20-400).
  int stuck = 0;
  for (std::size_t i = 0; i < n; ++i)
    stuck += truth[i] > 0.01 && st1[i] == static_cast<int>(PixelStatus::kAtBound);
  EXPECT_EQ(stuck, 0);
  EXPECT_GT(compared, 3000);
  EXPECT_EQ(same_status, static_cast<int>(n));
  EXPECT_LT(worst, 0.01) << "largest |X_line - X_table| / max(sigma_X, 1e-3 X)";
  std::printf(
      "line tables vs table: %d converged pixels compared, %d of %zu same status, "
      "largest |dX| / max(sigma_X, 1e-3 X) %.2e\n",
      compared, same_status, n, worst);
  bool bad = false;
  MixingLineOptions b = o;
  b.line_nodes_per_unit = -1;
  try {
    b.Check(2, nc);
  } catch (const std::invalid_argument&) {
    bad = true;
  }
  EXPECT_TRUE(bad);
}

}  // namespace
}  // namespace qogi
