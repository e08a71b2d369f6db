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

// Interpolation in temperature: 4-point Lagrange cubic on the table's
// temperature grid (2-point linear at the ends of the grid), clamped to the
// grid's range. Temperatures outside the grid are an error for the caller to
// prevent (the forward models check their inputs against the table range).
struct TemperatureStencil {
  std::size_t first = 0;  // first grid index used
  int count = 0;          // 2 or 4 points
  double weight[4] = {0, 0, 0, 0};
  double dweight[4] = {0, 0, 0, 0};  // d(weight)/dT [1/K]
};
TemperatureStencil MakeTemperatureStencil(const std::vector<double>& grid,
                                          double temperature_K);

}  // namespace qogi
