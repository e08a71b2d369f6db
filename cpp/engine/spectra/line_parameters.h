// Line parameters at a temperature, pressure and self fraction.
//
// With Tref = 296 K, p in atm, x the absorber's mole fraction (self fraction)
// and c2 = h c / k_B [cm K] (HITRAN conventions; e.g. Rothman et al., JQSRT
// 60 (1998) 665, Appendix; HAPI's EnvironmentDependency_* functions):
//
//   S(T)     = S(Tref) Q(Tref)/Q(T) exp(-c2 E''/T)/exp(-c2 E''/Tref)
//              (1 - exp(-c2 nu/T)) / (1 - exp(-c2 nu/Tref))        [cm/molecule]
//   gamma_L  = p [(1 - x) gamma_air (Tref/T)^n_air
//                 + x gamma_self (Tref/T)^n_self]                   [cm-1]
//   nu*      = nu + p [(1 - x) delta_air + x delta_self]             [cm-1]
//   gamma_D  = nu / c sqrt(2 N_A k_B T ln 2 / M)                     [cm-1]
//
// Q(T) is the TIPS-2025 partition sum (isotopologue.h), M the isotopologue's
// molar mass. n_self = n_air and delta_self = delta_air for HITRAN .par data
// (line_list.h).
#pragma once

#include <vector>

#include "engine/spectra/line_list.h"

namespace qogi {

// The physical state of the absorbing gas.
struct GasConditions {
  double temperature_K = 296.0;   // gas temperature [K]; default 296 K, > 0
  double pressure_Pa = 101325.0;  // total pressure [Pa]; default 1 atm, >= 0
  double self_fraction = 0.0;     // absorber mole fraction for broadening [0..1]; default 0

  // Throws std::invalid_argument naming the field, value and accepted range.
  void Check() const;
  double pressure_atm() const;
};

// Per-line parameters at given conditions, in the order of the line list.
struct LineParameters {
  std::vector<double> nu_cm1;         // unshifted position [cm-1]
  std::vector<double> center_cm1;     // pressure-shifted centre nu* [cm-1]
  std::vector<double> intensity;      // S(T) [cm/molecule]
  std::vector<double> gamma_lorentz;  // Lorentz HWHM [cm-1]
  std::vector<double> gamma_doppler;  // Doppler HWHM [cm-1]

  std::size_t size() const { return nu_cm1.size(); }
};

// Evaluates the equations above for every line. `line_shift` = false leaves
// centre = nu. Throws std::invalid_argument for a bad condition, a line of an
// isotopologue without partition sums, or a temperature outside its TIPS
// range.
LineParameters ComputeLineParameters(const LineList& lines, const GasConditions& conditions,
                                     bool line_shift = true);

// Number density of an ideal gas [molecule/cm3] at pressure_Pa and temperature_K.
double NumberDensity_cm3(double pressure_Pa, double temperature_K);

}  // namespace qogi
