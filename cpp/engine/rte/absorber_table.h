// Absorption cross-section tables as the radiative transfer consumes them.
//
// One table per species: sigma(nu, T) [cm2/molecule] on a uniform wavenumber
// grid nu_i = nu0 + i dnu and an ascending temperature grid, at one pressure,
// for the gas as a trace in air ("air") and, optionally, for the pure gas
// ("self"). At a local volume fraction x of the species the cross-section is
//   sigma(nu, T, x) = (1 - x) sigma_air(nu, T) + x sigma_self(nu, T),
// exact in the Lorentz wings (linear in the collisional width) and a close
// approximation in the cores. The tables are filled by the spectroscopy module
// (HITRAN line-by-line); this module only reads them.
#pragma once

#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

namespace qogi {

// Standard molar mass [kg/mol] of a species with natural isotopic composition
// ("CH4", "CO2", "H2O", "N2O", "CO", "NH3", "C2H6", "C3H8"); throws
// std::invalid_argument naming the known species otherwise.
double MolarMass(const std::string& species);

struct AbsorberTable {
  std::string species;              // e.g. "CH4"
  double molar_mass_kg_mol = 0;     // 0 = look up MolarMass(species)
  double pressure_Pa = 101325.0;    // pressure the table was computed at [Pa]
  double nu0_cm1 = 0;               // first wavenumber [cm-1]
  double dnu_cm1 = 0;               // grid step [cm-1], > 0
  std::size_t n_nu = 0;             // number of wavenumbers
  std::vector<double> temperatures_K;  // ascending, >= 2 values [K]
  std::vector<float> sigma_air;     // [n_T * n_nu], row-major by temperature
  std::vector<float> sigma_self;    // same shape, or empty (no self-broadening)

  // Validates sizes, ordering and values; throws std::invalid_argument.
  void Check() const;
  double nu_max_cm1() const { return nu0_cm1 + dnu_cm1 * (n_nu - 1); }
  bool has_self() const { return !sigma_self.empty(); }
  double molar_mass() const;
};

// Interpolation in temperature, the same rule as the spectroscopy module's
// tables (spectra/xsec_table.h): ln sigma is interpolated with a 4-point
// Lagrange cubic in T through the two grid temperatures below and the two
// above (one below and three above, or three below and one above, in the end
// intervals); where any of the four values is 0, sigma is interpolated
// linearly between the two bracketing grid temperatures. Temperatures outside
// the grid are clamped to it (the forward models check their inputs first).
struct TemperatureStencil {
  std::size_t first = 0;  // first grid index of the cubic
  int count = 0;          // points of the cubic (4, or fewer on a short grid)
  double weight[4] = {0, 0, 0, 0};
  double dweight[4] = {0, 0, 0, 0};  // d(weight)/dT [1/K]
  std::size_t lower = 0;  // bracketing interval [lower, lower + 1] for the fallback
  double frac = 0;        // position of T in that interval, in [0, 1]
  double dfrac = 0;       // d(frac)/dT [1/K]
};
TemperatureStencil MakeTemperatureStencil(const std::vector<double>& grid, double temperature_K);

// Interpolated value from the stencil: `value(k)` and `log_value(k)` return
// the table's sigma and ln sigma at grid temperature index k (ln of 0 may be
// anything). Templated on the weight scalar for automatic differentiation.
template <typename S, typename V, typename L>
S InterpolateInTemperature(const TemperatureStencil& st, const S* w, const S& frac, V value,
                           L log_value) {
  using std::exp;
  bool positive = true;
  for (int a = 0; a < st.count; ++a) positive = positive && value(st.first + a) > 0;
  if (positive) {
    S l = S(0.0);
    for (int a = 0; a < st.count; ++a) l += w[a] * log_value(st.first + a);
    return exp(l);
  }
  const double lo = value(st.lower), hi = value(st.lower + 1);
  return lo + frac * (hi - lo);
}

// ln sigma of a table's values (ln 0 stored as -1e300), computed once so that
// interpolation in temperature costs one exp per value.
std::vector<double> LogValues(const std::vector<float>& sigma);

// sigma [cm2/molecule] of table values `sigma`/`log_sigma` ([n_T][n_nu]) at
// wavenumber index j and the stencil's temperature.
inline double SigmaAt(const std::vector<float>& sigma, const std::vector<double>& log_sigma,
                      std::size_t n_nu, const TemperatureStencil& st, std::size_t j) {
  const double* w = st.weight;
  return InterpolateInTemperature<double>(
      st, w, st.frac, [&](std::size_t k) { return static_cast<double>(sigma[k * n_nu + j]); },
      [&](std::size_t k) { return log_sigma[k * n_nu + j]; });
}

}  // namespace qogi
