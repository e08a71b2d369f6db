#include "engine/rte/path.h"

#include <string>

#include "engine/util/check.h"

namespace qogi {

std::vector<double> BackgroundTemperaturesPerChannel(const std::vector<double>& t_bg,
                                                     std::size_t num_channels) {
  Require(t_bg.size() == 1 || t_bg.size() == num_channels,
          "background_temperature_K needs 1 value or one per channel (" +
              std::to_string(num_channels) + "); got " + std::to_string(t_bg.size()));
  std::vector<double> out(num_channels, t_bg[0]);
  for (std::size_t c = 0; c < out.size(); ++c) {
    if (t_bg.size() > 1) out[c] = t_bg[c];
    CheckInRange(out[c], 100.0, 2000.0, "background_temperature_K", "K");
  }
  return out;
}

void CheckPath(const Path& path) {
  const std::size_t n = path.size();
  Require(n >= 2, "path needs at least 2 nodes; got " + std::to_string(n));
  Require(path.temperature_K.size() == n && path.fraction.size() == n * path.num_species,
          "path arrays disagree: " + std::to_string(n) + " positions, " +
              std::to_string(path.temperature_K.size()) + " temperatures, " +
              std::to_string(path.fraction.size()) + " fractions for " +
              std::to_string(path.num_species) + " species");
  CheckPositive(path.pressure_Pa, "pressure_Pa", "Pa");
  for (std::size_t k = 0; k < n; ++k) {
    CheckFinite(path.position_m[k], "path position_m");
    if (k > 0)
      Require(path.position_m[k] > path.position_m[k - 1],
              "path positions must increase from the background to the camera; node " +
                  std::to_string(k) + " is at " + FormatNumber(path.position_m[k]) +
                  " m, not beyond " + FormatNumber(path.position_m[k - 1]) + " m");
    CheckInRange(path.temperature_K[k], 1.0, 5000.0, "path temperature_K", "K");
    double sum = 0;
    for (std::size_t i = 0; i < path.num_species; ++i) {
      const double x = path.fraction[k * path.num_species + i];
      CheckInRange(x, 0.0, 1.0, "path volume fraction");
      sum += x;
    }
    Require(sum <= 1.0 + 1e-9, "path volume fractions at node " + std::to_string(k) + " sum to " +
                                   FormatNumber(sum) + " > 1");
  }
}

void GaussianPlume::Check() const {
  double sum = 0;
  for (double x : peak_fractions) {
    CheckInRange(x, 0.0, 1.0, "peak volume fraction");
    sum += x;
  }
  Require(sum <= 1.0 + 1e-12,
          "peak volume fractions sum to " + FormatNumber(sum) + "; they must sum to <= 1");
  CheckInRange(peak_temperature_K, 100.0, 2000.0, "peak_temperature_K", "K");
  CheckInRange(ambient_temperature_K, 100.0, 2000.0, "ambient_temperature_K", "K");
  CheckPositive(sigma_m, "sigma_m", "m");
  CheckPositive(pressure_Pa, "pressure_Pa", "Pa");
}

std::vector<double> GaussianColumnDensity(const GaussianPlume& plume,
                                          const std::vector<double>& molar_masses) {
  plume.Check();
  CheckSameLength(plume.peak_fractions.size(), molar_masses.size(), "peak_fractions",
                  "molar_masses");
  const int n = 801;
  const double z_max = 9.0, dz = 2 * z_max / (n - 1);
  double integral = 0;  // int g / T dz
  for (int k = 0; k < n; ++k) {
    const double z = -z_max + k * dz;
    const double g = std::exp(-0.5 * z * z);
    const double t =
        plume.ambient_temperature_K + (plume.peak_temperature_K - plume.ambient_temperature_K) * g;
    integral += g / t * dz;
  }
  std::vector<double> out(molar_masses.size());
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = molar_masses[i] / constants::kAvogadro * plume.peak_fractions[i] * plume.pressure_Pa /
             constants::kBoltzmann * plume.sigma_m * integral;
  return out;
}

std::vector<double> PathColumnDensity(const Path& path, const std::vector<double>& molar_masses) {
  CheckPath(path);
  CheckSameLength(path.num_species, molar_masses.size(), "path species", "molar_masses");
  std::vector<double> out(path.num_species, 0.0);
  for (std::size_t k = 0; k + 1 < path.size(); ++k) {
    const double ds = path.position_m[k + 1] - path.position_m[k];
    for (std::size_t i = 0; i < path.num_species; ++i) {
      const double a = path.fraction[k * path.num_species + i] / path.temperature_K[k];
      const double b = path.fraction[(k + 1) * path.num_species + i] / path.temperature_K[k + 1];
      out[i] += 0.5 * (a + b) * ds;
    }
  }
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] *= molar_masses[i] / constants::kAvogadro * path.pressure_Pa / constants::kBoltzmann;
  return out;
}

}  // namespace qogi
