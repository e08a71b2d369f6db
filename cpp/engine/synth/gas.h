// Ideal-gas thermodynamics of a release mixing adiabatically with ambient air.
//
// Species data: molar masses (IUPAC 2013 standard atomic weights) and
// ideal-gas heat capacities cp(T): NIST Chemistry WebBook Shomate fits for
// CH4, CO2, N2, O2 (Chase, NIST-JANAF Thermochemical Tables, 1998); argon is
// monatomic (cp = 5R/2); C2H6 and C3H8 use the quadratic through the WebBook's
// tabulated cp at 300, 400 and 500 K (Gurvich et al. 1989; Chao et al. 1973).
// Valid from 200 K to 600 K for every species listed (the Shomate fits are
// mildly extrapolated below 298 K, where cp changes by < 1 %).
//
// Mixing: a parcel with released-gas mass fraction Y (the mixture fraction)
// conserves enthalpy,
//   Y h_r(T) + (1 - Y) h_a(T) = Y h_r(T_exit) + (1 - Y) h_a(T_ambient),
// at the ambient pressure p, and its density follows the ideal-gas law,
//   rho = p M_mix / (R T),  1/M_mix = Y/M_r + (1 - Y)/M_a.
// The released gas's partial density rho_r = Y rho is the field the plume
// simulator transports; MixingModel maps it back to T and mole fraction.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace qogi::synth {

// Molar gas constant [J/(mol K)] (CODATA 2018, exact).
inline constexpr double kGasConstant = 8.314462618;
// Standard gravity [m/s2].
inline constexpr double kGravity = 9.80665;

// Thermodynamic data of one gas species.
struct Species {
  std::string name;           // formula as used in compositions, e.g. "CH4"
  double molar_mass_kg_mol;   // [kg/mol]
  // cp(T) [J/(mol K)]: Shomate A + B t + C t^2 + D t^3 + E / t^2, t = T/1000 K
  // (quadratic fits are stored with E = 0 and D = 0 in the same form).
  double a, b, c, d, e;
  // Molar isobaric heat capacity [J/(mol K)].
  double HeatCapacity(double temperature_K) const;
  // Molar enthalpy relative to 298.15 K [J/mol].
  double Enthalpy(double temperature_K) const;
};

// The species the simulator knows; throws std::invalid_argument listing them
// when `name` is not one of them.
const Species& FindSpecies(const std::string& name);
// Names of all known species.
std::vector<std::string> KnownSpecies();

// An ideal-gas mixture of known species with fixed mole fractions.
class GasMixture {
 public:
  // mole_fractions: species name -> volume (= mole) fraction, each >= 0,
  // summing to 1 within 1e-3 (then normalised exactly).
  explicit GasMixture(const std::map<std::string, double>& mole_fractions);
  // Dry air: N2 0.78084, O2 0.20946, Ar 0.00934, CO2 0.00036 (US Standard
  // Atmosphere 1976 with present-day CO2).
  static GasMixture DryAir();

  const std::vector<std::string>& names() const { return names_; }
  const std::vector<double>& mole_fractions() const { return x_; }
  // Mass fraction of each species within the mixture.
  const std::vector<double>& mass_fractions() const { return w_; }
  double molar_mass_kg_mol() const { return molar_mass_; }
  // Specific isobaric heat capacity [J/(kg K)].
  double SpecificHeatCapacity(double temperature_K) const;
  // Specific enthalpy relative to 298.15 K [J/kg].
  double SpecificEnthalpy(double temperature_K) const;
  // Density [kg/m3] at temperature and pressure.
  double Density(double temperature_K, double pressure_Pa) const;

 private:
  std::vector<std::string> names_;
  std::vector<const Species*> species_;
  std::vector<double> x_, w_;
  double molar_mass_ = 0;
};

// Adiabatic mixing of a released gas (at its exit temperature) with ambient
// air, at the ambient pressure.
class MixingModel {
 public:
  MixingModel(GasMixture released, double exit_temperature_K, GasMixture ambient,
              double ambient_temperature_K, double pressure_Pa);

  const GasMixture& released() const { return released_; }
  const GasMixture& ambient() const { return ambient_; }
  double exit_temperature_K() const { return t_exit_; }
  double ambient_temperature_K() const { return t_amb_; }
  double pressure_Pa() const { return p_; }
  // Density of the pure released gas at the exit [kg/m3].
  double exit_density() const { return rho_exit_; }
  double ambient_density() const { return rho_amb_; }

  // Temperature [K] of a parcel with released-gas mass fraction Y in [0, 1]
  // (enthalpy balance solved by Newton's method to 1e-10 K).
  double TemperatureAtMassFraction(double mass_fraction) const;
  // Mixture density [kg/m3] at mass fraction Y.
  double DensityAtMassFraction(double mass_fraction) const;
  // Partial density of the released gas, Y rho(Y) [kg/m3].
  double PartialDensityAtMassFraction(double mass_fraction) const;

  // Local state from the released gas's partial density rho_r [kg/m3]:
  // temperature [K] (interpolated in a table of 4097 nodes uniform in
  // rho_r / exit_density, error < 1e-6 K) and the released gas's mole fraction
  // X_r = rho_r R T / (p M_r), exactly consistent with rho_r and T.
  // Returns false (and the pure-gas temperature) when rho_r exceeds the pure
  // released gas's density, which no mixture can reach.
  bool StateFromPartialDensity(double partial_density, double* temperature_K,
                               double* mole_fraction) const;

 private:
  GasMixture released_, ambient_;
  double t_exit_, t_amb_, p_;
  double h_r_exit_, h_a_amb_;
  double rho_exit_, rho_amb_;
  std::vector<double> table_t_;  // T at rho_r = k / (N-1) * rho_exit
};

}  // namespace qogi::synth
