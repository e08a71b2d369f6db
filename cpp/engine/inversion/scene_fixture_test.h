// Test support (a *_test.h header: not installed, not part of the library):
// the synthetic scene of the inversion module's suites, a binned model of
// four channels over Lorentz-line "CH4" and "CO2" tables and its per-scene
// table, built once per test executable.
#pragma once

#include <memory>
#include <random>
#include <string>
#include <vector>

#include "engine/inversion/scene_table.h"
#include "engine/rte/binned_model.h"
#include "engine/rte/synthetic_spectra_test.h"

namespace qogi {
namespace testing_support {

// ---------------------------------------------------------------------------
// Synthetic spectroscopy: "CH4" lines at 2950-3100 cm-1 and "CO2" lines at
// 2150-2300 cm-1 (spectrally separate, as the real bands are).

inline AbsorberTable LorentzTable(const std::string& species, double nu0, double nu1, double lo,
                                  double hi, unsigned seed, bool with_self, int n_lines = 150) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::vector<testing_support::TestLine> lines;
  // Low-lying lines (lower-state energy 0-400 cm-1) in the lower half of the
  // band, hot lines (1200-2400 cm-1) in the upper half: as in a real band's
  // rotational structure, the band shape then depends on temperature, which
  // is what lets several channels measure it.
  for (int l = 0; l < n_lines; ++l) {
    const double nu = lo + (hi - lo) * u01(rng);
    const double e = nu < 0.5 * (lo + hi) ? 400 * u01(rng) : 1200 + 1200 * u01(rng);
    lines.push_back({nu, 2e-19 * std::pow(10.0, -3 * u01(rng)), e});
  }
  return testing_support::LorentzAbsorberTable(species, nu0, nu1, 600, lines, with_self);
}

inline SpectralResponse Bandpass(double lo, double hi, const std::string& name) {
  return testing_support::TestBandpass(lo, hi, name);
}

inline BinnedModelOptions CoarseOptions() {
  BinnedModelOptions o;
  o.num_nodes =
      65;  // fewer nodes keep the tests fast; the table reproduces whatever the model does
  return o;
}

struct Fixture {
  std::shared_ptr<const BinnedModel> model;
  std::shared_ptr<const SceneTable> table;
  double t_amb = 293.0;
  Fixture() {
    std::vector<SpectralResponse> ch{Bandpass(2140, 3110, "open"), Bandpass(2150, 2300, "co2"),
                                     Bandpass(2960, 3090, "ch4"), Bandpass(2960, 3020, "ch4 cold")};
    std::vector<AbsorberTable> tabs{LorentzTable("CH4", 2930, 3120, 2955, 3095, 1, true, 80),
                                    LorentzTable("CO2", 2130, 2320, 2155, 2295, 2, true, 80)};
    model = std::make_shared<BinnedModel>(ch, tabs, CoarseOptions());
    SceneTableOptions so;
    so.ambient_temperature_K = t_amb;
    so.min_peak_temperature_K = 250;
    so.max_peak_temperature_K = 450;
    so.negligible_fraction =
        0;  // every bin: the table must reproduce the model exactly on its nodes
    so.linear_optical_depth = 1e-7;  // and every bin marched wherever it is not linear to 5e-8
    so.max_sigma_m = 2.0;
    so.num_threads = 2;
    table = std::make_shared<SceneTable>(model, so);
  }
};

inline const Fixture& F() {
  static const Fixture f;
  return f;
}

}  // namespace testing_support
}  // namespace qogi
