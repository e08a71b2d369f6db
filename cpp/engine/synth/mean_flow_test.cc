// The integral plume model against similarity laws it must reproduce.
#include "engine/synth/mean_flow.h"

#include <gtest/gtest.h>

#include <cmath>

namespace qogi::synth {
namespace {

MixingModel MixingOf(const Release& r) {
  return MixingModel(r.ReleasedGas(), r.exit_temperature_K, GasMixture::DryAir(),
                     r.ambient_temperature_K, r.pressure_Pa);
}

// A pure plume far from its source: Morton, Taylor & Turner (1956) top-hat
// similarity solution b = 6 alpha z / 5, w = (5/(6 alpha)) (9 alpha B / 10)^(1/3)
// z^(-1/3), so db/dz = 6 alpha / 5 and w b^(1/3) = (0.625 B / alpha)^(1/3)
// whatever the virtual origin (B = g' w b^2, per pi).
TEST(MeanFlow, FarFieldFollowsMortonTaylorTurner) {
  Release r;
  r.composition = {{"N2", 1.0}};
  r.exit_temperature_K = 313.15;
  r.ambient_temperature_K = 293.15;
  r.exit_diameter_m = 0.1;
  r.rate = 0.5 * 3600 * 1e-3;  // 1.8 kg/h: a lazy source
  r.rate_unit = RateUnit::kKgPerH;
  PlumeModelOptions opt;
  opt.laminar_length_diameters = 0;
  const MixingModel mix = MixingOf(r);
  const MeanFlow mf(r, opt, mix, {-1, -1, 0}, {1, 1, 12}, 0.0);
  const double rho_a = mix.ambient_density(), rho_e = mix.exit_density();
  const double b0 = r.exit_diameter_m / 2;
  const double buoyancy = kGravity * (rho_a - rho_e) / rho_a * r.ExitVelocity() * b0 * b0;
  const double alpha = opt.alpha_plume;
  for (double z : {6.0, 10.0}) {
    const Station a = mf.AtS(z - 0.05), b = mf.AtS(z + 0.05);
    const double slope = (b.radius_m - a.radius_m) / (b.s - a.s);
    EXPECT_NEAR(slope / (1.2 * alpha), 1.0, 0.03) << z;
    const Station c = mf.AtS(z);
    const double invariant = c.velocity_m_s * std::cbrt(c.radius_m) / std::cbrt(buoyancy);
    EXPECT_NEAR(invariant / std::cbrt(0.625 / alpha), 1.0, 0.02) << z;
  }
}

// A buoyant plume bent over by wind rises as Briggs' two-thirds law,
// dz = (3 F x^2 / (2 beta^2 U^3))^(1/3), far from a lazy source (Briggs 1975).
TEST(MeanFlow, BentOverPlumeFollowsBriggsTwoThirdsLaw) {
  Release r;
  r.composition = {{"N2", 1.0}};
  r.exit_temperature_K = 393.15;
  r.ambient_temperature_K = 293.15;
  r.exit_diameter_m = 1.0;
  r.rate = 0.6;  // kg/s: exit velocity ~0.9 m/s, buoyancy-dominated
  r.rate_unit = RateUnit::kKgPerS;
  r.stack_height_m = 10;
  r.wind_speed_m_s = 5;
  PlumeModelOptions opt;
  opt.laminar_length_diameters = 0;
  const MixingModel mix = MixingOf(r);
  const MeanFlow mf(r, opt, mix, {-5, -5, 0}, {400, 5, 100}, 0.0);
  const double rho_a = mix.ambient_density(), rho_e = mix.exit_density();
  const double b0 = r.exit_diameter_m / 2;
  const double f = kGravity * (rho_a - rho_e) / rho_a * r.ExitVelocity() * b0 * b0;
  const double u = r.wind_speed_m_s, beta = opt.beta_crossflow;
  for (double x : {100.0, 200.0, 300.0}) {
    // First station at or beyond x.
    const auto& st = mf.stations();
    std::size_t i = 0;
    while (i + 1 < st.size() && st[i].pos[0] < x) ++i;
    const double rise = st[i].pos[2] - r.stack_height_m;
    const double briggs = std::cbrt(3 * f * x * x / (2 * beta * beta * u * u * u));
    EXPECT_NEAR(rise / briggs, 1.0, 0.1) << x;
  }
}

TEST(MeanFlow, ExitStateAndLaminarColumn) {
  Release r;  // 5 SLPM CH4, 1.9 cm, laminar exit
  r.exit_temperature_K = r.ambient_temperature_K = 294.45;
  const MixingModel mix = MixingOf(r);
  const MeanFlow mf(r, PlumeModelOptions(), mix, {-0.3, -0.3, 0}, {0.3, 0.3, 0.5}, 0.0);
  const Station e = mf.stations()[mf.exit_station()];
  EXPECT_EQ(e.s, 0.0);
  EXPECT_NEAR(e.velocity_m_s, r.ExitVelocity(), 1e-12);
  EXPECT_NEAR(e.mass_fraction, 1.0, 1e-12);
  EXPECT_NEAR(mf.laminar_length_m(), r.exit_diameter_m, 1e-12);
  // No entrainment in the laminar column: the gas stays pure and accelerates
  // by its buoyancy as V^2 = V0^2 + 2 g (rho_a - rho) / rho z (inviscid).
  const Station c = mf.AtS(0.5 * r.exit_diameter_m);
  EXPECT_NEAR(c.mass_fraction, 1.0, 1e-9);
  const double rho = mix.exit_density(), rho_a = mix.ambient_density();
  const double v2 = std::pow(r.ExitVelocity(), 2) + 2 * kGravity * (rho_a - rho) / rho * c.s;
  EXPECT_NEAR(c.velocity_m_s / std::sqrt(v2), 1.0, 0.01);
  // Mean centreline partial density never exceeds the pure gas's.
  for (const Station& s : mf.stations())
    EXPECT_LE(s.centre_partial_density, mix.exit_density() * (1 + 1e-9));
}

TEST(MeanFlow, DenseReleaseInStillAirIsRejected) {
  Release r;
  r.composition = {{"CO2", 1.0}};
  r.rate = 50;
  const MixingModel mix = MixingOf(r);
  EXPECT_THROW(MeanFlow(r, PlumeModelOptions(), mix, {-1, -1, 0}, {1, 1, 2}, 0.0),
               std::invalid_argument);
}

}  // namespace
}  // namespace qogi::synth
