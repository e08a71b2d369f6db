// Settings of the plume model that change its output (the physical conditions
// are in Release, the camera geometry in View).
#pragma once

#include <cstdint>

namespace qogi::synth {

struct PlumeModelOptions {
  // Top-hat entrainment coefficient of a pure jet, sqrt(2) x the Gaussian
  // 0.0535 of Fischer et al. (1979, "Mixing in Inland and Coastal Waters",
  // ch. 9); in [0.01, 0.3]. Default 0.0757.
  double alpha_jet = 0.0757;
  // Top-hat entrainment coefficient of a pure plume, sqrt(2) x the Gaussian
  // 0.0833 of Fischer et al. (1979); in [0.01, 0.3]. Default 0.1178.
  double alpha_plume = 0.1178;
  // Crossflow (forced) entrainment coefficient of a bent-over plume (Hoult,
  // Fay & Forney 1969; Briggs 1975: 0.6); in [0.1, 1.5]. Default 0.6.
  double beta_crossflow = 0.6;
  // Ratio of the concentration to the velocity Gaussian width, lambda; in
  // [0.8, 2]. Default 1.2 (Fischer et al. 1979).
  double concentration_width_ratio = 1.2;
  // Length of the laminar column above the exit [exit diameters]; < 0 picks
  // 1 + kQuietLaminarDiameters (1 - Release::release_turbulence) for exit
  // Reynolds numbers below 2000 (1 for a fully turbulent release) and 0
  // otherwise; at most 50. Default -1.
  double laminar_length_diameters = -1.0;
  // Length over which the exit's top-hat profile develops into the Gaussian
  // similarity profile and turbulence sets in [exit diameters]; in [0.5, 50].
  // Default 4.
  double development_length_diameters = 4.0;
  // Released-gas-weighted axial speed at the plume edge as a fraction of the
  // profile's scale, epsilon: the puff speed profile is
  // K [epsilon + (1 - epsilon) 2 beta exp(-r^2/B^2)] instead of the Gaussian
  // mean-velocity profile, because gas parcels at the intermittent edge move
  // with the plume fluid, not with the unconditional mean that averages in
  // still ambient air (K keeps the mass-weighted speed). In [0, 0.9].
  // Default 0.3.
  double edge_speed_fraction = 0.3;
  // Size of a puff relative to the local plume concentration width once the
  // flow is developed; in [0.1, 1]. Smaller = finer structure. Default 0.35.
  double puff_size_fraction = 0.35;
  // Puffs released per second; 0 = automatic (spacing at the exit <= 1/4 of
  // the exit width and >= 3 puffs per developed puff length); at most 2e4.
  // Default 0.
  double puff_rate_per_s = 0.0;
  // RMS of the relative fluctuation of a puff's axial speed in the developed
  // flow; in [0, 0.33]. Default 0.25 (axial turbulence intensity of plumes,
  // Papanicolaou & List 1988).
  double axial_turbulence = 0.25;
  // Axial length of a coherent structure in local concentration widths; in
  // [0.2, 10]. Default 1.
  double structure_length = 1.0;
  // Lifetime of a coherent structure in local eddy turnover times
  // sigma_c / u_int (u_int the plume's internal turbulent velocity); in
  // [0.2, 20]. Default 1.
  double structure_persistence = 1.0;
  // Random Fourier modes per scale band and component; in [2, 64]. Default 12.
  int modes_per_band = 12;
  // Relative amplitude of the axial speed wave of a quiet laminar column
  // (dimensionless): in the laminar column the gas speed is
  // W (1 + A sin(2 pi f (T(s) / c - t) + theta)) with A = this x
  // (1 - Release::release_turbulence) x (1 - development), ramped in over the
  // first exit diameter; f the puffing frequency 1.5 / sqrt(D [m]) Hz
  // (Cetegen & Ahmed 1993) within +-10 % (seeded), T(s) the travel time at
  // the mass-weighted speed, c column_wave_phase_speed. The gas bunches where
  // it is slow: a pattern that travels at c W while the gas moves at W. In
  // [0, 0.3]. Default 0.06.
  double column_wave_amplitude = 0.06;
  // Phase speed of that wave as a fraction of the local mass-weighted speed
  // (instability waves of laminar jets and plumes travel at about 0.5-0.8 of
  // the centreline speed); in [0.2, 1]. Default 0.6.
  double column_wave_phase_speed = 0.6;
  // Simulated time before the first frame so that the plume is established
  // [s]; < 0 = automatic (twice the travel time out of the view plus 0.5 s);
  // at most 600. Default -1.
  double spin_up_s = -1.0;
  // Seed of every random choice; equal seeds give identical runs. Default 0.
  std::uint64_t seed = 0;

  // Throws std::invalid_argument naming the first bad field.
  void Check() const;
};

}  // namespace qogi::synth
