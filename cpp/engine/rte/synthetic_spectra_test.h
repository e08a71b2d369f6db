// Test support (a *_test.h header: not installed, not part of the library): synthetic
// absorption-cross-section tables from Lorentz lines and smooth band-passes,
// shared by the GoogleTest suites of the radiative-transfer and inversion
// modules. Each suite chooses its own lines; this only tabulates them.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "engine/optics/planck.h"
#include "engine/optics/spectral_response.h"
#include "engine/rte/absorber_table.h"

namespace qogi {
namespace testing_support {

struct TestLine {
  double nu;  // line centre [cm-1]
  double s;   // strength at 296 K [cm/molecule]
  double e;   // lower-state energy [cm-1]
};

// Cross sections [cm2/molecule] on 0.02 cm-1 steps over [nu0, nu1], at 25 K
// steps from 200 K to max_temperature_K, at 1 atm: Lorentz lines (air
// half-width 0.06 cm-1, self 0.08, both x (296/T)^0.75) cut 10 cm-1 from
// their centres, strengths scaled by (296/T)^1.5 and the Boltzmann factor of
// the lower-state energy. Self-broadened cross sections only with `with_self`.
inline AbsorberTable LorentzAbsorberTable(const std::string& species, double nu0, double nu1,
                                          double max_temperature_K,
                                          const std::vector<TestLine>& lines, bool with_self) {
  AbsorberTable t;
  t.species = species;
  t.pressure_Pa = constants::kAtm;
  t.dnu_cm1 = 0.02;
  t.nu0_cm1 = nu0;
  t.n_nu = static_cast<std::size_t>(std::round((nu1 - nu0) / t.dnu_cm1)) + 1;
  for (double temp = 200; temp <= max_temperature_K + 1e-9; temp += 25)
    t.temperatures_K.push_back(temp);
  const std::size_t nt = t.temperatures_K.size();
  t.sigma_air.assign(nt * t.n_nu, 0.f);
  if (with_self) t.sigma_self.assign(nt * t.n_nu, 0.f);
  for (std::size_t it = 0; it < nt; ++it) {
    const double temp = t.temperatures_K[it];
    const double ga = 0.06 * std::pow(296.0 / temp, 0.75), gs = 0.08 * std::pow(296.0 / temp, 0.75);
    for (const TestLine& l : lines) {
      const double s = l.s * std::pow(296.0 / temp, 1.5) *
                       std::exp(-constants::kC2 * l.e * (1 / temp - 1 / 296.0));
      const long j0 = std::max<long>(0, static_cast<long>((l.nu - 10 - nu0) / t.dnu_cm1));
      const long j1 = std::min<long>(static_cast<long>(t.n_nu) - 1,
                                     static_cast<long>((l.nu + 10 - nu0) / t.dnu_cm1));
      for (long j = j0; j <= j1; ++j) {
        const double dx = nu0 + j * t.dnu_cm1 - l.nu;
        t.sigma_air[it * t.n_nu + j] +=
            static_cast<float>(s * ga / constants::kPi / (dx * dx + ga * ga));
        if (with_self)
          t.sigma_self[it * t.n_nu + j] +=
              static_cast<float>(s * gs / constants::kPi / (dx * dx + gs * gs));
      }
    }
  }
  return t;
}

// A smooth band-pass (logistic edges 3 cm-1 wide, peak 0.8) from lo to hi [cm-1].
inline SpectralResponse TestBandpass(double lo, double hi, const std::string& name) {
  std::vector<double> nu, r;
  for (double x = lo - 20; x <= hi + 20; x += 0.5) {
    nu.push_back(x);
    r.push_back(0.8 / (1 + std::exp(-(x - lo) / 3.0)) / (1 + std::exp((x - hi) / 3.0)));
  }
  return SpectralResponse(nu, r, name);
}

}  // namespace testing_support
}  // namespace qogi
