// Lines of sight through a gas: the general node-sampled path, and the
// Gaussian plume of the forward-model contract (thesis eqs. 4-6).
//
// A path is a list of nodes from the background side (index 0) to the camera
// side (last index), each with its position along the line of sight [m],
// temperature [K] and the volume fraction of every species of the model.
// Pressure is uniform along the path.
//
// Gaussian plume, s along the line of sight with the plume centre at s = 0:
//   g(s) = exp(-s^2 / (2 sigma^2)),  x_i(s) = x_i,peak g(s),
//   T(s) = T_amb + (T_peak - T_amb) g(s).
// Column density (eq. 6): c_i = (M_i / N_A) int x_i(s) p / (k_B T(s)) ds [kg/m2].
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

#include "engine/optics/planck.h"

namespace qogi {

// The plain value of a scalar: itself for double, the value part `.a` for
// automatic-differentiation types such as ceres::Jet.
inline double ValueOfScalar(double x) { return x; }
template <typename T>
double ValueOfScalar(const T& x) {
  return x.a;
}

template <typename S>
struct PathT {
  std::size_t num_species = 0;
  std::vector<S> position_m;     // ascending from background to camera [m]
  std::vector<S> temperature_K;  // per node [K]
  std::vector<S> fraction;       // [node * num_species], volume fractions
  double pressure_Pa = constants::kAtm;

  std::size_t size() const { return position_m.size(); }
};
using Path = PathT<double>;

// Validates a path: >= 2 nodes, strictly increasing positions, finite
// temperatures > 0, fractions in [0, 1] summing to <= 1, pressure > 0.
void CheckPath(const Path& path);

// The background temperature behind the path in each of `num_channels`
// channels [K], from one value (every channel) or one per channel; each
// within [100, 2000] K (std::invalid_argument naming background_temperature_K
// otherwise).
std::vector<double> BackgroundTemperaturesPerChannel(const std::vector<double>& t_bg,
                                                     std::size_t num_channels);

struct GaussianPlume {
  std::vector<double> peak_fractions;    // x_i,peak per species, in [0, 1], sum <= 1
  double peak_temperature_K = 296.0;     // T_peak [K]
  double ambient_temperature_K = 296.0;  // T_amb [K]
  double sigma_m = 0.05;                 // Gaussian depth sigma [m]; FWHM = 2.35482 sigma
  double pressure_Pa = constants::kAtm;  // p [Pa]
  // Validates ranges; throws std::invalid_argument naming the field.
  void Check() const;
};

// Samples a Gaussian plume at num_nodes nodes uniformly spaced in s / sigma
// over [-z_max, z_max]. Templated on the scalar type so that derivatives
// (ceres::Jet) flow through peak fractions, peak temperature and sigma.
template <typename S>
PathT<S> SampleGaussianPlume(const S* peak_fractions, std::size_t num_species,
                             const S& peak_temperature_K, double ambient_temperature_K,
                             const S& sigma_m, double pressure_Pa, int num_nodes, double z_max) {
  PathT<S> path;
  path.num_species = num_species;
  path.pressure_Pa = pressure_Pa;
  path.position_m.resize(num_nodes);
  path.temperature_K.resize(num_nodes);
  path.fraction.resize(static_cast<std::size_t>(num_nodes) * num_species);
  const double dz = 2 * z_max / (num_nodes - 1);
  for (int k = 0; k < num_nodes; ++k) {
    const double z = -z_max + k * dz;
    const double g = std::exp(-0.5 * z * z);
    path.position_m[k] = sigma_m * z;
    path.temperature_K[k] =
        ambient_temperature_K + (peak_temperature_K - ambient_temperature_K) * g;
    for (std::size_t i = 0; i < num_species; ++i)
      path.fraction[k * num_species + i] = peak_fractions[i] * g;
  }
  return path;
}

// Column density [kg/m2] of each species of a Gaussian plume (eq. 6). The
// integrand is smooth and Gaussian-decaying, so the trapezoid rule on 801 nodes
// over +-9 sigma is accurate to machine precision.
std::vector<double> GaussianColumnDensity(const GaussianPlume& plume,
                                          const std::vector<double>& molar_masses_kg_mol);

// Column density [kg/m2] of each species along a general path (trapezoid rule).
std::vector<double> PathColumnDensity(const Path& path,
                                      const std::vector<double>& molar_masses_kg_mol);

// Number density [molecules/cm3] of an ideal gas at pressure_Pa and T.
template <typename S>
S NumberDensityCm3(double pressure_Pa, const S& temperature_K) {
  return pressure_Pa / (constants::kBoltzmann * temperature_K) * 1e-6;
}

}  // namespace qogi
