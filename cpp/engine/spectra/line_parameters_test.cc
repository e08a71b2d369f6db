#include "engine/spectra/line_parameters.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace qogi {
namespace {

LineList TwoCh4Lines() {
  LineList l;
  for (int k = 0; k < 2; ++k) {
    l.molecule.push_back(6);
    l.isotopologue.push_back(1);
    l.nu_cm1.push_back(3000.0);
    l.intensity.push_back(1e-20);
    l.einstein_a.push_back(0);
    l.gamma_air.push_back(0.05);
    l.gamma_self.push_back(0.08);
    l.elower_cm1.push_back(k == 0 ? 0.0 : 1000.0);
    l.n_air.push_back(0.7);
    l.n_self.push_back(0.6);
    l.delta_air.push_back(-0.006);
    l.delta_self.push_back(-0.010);
  }
  return l;
}

TEST(LineParameters, ReferenceConditionsReproduceTheCatalogue) {
  const LineList l = TwoCh4Lines();
  const LineParameters p = ComputeLineParameters(l, GasConditions{296.0, 101325.0, 0.0});
  for (int k = 0; k < 2; ++k) {
    EXPECT_NEAR(p.intensity[k] / 1e-20, 1.0, 1e-12);
    EXPECT_NEAR(p.gamma_lorentz[k], 0.05, 1e-15);
    EXPECT_NEAR(p.center_cm1[k], 3000.0 - 0.006, 1e-12);
    // Doppler HWHM = 3.581163e-7 nu sqrt(T / M[g/mol]) (the usual numerical
    // form of nu/c sqrt(2 ln2 k T / m)).
    EXPECT_NEAR(p.gamma_doppler[k] / (3.581163e-7 * 3000.0 * std::sqrt(296.0 / 16.0313)), 1.0,
                1e-6);
  }
  const LineParameters noshift = ComputeLineParameters(l, GasConditions{}, false);
  EXPECT_DOUBLE_EQ(noshift.center_cm1[0], 3000.0);
}

TEST(LineParameters, PressureSelfFractionAndTemperatureExponents) {
  const LineList l = TwoCh4Lines();
  const double atm = 101325.0;
  const LineParameters two = ComputeLineParameters(l, GasConditions{296.0, 2 * atm, 0.0});
  EXPECT_NEAR(two.gamma_lorentz[0], 0.10, 1e-14);
  EXPECT_NEAR(two.center_cm1[0], 3000.0 - 0.012, 1e-12);
  const LineParameters self = ComputeLineParameters(l, GasConditions{296.0, atm, 1.0});
  EXPECT_NEAR(self.gamma_lorentz[0], 0.08, 1e-14);
  EXPECT_NEAR(self.center_cm1[0], 3000.0 - 0.010, 1e-12);
  const LineParameters mix = ComputeLineParameters(l, GasConditions{400.0, atm, 0.3});
  const double r = 296.0 / 400.0;
  EXPECT_NEAR(mix.gamma_lorentz[0], 0.7 * 0.05 * std::pow(r, 0.7) + 0.3 * 0.08 * std::pow(r, 0.6),
              1e-14);
  EXPECT_NEAR(mix.center_cm1[0], 3000.0 + 0.7 * -0.006 + 0.3 * -0.010, 1e-12);
  // Doppler width grows as sqrt(T) and does not depend on pressure.
  EXPECT_NEAR(mix.gamma_doppler[0] / two.gamma_doppler[0], std::sqrt(400.0 / 296.0), 1e-12);
  const LineParameters vacuum = ComputeLineParameters(l, GasConditions{296.0, 0.0, 0.0});
  EXPECT_EQ(vacuum.gamma_lorentz[0], 0.0);
}

TEST(LineParameters, IntensityRatioFollowsTheBoltzmannFactor) {
  // Two lines at the same wavenumber differ only by E'': the partition sum and
  // stimulated emission cancel in their ratio, leaving exp(-c2 dE (1/T - 1/Tref)).
  const LineList l = TwoCh4Lines();
  const double c2 = 1.4387768775039337;  // h c / k_B [cm K] (CODATA 2018, exact)
  for (double t : {200.0, 250.0, 350.0, 500.0, 800.0}) {
    const LineParameters p = ComputeLineParameters(l, GasConditions{t, 101325.0, 0.0});
    EXPECT_NEAR(p.intensity[1] / p.intensity[0] / std::exp(-c2 * 1000.0 * (1.0 / t - 1.0 / 296.0)),
                1.0, 1e-12)
        << t;
    // A line from the ground state weakens as Q(T) grows.
    if (t > 296) {
      EXPECT_LT(p.intensity[0], 1e-20);
    } else {
      EXPECT_GT(p.intensity[0], 1e-20);
    }
  }
}

TEST(LineParameters, ClearErrors) {
  LineList l = TwoCh4Lines();
  EXPECT_THROW(ComputeLineParameters(l, GasConditions{-1.0, 101325.0, 0.0}), std::invalid_argument);
  EXPECT_THROW(ComputeLineParameters(l, GasConditions{296.0, -1.0, 0.0}), std::invalid_argument);
  EXPECT_THROW(ComputeLineParameters(l, GasConditions{296.0, 101325.0, 1.5}),
               std::invalid_argument);
  EXPECT_THROW(ComputeLineParameters(l, GasConditions{3000.0, 101325.0, 0.0}),
               std::invalid_argument);
  l.molecule[1] = 3;  // O3: no partition sums shipped
  try {
    ComputeLineParameters(l, GasConditions{});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("O3"), std::string::npos);
  }
  l.molecule[1] = 6;
  l.gamma_air.pop_back();
  EXPECT_THROW(ComputeLineParameters(l, GasConditions{}), std::invalid_argument);
}

TEST(LineParameters, NumberDensity) {
  // Loschmidt's constant at 273.15 K and 1 atm: 2.686780111e19 molecule/cm3 (CODATA 2018).
  EXPECT_NEAR(NumberDensity_cm3(101325.0, 273.15) / 2.686780111e19, 1.0, 1e-9);
}

}  // namespace
}  // namespace qogi
