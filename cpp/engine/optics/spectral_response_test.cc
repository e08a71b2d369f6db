// Band radiance against analytic physics and the thesis's Table 4.
#include "engine/optics/spectral_response.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "engine/optics/planck.h"

namespace qogi {
namespace {

SpectralResponse Flat(double lo, double hi, const char* name = "flat") {
  return SpectralResponse({lo, hi}, {1.0, 1.0}, name);
}

TEST(SpectralResponse, WideBandConvergesToStefanBoltzmann) {
  for (double t : {200.0, 300.0, 1000.0, 1500.0}) {
    // Up to c2 nu / T = 40 the missing tail is below 1e-12 relative.
    const SpectralResponse wide = Flat(0.0, 40.0 * t / constants::kC2);
    const double expected = constants::kStefanBoltzmann * std::pow(t, 4) / constants::kPi;
    EXPECT_NEAR(wide.BandRadiance(t) / expected, 1.0, 1e-6) << "T = " << t;
  }
}

TEST(SpectralResponse, ThesisTable4OpenBandAt288_7K) {
  // Thesis Table 4: a 288.7 K blackbody over 1852-6667 cm-1 is 2.09 W/(m2 sr).
  EXPECT_NEAR(Flat(1852, 6667).BandRadiance(288.7), 2.09, 0.005);
}

TEST(SpectralResponse, RadiometricTemperatureRoundTrip) {
  // 3.2-3.4 um narrow band (smooth edges) and the wide InSb band.
  std::vector<double> nu, r;
  for (double x = 2900; x <= 3150; x += 0.5) {
    nu.push_back(x);
    r.push_back(std::exp(-std::pow((x - 3030) / 70.0, 8)));
  }
  const SpectralResponse narrow(nu, r, "narrow");
  const SpectralResponse wide = Flat(1852, 6667, "wide");
  for (const SpectralResponse* ch : {&narrow, &wide})
    for (double t = 200; t <= 1500; t += 13.7) {
      const double l = ch->BandRadiance(t);
      EXPECT_NEAR(ch->RadiometricTemperature(l), t, 1e-6) << ch->name() << " T=" << t;
    }
}

TEST(SpectralResponse, DerivativeMatchesFiniteDifference) {
  const SpectralResponse ch = Flat(2941, 3125);
  for (double t : {250.0, 300.0, 600.0}) {
    const double fd = (ch.BandRadiance(t + 1e-3) - ch.BandRadiance(t - 1e-3)) / 2e-3;
    EXPECT_NEAR(ch.BandRadianceDerivative(t) / fd, 1.0, 1e-7);
  }
}

TEST(SpectralResponse, PiecewiseLinearIntegralIsExact) {
  // Triangle of height 2 over [1000, 1100]: area 100.
  const SpectralResponse tri({1000, 1050, 1100}, {0, 2, 0}, "tri");
  EXPECT_NEAR(tri.Integral(), 100.0, 1e-10);
  EXPECT_NEAR(tri.CentroidWavenumber(), 1050.0, 1e-9);
  EXPECT_NEAR(tri.Evaluate(1025), 1.0, 1e-12);
  EXPECT_EQ(tri.Evaluate(999), 0.0);
}

TEST(SpectralResponse, RejectsBadGrids) {
  EXPECT_THROW(SpectralResponse({}, {}), std::invalid_argument);
  EXPECT_THROW(SpectralResponse({1, 2, 3}, {1, 1}), std::invalid_argument);
  EXPECT_THROW(SpectralResponse({1, 3, 2}, {1, 1, 1}), std::invalid_argument);
  EXPECT_THROW(SpectralResponse({1, 2}, {1, -1}), std::invalid_argument);
  EXPECT_THROW(SpectralResponse({1, 2}, {0, 0}), std::invalid_argument);
  EXPECT_THROW(SpectralResponse({1, std::nan("")}, {1, 1}), std::invalid_argument);
  try {
    SpectralResponse({1, 3, 2}, {1, 1, 1}, "bad");
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("nu_cm1[2]"), std::string::npos) << e.what();
  }
}

TEST(SpectralResponse, RadiometricTemperatureRejectsImpossibleRadiance) {
  const SpectralResponse ch = Flat(2941, 3125);
  EXPECT_THROW(ch.RadiometricTemperature(-1.0), std::invalid_argument);
  EXPECT_THROW(ch.RadiometricTemperature(0.0), std::invalid_argument);
  EXPECT_THROW(ch.RadiometricTemperature(std::nan("")), std::invalid_argument);
  EXPECT_THROW(ch.RadiometricTemperature(1e30), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
