// A gas release from a round vertical stack: the physical conditions of a
// synthetic scene.
//
// World frame (shared by the simulator, the truth maps and the renderer):
// x to the right in the image, z up, y along the viewing direction away from
// the camera. The stack exit centre is at (exit_x_m, 0, stack_height_m).
#pragma once

#include <map>
#include <string>

#include "engine/synth/gas.h"

namespace qogi::synth {

// How Release::rate is expressed.
enum class RateUnit {
  kKgPerS,  // kg/s
  kKgPerH,  // kg/h
  kGPerH,   // g/h
  kSlpm,    // standard litres per minute at standard_temperature_K and
            // standard_pressure_Pa (ideal gas)
};

// Parses "kg/s", "kg/h", "g/h", "SLPM" (case-insensitive); throws otherwise.
RateUnit ParseRateUnit(const std::string& text);
std::string RateUnitName(RateUnit unit);

struct Release {
  // Release rate in `rate_unit`; > 0. Default 5 (SLPM).
  double rate = 5.0;
  // Unit of `rate`. Default SLPM.
  RateUnit rate_unit = RateUnit::kSlpm;
  // Volume (mole) fractions of the released gas, summing to 1.
  // Default {"CH4": 1}.
  std::map<std::string, double> composition = {{"CH4", 1.0}};
  // Inner diameter of the round exit [m], in [1 mm, 2 m]. Default 0.019.
  double exit_diameter_m = 0.019;
  // Height of the exit above the ground [m], >= 0; places the exit at
  // z = stack_height_m (the ground itself is not modelled). Default 0.
  double stack_height_m = 0.0;
  // Horizontal position of the exit centre along x [m]. Default 0.
  double exit_x_m = 0.0;
  // Temperature of the gas leaving the exit [K], in [200, 600]. Default 293.15.
  double exit_temperature_K = 293.15;
  // Ambient air temperature [K], in [200, 600]. Default 293.15.
  double ambient_temperature_K = 293.15;
  // Ambient pressure [Pa], in [1e4, 2e5]; the gas exits at this pressure.
  // Default 101325.
  double pressure_Pa = 101325.0;
  // Mean horizontal wind speed [m/s], in [0, 30]. Default 0.
  double wind_speed_m_s = 0.0;
  // Direction the wind blows towards, in degrees from +x towards +y:
  // 0 = crosswind to the right in the image, 180 = to the left, 90 = along
  // the line of sight away from the camera. In [-360, 360]. Default 0.
  double wind_direction_deg = 0.0;
  // Ambient turbulence intensity sigma_u / wind speed, in [0, 1]. Default 0.
  double turbulence_intensity = 0.0;
  // RMS horizontal velocity of room drafts or calm-air fluctuations [m/s], in
  // [0, 2]; adds to turbulence_intensity * wind_speed_m_s in quadrature.
  // Default 0.
  double draft_m_s = 0.0;
  // Lagrangian integral time scale of the ambient fluctuations [s], in
  // [0.1, 600]. Default 3.
  double ambient_time_scale_s = 3.0;
  // Turbulence the released gas carries of its own, relative to a fully
  // developed turbulent buoyant plume (dimensionless), in [0, 1]: 1 = the
  // developed plume's puffs, offsets and axial fluctuations; 0 = a quiet
  // column that keeps its mean profile and moves only with the ambient air
  // (turbulence_intensity, draft_m_s). Below 1 a low-Reynolds-number exit
  // also stays laminar (no entrainment, buoyant acceleration) for longer: the
  // automatic laminar length is 1 + kQuietLaminarDiameters (1 -
  // release_turbulence) exit diameters (mean_flow.h). Default 1.
  double release_turbulence = 1.0;
  // Standard conditions that define SLPM: temperature [K] in [250, 320]
  // (default 293.15, i.e. 20 C as many mass-flow controllers use) and pressure
  // [Pa] in [5e4, 2e5] (default 101325).
  double standard_temperature_K = 293.15;
  double standard_pressure_Pa = 101325.0;

  // Throws std::invalid_argument naming the first bad field.
  void Check() const;

  GasMixture ReleasedGas() const { return GasMixture(composition); }
  // Mass release rate of the mixture [kg/s].
  double MassRateKgS() const;
  // Density of the released gas at the exit [kg/m3].
  double ExitDensity() const;
  // Bulk exit velocity, mass rate / (exit density * exit area) [m/s].
  double ExitVelocity() const;
  // Exit Reynolds number V D / nu (kinematic viscosity of the released gas at
  // the exit from a mole-weighted Sutherland fit; used only to choose the
  // laminar length).
  double ExitReynoldsNumber() const;
  // RMS of the ambient horizontal velocity fluctuations [m/s].
  double AmbientRmsVelocity() const;
};

// Converts `value` in `unit` to kg/s for a gas of molar mass M [kg/mol] with
// the given standard conditions.
double ToKgPerS(double value, RateUnit unit, double molar_mass_kg_mol,
                double standard_temperature_K, double standard_pressure_Pa);
double FromKgPerS(double kg_s, RateUnit unit, double molar_mass_kg_mol,
                  double standard_temperature_K, double standard_pressure_Pa);

}  // namespace qogi::synth
