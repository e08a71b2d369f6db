#include "engine/camera/warm_optics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

#include "engine/camera/camera.h"
#include "engine/optics/planck.h"

namespace qogi {
namespace {

// Smooth analytic components over 1800-6700 cm-1 (an InSb-like detector, a
// 4.2-4.45 um band-pass with some out-of-band reflectance, a lens whose
// transmittance falls towards the band edges).
double Det(double nu) { return 1.0 / (1.0 + std::exp(-(nu - 1900.0) / 15.0)); }
double TauF(double nu) {
  const double a = 1.0 / (1.0 + std::exp(-(nu - 2250.0) / 8.0));
  const double b = 1.0 / (1.0 + std::exp((nu - 2380.0) / 8.0));
  return 0.8 * a * b;
}
double RhoF(double nu) { return 0.9 * (1.0 - TauF(nu) / 0.8); }
double TauL(double nu) { return 0.92 - 0.1 * std::pow((nu - 3500.0) / 2000.0, 2); }

std::vector<double> Sample(const std::vector<double>& nu, double (*f)(double)) {
  std::vector<double> out;
  for (double x : nu) out.push_back(f(x));
  return out;
}

std::vector<double> Grid(double lo, double hi, double step) {
  std::vector<double> nu;
  for (int i = 0; lo + i * step <= hi + 1e-9; ++i) nu.push_back(lo + i * step);
  return nu;
}

// Independent reference: composite Simpson over [1800, 6700] cm-1 on a grid
// 8x finer than the model's samples, of the analytic integrand.
double Integral(const std::function<double(double)>& f) {
  const double lo = 1800.0, hi = 6700.0;
  const int n = 8 * 4900;
  const double h = (hi - lo) / n;
  double s = f(lo) + f(hi);
  for (int i = 1; i < n; ++i) s += (i % 2 ? 4.0 : 2.0) * f(lo + i * h);
  return s * h / 3.0;
}

ChannelOptics Analytic(bool reflective) {
  const std::vector<double> nu = Grid(1800.0, 6700.0, 1.0);
  return ChannelOptics(nu, Sample(nu, Det), Sample(nu, TauF), Sample(nu, TauL),
                       reflective ? Sample(nu, RhoF) : std::vector<double>{}, "test");
}

TEST(WarmOptics, VanishesForAPerfectlyTransmittingFilter) {
  const std::vector<double> nu = Grid(1800.0, 6700.0, 1.0);
  const std::vector<double> one(nu.size(), 1.0);
  const ChannelOptics clear(nu, Sample(nu, Det), one, Sample(nu, TauL));
  EXPECT_EQ(clear.FilterTerm(300.0), 0.0);
  // What remains is the lens's own emission, through the (clear) filter.
  EXPECT_NEAR(clear.WarmRadiance(300.0, 300.0),
              Integral([](double x) { return Det(x) * (1 - TauL(x)) * PlanckRadiance(x, 300.0); }),
              1e-5 * clear.WarmRadiance(300.0, 300.0));
  const ChannelOptics perfect(nu, Sample(nu, Det), one, one);
  EXPECT_EQ(perfect.WarmRadiance(300.0, 330.0), 0.0);
  EXPECT_EQ(perfect.WarmRadiance(300.0, 330.0, 300.0), 0.0);
}

TEST(WarmOptics, OpaqueFilterEmitsAsABlackbodyThroughDetectorTimesEmissivity) {
  const std::vector<double> nu = Grid(1800.0, 6700.0, 1.0);
  // Opaque-ish: 1e-9 transmittance (a channel must transmit somewhere).
  const std::vector<double> zero(nu.size(), 1e-9);
  const ChannelOptics opaque(nu, Sample(nu, Det), zero, Sample(nu, TauL), Sample(nu, RhoF));
  for (double tf : {250.0, 293.15, 320.0}) {
    const double ref =
        Integral([tf](double x) { return Det(x) * (1 - RhoF(x)) * PlanckRadiance(x, tf); });
    // Independent of the lens (nothing passes the filter), 5e-6: sampling.
    EXPECT_NEAR(opaque.WarmRadiance(200.0, tf), ref, 5e-6 * ref);
    EXPECT_NEAR(opaque.WarmRadiance(350.0, tf), ref, 5e-6 * ref);
  }
  // Absorbing, not reflecting: emissivity 1 - 1e-9 over the whole detector band.
  const ChannelOptics black(nu, Sample(nu, Det), zero, Sample(nu, TauL));
  EXPECT_NEAR(black.WarmRadiance(0.0, 293.15) / black.DetectorBandRadiance(293.15), 1.0, 2e-9);
}

TEST(WarmOptics, EachTermMatchesAnIndependentIntegral) {
  const ChannelOptics o = Analytic(true);
  const double tl = 296.0, tf = 303.0, tr = 280.0;
  const double lens =
      Integral([&](double x) { return Det(x) * TauF(x) * (1 - TauL(x)) * PlanckRadiance(x, tl); });
  const double filt =
      Integral([&](double x) { return Det(x) * (1 - TauF(x) - RhoF(x)) * PlanckRadiance(x, tf); });
  const double refl = Integral([&](double x) { return Det(x) * RhoF(x) * PlanckRadiance(x, tr); });
  EXPECT_NEAR(o.LensTerm(tl), lens, 1e-5 * lens);
  EXPECT_NEAR(o.FilterTerm(tf), filt, 1e-5 * filt);
  EXPECT_NEAR(o.ReflectedTerm(tr), refl, 1e-5 * refl);
  EXPECT_NEAR(o.WarmRadiance(tl, tf, tr), lens + filt + refl, 1e-5 * (lens + filt + refl));
  EXPECT_EQ(o.WarmRadiance(tl, tf), o.LensTerm(tl) + o.FilterTerm(tf));  // 0 K: cold
  // Derivatives against central differences.
  const double h = 0.01;
  EXPECT_NEAR(o.WarmRadianceDerivativeLens(tl), (o.LensTerm(tl + h) - o.LensTerm(tl - h)) / (2 * h),
              1e-6 * o.WarmRadianceDerivativeLens(tl));
  EXPECT_NEAR(o.WarmRadianceDerivativeFilter(tf),
              (o.FilterTerm(tf + h) - o.FilterTerm(tf - h)) / (2 * h),
              1e-6 * o.WarmRadianceDerivativeFilter(tf));
}

TEST(WarmOptics, CorrectionIsTheExactInverseOfTheForward) {
  const ChannelOptics o = Analytic(true);
  for (double l : {0.01, 0.2, 1.5})
    for (double t : {273.0, 293.15, 313.0}) {
      const double m = o.Measured(l, t, t + 2.0, 77.0);
      EXPECT_GT(m, l);
      EXPECT_NEAR(o.Corrected(m, t, t + 2.0, 77.0), l, 1e-15 * m);
    }
}

TEST(WarmOptics, ClosedIsothermalSystemIsABlackbodyThroughTheDetector) {
  // Kirchhoff: scene, lens, filter (and what the filter reflects) at one
  // temperature give the detector's blackbody band radiance, whatever the
  // optics.
  for (bool reflective : {false, true}) {
    const ChannelOptics o = Analytic(reflective);
    for (double t : {250.0, 293.15, 350.0}) {
      const double scene = o.response().BandRadiance(t);
      const double total = o.Measured(scene, t, t, t);
      const double ref = Integral([t](double x) { return Det(x) * PlanckRadiance(x, t); });
      EXPECT_NEAR(total / o.DetectorBandRadiance(t), 1.0, 1e-12);
      EXPECT_NEAR(total / ref, 1.0, 1e-5);
    }
  }
}

TEST(WarmOptics, PresetOpticsReproduceThePresetChannels) {
  for (const std::string name : {"fast-m150", "gf320"}) {
    const CameraModel cam = CameraPreset(name);
    const std::vector<ChannelOptics> optics = CameraPresetOptics(name);
    ASSERT_EQ(optics.size(), cam.channels.size());
    for (std::size_t c = 0; c < optics.size(); ++c) {
      const SpectralResponse& ch = cam.channels[c];
      EXPECT_EQ(optics[c].name(), ch.name());
      for (std::size_t i = 0; i < ch.nu_cm1().size(); ++i)
        EXPECT_NEAR(optics[c].response().Evaluate(ch.nu_cm1()[i]), ch.response()[i], 1e-14);
      EXPECT_NEAR(optics[c].response().BandRadiance(293.15) / ch.BandRadiance(293.15), 1.0, 1e-9);
    }
  }
  EXPECT_THROW(CameraPresetOptics("gf999"), std::invalid_argument);
}

TEST(WarmOptics, WarmerOpticsEmitMore) {
  const ChannelOptics o = CameraPresetOptics("fast-m150")[1];
  double prev = 0;
  for (double t = 273.0; t <= 323.0; t += 5.0) {
    const double w = o.WarmRadiance(t, t);
    EXPECT_GT(w, prev);
    prev = w;
  }
  // The open position has no filter: only the lens emits.
  const ChannelOptics open = CameraPresetOptics("fast-m150")[0];
  EXPECT_EQ(open.FilterTerm(300.0), 0.0);
  EXPECT_GT(open.LensTerm(300.0), 0.0);
}

TEST(WarmOptics, RejectsBadComponentsAndTemperatures) {
  const std::vector<double> nu = {2000.0, 3000.0};
  EXPECT_THROW(ChannelOptics(nu, {1, 1}, {1.2, 1}, {1, 1}), std::invalid_argument);
  EXPECT_THROW(ChannelOptics(nu, {1, 1}, {0.5, 0.5}, {1, -0.1}), std::invalid_argument);
  EXPECT_THROW(ChannelOptics(nu, {1, 1}, {0.5, 0.5}, {1, 1}, {0.6, 0.2}),
               std::invalid_argument);  // tau + rho > 1
  EXPECT_THROW(ChannelOptics(nu, {1}, {0.5, 0.5}, {1, 1}), std::invalid_argument);
  EXPECT_THROW(ChannelOptics(nu, {1, 1}, {0, 0}, {1, 1}), std::invalid_argument);  // no response
  const ChannelOptics o(nu, {1, 1}, {0.5, 0.5}, {0.9, 0.9});
  EXPECT_THROW(o.WarmRadiance(-1.0, 300.0), std::invalid_argument);
  EXPECT_THROW(o.WarmRadiance(300.0, std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
