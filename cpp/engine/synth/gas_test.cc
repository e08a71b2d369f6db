// Thermodynamics against tabulated reference data and conservation laws.
#include "engine/synth/gas.h"

#include <gtest/gtest.h>

#include <cmath>

#include "engine/synth/release.h"

namespace qogi::synth {
namespace {

// NIST Chemistry WebBook tabulated ideal-gas cp [J/(mol K)] (Gurvich et al.
// 1989 for CH4; JANAF for CO2, N2, O2).
TEST(Species, HeatCapacityMatchesTabulatedValues) {
  struct Ref {
    const char* name;
    double t, cp;
  };
  const Ref refs[] = {{"CH4", 300, 35.76}, {"CH4", 400, 40.63}, {"CH4", 500, 46.63},
                      {"CO2", 300, 37.22}, {"CO2", 400, 41.33}, {"N2", 300, 29.12},
                      {"N2", 400, 29.25},  {"O2", 300, 29.39},  {"O2", 400, 30.11},
                      {"Ar", 300, 20.79}};
  for (const Ref& r : refs)
    EXPECT_NEAR(FindSpecies(r.name).HeatCapacity(r.t), r.cp, 0.007 * r.cp) << r.name << " " << r.t;
}

TEST(Species, EnthalpyIsTheIntegralOfHeatCapacity) {
  for (const std::string& name : KnownSpecies()) {
    const Species& s = FindSpecies(name);
    // Simpson's rule from 298.15 K to 400 K.
    const int n = 200;
    const double a = 298.15, b = 400.0, h = (b - a) / n;
    double sum = s.HeatCapacity(a) + s.HeatCapacity(b);
    for (int i = 1; i < n; ++i) sum += (i % 2 ? 4 : 2) * s.HeatCapacity(a + i * h);
    EXPECT_NEAR(s.Enthalpy(b), sum * h / 3, 1e-6) << name;
    EXPECT_NEAR(s.Enthalpy(298.15), 0.0, 1e-9) << name;
  }
}

TEST(Species, UnknownNameListsTheKnownOnes) {
  try {
    FindSpecies("XYZ");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("CH4"), std::string::npos);
  }
}

TEST(GasMixture, DryAirMolarMassAndHeatCapacity) {
  const GasMixture air = GasMixture::DryAir();
  EXPECT_NEAR(air.molar_mass_kg_mol(), 28.965e-3, 0.002e-3);  // US Standard Atmosphere
  EXPECT_NEAR(air.SpecificHeatCapacity(300.0), 1005.0, 4.0);  // J/(kg K)
  // Ideal-gas density at 20 C, 1 atm: 1.204 kg/m3.
  EXPECT_NEAR(air.Density(293.15, 101325.0), 1.204, 0.002);
}

TEST(GasMixture, RejectsBadCompositions) {
  EXPECT_THROW(GasMixture({{"CH4", 0.5}}), std::invalid_argument);
  EXPECT_THROW(GasMixture({{"CH4", -0.1}, {"CO2", 1.1}}), std::invalid_argument);
  EXPECT_THROW(GasMixture({}), std::invalid_argument);
  const GasMixture g({{"CH4", 0.5}, {"CO2", 0.5}});
  EXPECT_NEAR(g.mass_fractions()[0], 16.0425 / (16.0425 + 44.0095), 1e-12);
}

TEST(MixingModel, ConservesEnthalpyAndReachesBothEnds) {
  const GasMixture rel({{"CH4", 0.5}, {"CO2", 0.5}});
  const MixingModel mix(rel, 363.15, GasMixture::DryAir(), 293.15, 101325.0);
  EXPECT_NEAR(mix.TemperatureAtMassFraction(0.0), 293.15, 1e-9);
  EXPECT_NEAR(mix.TemperatureAtMassFraction(1.0), 363.15, 1e-9);
  const GasMixture air = GasMixture::DryAir();
  for (double y : {0.01, 0.1, 0.3, 0.7}) {
    const double t = mix.TemperatureAtMassFraction(y);
    const double h_mix = y * rel.SpecificEnthalpy(t) + (1 - y) * air.SpecificEnthalpy(t);
    const double h_in = y * rel.SpecificEnthalpy(363.15) + (1 - y) * air.SpecificEnthalpy(293.15);
    EXPECT_NEAR(h_mix, h_in, 1e-6) << y;
    // The constant-cp estimate at the mean temperature is within 1 K (cp of
    // the mixture changes by ~8 % between 293 K and 363 K).
    const double cpr = rel.SpecificHeatCapacity(328.15), cpa = air.SpecificHeatCapacity(328.15);
    EXPECT_NEAR(t, (y * cpr * 363.15 + (1 - y) * cpa * 293.15) / (y * cpr + (1 - y) * cpa), 1.0);
  }
}

TEST(MixingModel, StateFromPartialDensityInvertsTheMixture) {
  const GasMixture rel({{"CH4", 1.0}});
  const MixingModel mix(rel, 328.15, GasMixture::DryAir(), 295.15, 101325.0);
  const double m_r = rel.molar_mass_kg_mol(), m_a = GasMixture::DryAir().molar_mass_kg_mol();
  for (double y : {0.0, 1e-4, 0.02, 0.2, 0.5, 0.9, 1.0}) {
    const double rho_r = mix.PartialDensityAtMassFraction(y);
    double t, x;
    ASSERT_TRUE(mix.StateFromPartialDensity(rho_r, &t, &x));
    EXPECT_NEAR(t, mix.TemperatureAtMassFraction(y), 2e-5) << y;
    // Mole fraction of the released gas in a mixture of mass fraction y.
    const double x_ref = (y / m_r) / (y / m_r + (1 - y) / m_a);
    EXPECT_NEAR(x, x_ref, 2e-7) << y;
  }
  double t, x;
  EXPECT_FALSE(mix.StateFromPartialDensity(1.01 * mix.exit_density(), &t, &x));
  ASSERT_TRUE(mix.StateFromPartialDensity(0.0, &t, &x));
  EXPECT_EQ(t, 295.15);
  EXPECT_EQ(x, 0.0);
}

TEST(Release, StandardLitresPerMinute) {
  // 1 SLPM of CH4 at 20 C and 1 atm: 1e-3/60 m3/s x p M / (R T).
  const double rho = 101325.0 * 16.0425e-3 / (8.314462618 * 293.15);
  EXPECT_NEAR(ToKgPerS(1.0, RateUnit::kSlpm, 16.0425e-3, 293.15, 101325.0), 1e-3 / 60 * rho, 1e-15);
  EXPECT_NEAR(ToKgPerS(20.0, RateUnit::kKgPerH, 0.016, 293.15, 101325.0), 20.0 / 3600, 1e-15);
  EXPECT_NEAR(FromKgPerS(ToKgPerS(7.2, RateUnit::kSlpm, 0.030, 273.15, 1e5), RateUnit::kSlpm, 0.030,
                         273.15, 1e5),
              7.2, 1e-12);
  Release r;  // 5 SLPM CH4 through 1.9 cm at 21.3 C: ~0.295 m/s
  r.exit_temperature_K = r.ambient_temperature_K = 294.45;
  EXPECT_NEAR(r.ExitVelocity(), 0.2952, 0.0005);
  EXPECT_LT(r.ExitReynoldsNumber(), 2000);
}

TEST(Release, CheckNamesTheBadField) {
  Release r;
  r.exit_diameter_m = -1;
  try {
    r.Check();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("exit_diameter_m"), std::string::npos);
  }
  r = Release();
  r.composition = {{"CH4", 0.6}};
  EXPECT_THROW(r.Check(), std::invalid_argument);
  EXPECT_THROW(ParseRateUnit("l/min"), std::invalid_argument);
}

}  // namespace
}  // namespace qogi::synth
