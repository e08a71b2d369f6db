// Computes the band radiance of a blackbody through a 3.2-3.4 um channel with
// the installed qogi engine, and back to temperature.
#include <engine/qogi.h>

#include <cmath>
#include <cstdio>
#include <vector>

// One synthetic CH4 line (S = 1e-20 cm/molecule at 3000 cm-1) through the
// spectra module: its cross-section must integrate to S (up to the Lorentz
// area beyond the 100 cm-1 wings).
static bool SpectraWorks() {
  qogi::LineList line;
  line.molecule = {6}, line.isotopologue = {1}, line.nu_cm1 = {3000.0};
  line.intensity = {1e-20}, line.einstein_a = {0.0}, line.gamma_air = {0.05};
  line.gamma_self = {0.07}, line.elower_cm1 = {0.0}, line.n_air = {0.7};
  line.n_self = {0.7}, line.delta_air = {0.0}, line.delta_self = {0.0};
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

int main() {
  const qogi::SpectralResponse channel({2941.18, 3125.0}, {1.0, 1.0},
                                       "3.2-3.4 um bandpass");
  const double t = 300.0;
  const double l = channel.BandRadiance(t);
  const double back = channel.RadiometricTemperature(l);
  std::printf("qogi consumer: %s, T = %.2f K -> L = %.6f W/(m2 sr) -> T = %.6f K\n",
              channel.name().c_str(), t, l, back);
  if (!SpectraWorks()) return 1;
  return std::abs(back - t) < 1e-6 ? 0 : 1;
}
