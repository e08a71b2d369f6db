// Planck's law against analytic physics: Stefan-Boltzmann, Wien, limits.
#include "engine/optics/planck.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace qogi {
namespace {

using constants::kC2;

TEST(Planck, ConstantsMatchTextbookValues) {
  EXPECT_NEAR(constants::kC1, 1.191042972e-8, 1e-16);
  EXPECT_NEAR(kC2, 1.438776877, 1e-9);
  // sigma = 2 pi^5 k^4 / (15 h^3 c^2)
  const double k = constants::kBoltzmann, h = constants::kPlanck, c = constants::kSpeedOfLight;
  EXPECT_NEAR(2 * std::pow(constants::kPi, 5) * std::pow(k, 4) / (15 * h * h * h * c * c),
              constants::kStefanBoltzmann, 1e-16);
}

TEST(Planck, RayleighJeansLimitAtLowWavenumber) {
  // c2 nu / T << 1: B -> c1 nu^2 T / c2.
  const double nu = 1e-3, t = 1000;
  EXPECT_NEAR(PlanckRadiance(nu, t) / (constants::kC1 * nu * nu * t / kC2), 1.0, 1e-6);
}

TEST(Planck, WienPeakWhereWienLawPutsIt) {
  for (double t : {200.0, 296.0, 1000.0, 1500.0}) {
    const double expected = constants::kWienNu * t;
    // Golden-section search for the maximum of B(nu, T).
    double a = 0.2 * expected, b = 5 * expected;
    const double g = 0.5 * (std::sqrt(5.0) - 1);
    for (int i = 0; i < 200; ++i) {
      const double c = b - g * (b - a), d = a + g * (b - a);
      if (PlanckRadiance(c, t) > PlanckRadiance(d, t))
        b = d;
      else
        a = c;
    }
    EXPECT_NEAR(0.5 * (a + b) / expected, 1.0, 1e-7) << "T = " << t;
  }
}

TEST(Planck, DerivativeMatchesFiniteDifference) {
  for (double nu : {500.0, 2000.0, 3000.0, 6000.0})
    for (double t : {220.0, 300.0, 900.0}) {
      const double h = 1e-3;
      const double fd = (PlanckRadiance(nu, t + h) - PlanckRadiance(nu, t - h)) / (2 * h);
      EXPECT_NEAR(PlanckRadianceDerivative(nu, t) / fd, 1.0, 1e-7);
    }
}

TEST(Planck, ZeroAtZeroWavenumberAndUnderflowIsZeroNotNaN) {
  EXPECT_EQ(PlanckRadiance(0.0, 300), 0.0);
  EXPECT_EQ(PlanckRadiance(1e5, 10.0), 0.0);
  EXPECT_EQ(PlanckRadianceDerivative(1e5, 10.0), 0.0);
}

TEST(Planck, RejectsBadArguments) {
  EXPECT_THROW(PlanckRadiance(3000, -5), std::invalid_argument);
  EXPECT_THROW(PlanckRadiance(3000, 0), std::invalid_argument);
  EXPECT_THROW(PlanckRadiance(3000, std::nan("")), std::invalid_argument);
  EXPECT_THROW(PlanckRadiance(-1, 300), std::invalid_argument);
  EXPECT_THROW(PlanckRadiance(std::numeric_limits<double>::infinity(), 300), std::invalid_argument);
  try {
    PlanckRadiance(3000, -5);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("temperature_K"), std::string::npos);
  }
}

}  // namespace
}  // namespace qogi
