#include "engine/spectra/line_parameters.h"

#include <cmath>
#include <map>
#include <utility>

#include "engine/optics/planck.h"
#include "engine/spectra/isotopologue.h"
#include "engine/util/check.h"

namespace qogi {

void GasConditions::Check() const {
  CheckPositive(temperature_K, "temperature_K", "K");
  CheckNonNegative(pressure_Pa, "pressure_Pa", "Pa");
  CheckInRange(self_fraction, 0.0, 1.0, "self_fraction");
}

double GasConditions::pressure_atm() const { return pressure_Pa / constants::kAtm; }

double NumberDensity_cm3(double pressure_Pa, double temperature_K) {
  CheckNonNegative(pressure_Pa, "pressure_Pa", "Pa");
  CheckPositive(temperature_K, "temperature_K", "K");
  return pressure_Pa / (constants::kBoltzmann * temperature_K) * 1e-6;
}

LineParameters ComputeLineParameters(const LineList& lines, const GasConditions& cond,
                                     bool line_shift) {
  cond.Check();
  lines.Check();
  const double T = cond.temperature_K;
  const double Tref = constants::kTref;
  const double c2 = constants::kC2;
  const double p = cond.pressure_atm();
  const double x = cond.self_fraction;

  // Per isotopologue: Q(Tref)/Q(T) and the Doppler factor sqrt(2 k T ln2 / m) / c.
  struct IsoFactors {
    double q_ratio, doppler;
  };
  std::map<std::pair<int, int>, IsoFactors> factors;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const auto key = std::make_pair(lines.molecule[i], lines.isotopologue[i]);
    if (factors.count(key)) continue;
    const Isotopologue& iso = GetIsotopologue(key.first, key.second);
    const double q_t = PartitionSum(key.first, key.second, T);
    const double mass_kg = iso.molar_mass_g_mol * 1e-3 / constants::kAvogadro;
    const double doppler = std::sqrt(2.0 * constants::kBoltzmann * T * std::log(2.0) / mass_kg) /
                           constants::kSpeedOfLight;
    factors[key] = {iso.q_ref / q_t, doppler};
  }

  const std::size_t n = lines.size();
  LineParameters out;
  out.nu_cm1 = lines.nu_cm1;
  out.center_cm1.resize(n);
  out.intensity.resize(n);
  out.gamma_lorentz.resize(n);
  out.gamma_doppler.resize(n);
  const double log_t_ratio = std::log(Tref / T);
  const double inv_t_diff = 1.0 / T - 1.0 / Tref;
  auto last_key = std::make_pair(-1, -1);
  IsoFactors f{0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    const auto key = std::make_pair(lines.molecule[i], lines.isotopologue[i]);
    if (key != last_key) f = factors.at(key), last_key = key;
    const double nu = lines.nu_cm1[i];
    const double boltzmann = std::exp(-c2 * lines.elower_cm1[i] * inv_t_diff);
    const double stimulated = -std::expm1(-c2 * nu / T) / -std::expm1(-c2 * nu / Tref);
    out.intensity[i] = lines.intensity[i] * f.q_ratio * boltzmann * stimulated;
    out.gamma_lorentz[i] =
        p * ((1.0 - x) * lines.gamma_air[i] * std::exp(lines.n_air[i] * log_t_ratio) +
             x * lines.gamma_self[i] * std::exp(lines.n_self[i] * log_t_ratio));
    out.center_cm1[i] =
        line_shift ? nu + p * ((1.0 - x) * lines.delta_air[i] + x * lines.delta_self[i]) : nu;
    out.gamma_doppler[i] = nu * f.doppler;
  }
  return out;
}

}  // namespace qogi
