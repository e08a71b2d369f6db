#include "engine/synth/model_options.h"

#include "engine/util/check.h"

namespace qogi::synth {

void PlumeModelOptions::Check() const {
  CheckInRange(alpha_jet, 0.01, 0.3, "alpha_jet");
  CheckInRange(alpha_plume, 0.01, 0.3, "alpha_plume");
  CheckInRange(beta_crossflow, 0.1, 1.5, "beta_crossflow");
  CheckInRange(concentration_width_ratio, 0.8, 2.0, "concentration_width_ratio");
  CheckInRange(edge_speed_fraction, 0.0, 0.9, "edge_speed_fraction");
  CheckInRange(laminar_length_diameters, -1e300, 50.0, "laminar_length_diameters");
  CheckInRange(development_length_diameters, 0.5, 50.0, "development_length_diameters");
  CheckInRange(puff_size_fraction, 0.1, 1.0, "puff_size_fraction");
  CheckInRange(puff_rate_per_s, 0.0, 2e4, "puff_rate_per_s", "1/s");
  CheckInRange(axial_turbulence, 0.0, 0.33, "axial_turbulence");
  CheckInRange(structure_length, 0.2, 10.0, "structure_length");
  CheckInRange(structure_persistence, 0.2, 20.0, "structure_persistence");
  CheckInRange(modes_per_band, 2, 64, "modes_per_band");
  CheckInRange(column_wave_amplitude, 0.0, 0.3, "column_wave_amplitude");
  CheckInRange(column_wave_phase_speed, 0.2, 1.0, "column_wave_phase_speed");
  CheckInRange(spin_up_s, -1e300, 600.0, "spin_up_s", "s");
}

}  // namespace qogi::synth
