#include "engine/synth/release.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>

#include "engine/util/check.h"

namespace qogi::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Dynamic viscosity near 293 K [Pa s] (CRC Handbook values, rounded); only
// used for the exit Reynolds number, a regime indicator.
double ViscosityAt293(const std::string& name) {
  if (name == "CH4") return 1.10e-5;
  if (name == "CO2") return 1.47e-5;
  if (name == "N2") return 1.76e-5;
  if (name == "O2") return 2.04e-5;
  if (name == "Ar") return 2.23e-5;
  if (name == "C2H6") return 0.92e-5;
  if (name == "C3H8") return 0.80e-5;
  return 1.5e-5;
}

}  // namespace

RateUnit ParseRateUnit(const std::string& text) {
  const std::string t = Lower(text);
  if (t == "kg/s") return RateUnit::kKgPerS;
  if (t == "kg/h") return RateUnit::kKgPerH;
  if (t == "g/h") return RateUnit::kGPerH;
  if (t == "slpm") return RateUnit::kSlpm;
  throw std::invalid_argument(
      "rate_unit must be one of \"kg/s\", \"kg/h\", \"g/h\", "
      "\"SLPM\"; got \"" +
      text + "\"");
}

std::string RateUnitName(RateUnit unit) {
  switch (unit) {
    case RateUnit::kKgPerS: return "kg/s";
    case RateUnit::kKgPerH: return "kg/h";
    case RateUnit::kGPerH: return "g/h";
    case RateUnit::kSlpm: return "SLPM";
  }
  return "?";
}

double ToKgPerS(double value, RateUnit unit, double molar_mass_kg_mol,
                double standard_temperature_K, double standard_pressure_Pa) {
  switch (unit) {
    case RateUnit::kKgPerS: return value;
    case RateUnit::kKgPerH: return value / 3600.0;
    case RateUnit::kGPerH: return value / 3.6e6;
    case RateUnit::kSlpm: {
      const double rho_std =
          standard_pressure_Pa * molar_mass_kg_mol / (kGasConstant * standard_temperature_K);
      return value * 1e-3 / 60.0 * rho_std;
    }
  }
  return value;
}

double FromKgPerS(double kg_s, RateUnit unit, double molar_mass_kg_mol,
                  double standard_temperature_K, double standard_pressure_Pa) {
  return kg_s /
         ToKgPerS(1.0, unit, molar_mass_kg_mol, standard_temperature_K, standard_pressure_Pa);
}

void Release::Check() const {
  CheckPositive(rate, "rate");
  ReleasedGas();  // validates the composition
  CheckInRange(exit_diameter_m, 1e-3, 2.0, "exit_diameter_m", "m");
  CheckInRange(stack_height_m, 0.0, 1000.0, "stack_height_m", "m");
  CheckInRange(exit_x_m, -1e4, 1e4, "exit_x_m", "m");
  CheckInRange(exit_temperature_K, 200.0, 600.0, "exit_temperature_K", "K");
  CheckInRange(ambient_temperature_K, 200.0, 600.0, "ambient_temperature_K", "K");
  CheckInRange(pressure_Pa, 1e4, 2e5, "pressure_Pa", "Pa");
  CheckInRange(wind_speed_m_s, 0.0, 30.0, "wind_speed_m_s", "m/s");
  CheckInRange(wind_direction_deg, -360.0, 360.0, "wind_direction_deg", "deg");
  CheckInRange(turbulence_intensity, 0.0, 1.0, "turbulence_intensity");
  CheckInRange(draft_m_s, 0.0, 2.0, "draft_m_s", "m/s");
  CheckInRange(ambient_time_scale_s, 0.1, 600.0, "ambient_time_scale_s", "s");
  CheckInRange(release_turbulence, 0.0, 1.0, "release_turbulence");
  CheckInRange(standard_temperature_K, 250.0, 320.0, "standard_temperature_K", "K");
  CheckInRange(standard_pressure_Pa, 5e4, 2e5, "standard_pressure_Pa", "Pa");
  const double v = ExitVelocity();
  if (!(v <= 300.0))
    throw std::invalid_argument(
        "the exit velocity " + FormatNumber(v) +
        " m/s (rate / (exit density * exit area)) must be <= 300 m/s; lower the "
        "rate or widen exit_diameter_m");
}

double Release::MassRateKgS() const {
  return ToKgPerS(rate, rate_unit, ReleasedGas().molar_mass_kg_mol(), standard_temperature_K,
                  standard_pressure_Pa);
}

double Release::ExitDensity() const {
  return ReleasedGas().Density(exit_temperature_K, pressure_Pa);
}

double Release::ExitVelocity() const {
  const double area = kPi * exit_diameter_m * exit_diameter_m / 4.0;
  return MassRateKgS() / (ExitDensity() * area);
}

double Release::ExitReynoldsNumber() const {
  const GasMixture gas = ReleasedGas();
  double mu = 0;
  for (std::size_t i = 0; i < gas.names().size(); ++i)
    mu += gas.mole_fractions()[i] * ViscosityAt293(gas.names()[i]);
  mu *= std::pow(exit_temperature_K / 293.15, 0.7);
  return ExitVelocity() * exit_diameter_m * ExitDensity() / mu;
}

double Release::AmbientRmsVelocity() const {
  const double a = turbulence_intensity * wind_speed_m_s;
  return std::sqrt(a * a + draft_m_s * draft_m_s);
}

}  // namespace qogi::synth
