// Planck's law in wavenumber form and physical constants (CODATA 2018, exact).
//
//   B(nu, T) = c1 nu^3 / (exp(c2 nu / T) - 1)    [W / (m2 sr cm-1)]
//
// with nu in cm-1, T in K, c1 = 2 h c^2 x 1e8 W m2 sr-1 (the 1e8 converts m-1
// to cm-1 both in nu^3 and in the per-wavenumber density) and
// c2 = 100 h c / k_B cm K.
#pragma once

#include <cstddef>

namespace qogi {
namespace constants {
constexpr double kPi = 3.14159265358979323846;
constexpr double kPlanck = 6.62607015e-34;        // h [J s]
constexpr double kSpeedOfLight = 299792458.0;      // c [m/s]
constexpr double kBoltzmann = 1.380649e-23;        // k_B [J/K]
constexpr double kAvogadro = 6.02214076e23;        // N_A [1/mol]
constexpr double kStefanBoltzmann = 5.670374419e-8;  // sigma [W/(m2 K4)]
// First radiation constant for spectral radiance per cm-1: 2 h c^2 1e8.
constexpr double kC1 = 2.0 * kPlanck * kSpeedOfLight * kSpeedOfLight * 1e8;
// Second radiation constant h c / k_B in cm K.
constexpr double kC2 = 100.0 * kPlanck * kSpeedOfLight / kBoltzmann;
// Wien's displacement constant in wavenumber form: nu_max = kWienNu * T
// [cm-1/K]; 2.821439372... is the root of 3 (1 - exp(-x)) = x.
constexpr double kWienNu = 2.821439372122079 / kC2;
// HITRAN's reference temperature [K] and one standard atmosphere [Pa].
constexpr double kTref = 296.0;
constexpr double kAtm = 101325.0;
}  // namespace constants

// Spectral radiance B(nu, T) [W/(m2 sr cm-1)] of a blackbody.
// nu_cm1 >= 0 (B = 0 at nu = 0), temperature_K > 0; throws
// std::invalid_argument otherwise.
double PlanckRadiance(double nu_cm1, double temperature_K);

// dB/dT [W/(m2 sr cm-1 K)].
double PlanckRadianceDerivative(double nu_cm1, double temperature_K);

// Unchecked kernels for inner loops whose inputs are already validated.
inline double PlanckUnchecked(double nu_cm1, double temperature_K);

// Elementwise over equal-length arrays: out[i] = B(nu[i], T[i]).
void PlanckRadiance(const double* nu_cm1, const double* temperature_K, double* out, std::size_t n);

}  // namespace qogi

#include <cmath>

namespace qogi {
inline double PlanckUnchecked(double nu_cm1, double temperature_K) {
  if (nu_cm1 <= 0.0) return 0.0;
  return constants::kC1 * nu_cm1 * nu_cm1 * nu_cm1 /
         std::expm1(constants::kC2 * nu_cm1 / temperature_K);
}
}  // namespace qogi
