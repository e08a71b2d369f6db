// Computes the band radiance of a blackbody through a 3.2-3.4 um channel with
// the installed qogi engine, and back to temperature; a CH4 line's
// cross-section and forward-model table; and an emission rate from column and
// velocity arrays.
#include <engine/qogi.h>

#include <cmath>
#include <cstdio>
#include <vector>

// One synthetic CH4 line (S = 1e-20 cm/molecule at 3000 cm-1) through the
// spectra module: its cross-section must integrate to S (up to the Lorentz
// area beyond the 100 cm-1 wings).
static qogi::LineList OneLine() {
  qogi::LineList line;
  line.molecule = {6}, line.isotopologue = {1}, line.nu_cm1 = {3000.0};
  line.intensity = {1e-20}, line.einstein_a = {0.0}, line.gamma_air = {0.05};
  line.gamma_self = {0.07}, line.elower_cm1 = {0.0}, line.n_air = {0.7};
  line.n_self = {0.7}, line.delta_air = {0.0}, line.delta_self = {0.0};
  return line;
}

static bool SpectraWorks() {
  const qogi::LineList line = OneLine();
  qogi::CrossSectionOptions wings;
  wings.wing_half_widths = 0, wings.wing_cm1 = 100;
  const qogi::WavenumberGrid grid = qogi::WavenumberGrid::FromRange(2800, 3200, 0.005);
  const std::vector<double> sigma = qogi::CrossSection(line, qogi::GasConditions{}, grid, wings);
  double area = 0;
  for (double s : sigma) area += s * grid.step_cm1;
  const double pi = 3.14159265358979323846;
  const double expect = 1e-20 * 2 / pi * std::atan(100 / 0.05);
  std::printf("qogi consumer: one CH4 line, integral of sigma = %.6e (expected %.6e)\n", area,
              expect);
  return std::abs(area / expect - 1) < 1e-5;
}

// The forward models' table of that line through `channel` (2941-3125 cm-1):
// the band narrowed to the line +- 25 cm-1, 2975-3025 cm-1 on 0.01 cm-1 steps,
// in air and as the pure gas.
static bool TablesWork(const qogi::SpectralResponse& channel) {
  qogi::AbsorberTableOptions options;
  options.temperatures_K = {250.0, 300.0};
  const qogi::AbsorberTable t = qogi::BuildAbsorberTable("CH4", OneLine(), {channel}, options);
  std::printf("qogi consumer: CH4 table %.2f-%.2f cm-1 (%zu points), %zu temperatures, self %s\n",
              t.nu0_cm1, t.nu_max_cm1(), t.n_nu, t.temperatures_K.size(),
              t.has_self() ? "yes" : "no");
  return t.n_nu == 5001 && std::abs(t.nu0_cm1 - 2975.0) < 1e-9 && t.has_self();
}

// A Gaussian CH4 plume released at Q = 36 kg/h and carried at u = 3 m/s
// across a straight 4 m surface (161 samples, 25 ms of frames): its molar
// column c(y) = Q / (M u sqrt(2 pi) s) exp(-y^2 / 2 s^2) [mol/m2] with
// s = 0.4 m, through the flux module: the rate must be Q.
static bool FluxWorks() {
  const double q_kg_s = 36.0 / 3600.0, u = 3.0, s = 0.4, length = 4.0;
  const double pi = 3.14159265358979323846;
  const double molar_mass = qogi::MolarMass("CH4");  // [kg/mol]
  const std::size_t frames = 3, samples = 161;
  const double dl = length / samples;
  std::vector<double> column, sigma, velocity, lengths(samples, dl);
  for (std::size_t t = 0; t < frames; ++t)
    for (std::size_t i = 0; i < samples; ++i) {
      const double y = -0.5 * length + (i + 0.5) * dl;
      column.push_back(q_kg_s / (molar_mass * u * std::sqrt(2 * pi) * s) *
                       std::exp(-0.5 * y * y / (s * s)));
      sigma.push_back(1e-4);  // [mol/m2]
      velocity.push_back(u);
    }
  qogi::SurfaceFluxOptions options;
  options.molar_mass_kg_mol = molar_mass;
  const qogi::SurfaceRate rate = qogi::SurfaceFluxRate(column.data(), sigma.data(), velocity.data(),
                                                       lengths.data(), frames, samples, options);
  const double kg_h = rate.rate[0] * 3600.0;
  std::printf(
      "qogi consumer: Gaussian CH4 plume at 3 m/s through a 4 m surface, rate = "
      "%.6f kg/h +- %.2e (column term; expected %.6f)\n",
      kg_h, std::sqrt(rate.rate_variance[0]) * 3600.0, q_kg_s * 3600.0);
  // The midpoint rule over +-5 sigma of the Gaussian: its tails (6e-7) only.
  return std::abs(kg_h / (q_kg_s * 3600.0) - 1) < 1e-5;
}

int main() {
  const qogi::SpectralResponse channel({2941.18, 3125.0}, {1.0, 1.0}, "3.2-3.4 um bandpass");
  const double t = 300.0;
  const double l = channel.BandRadiance(t);
  const double back = channel.RadiometricTemperature(l);
  std::printf("qogi consumer: %s, T = %.2f K -> L = %.6f W/(m2 sr) -> T = %.6f K\n",
              channel.name().c_str(), t, l, back);
  if (!SpectraWorks()) return 1;
  if (!TablesWork(channel)) return 1;
  if (!FluxWorks()) return 1;
  return std::abs(back - t) < 1e-6 ? 0 : 1;
}
