// The mean (time-averaged) plume: an integral buoyant-jet model solved along
// the plume axis, and the similarity profiles the puff simulator needs.
//
// Integral model (top-hat variables along the arc length s of the axis, after
// Morton, Taylor & Turner 1956, extended to crossflow as in Hoult, Fay &
// Forney 1969 and Lee & Cheung 1990, non-Boussinesq as in Ricou & Spalding
// 1961):
//   dM/ds = E = 2 pi b [alpha sqrt(rho rho_a) |V - U cos(phi)| + beta rho_a U |sin(phi)|]
//   d(M V t)/ds = E U e_wind + pi b^2 g (rho_a - rho) e_z
//   dX/ds = t
// with M = pi rho b^2 V the mixture mass flux, t the unit tangent, phi the
// angle between the axis and the wind, released-gas mass fraction Y = Q / M,
// T and rho from adiabatic mixing (MixingModel). The entrainment coefficient
// goes from alpha_jet to alpha_plume with the local Richardson number
// Ri = g |rho_a - rho| b / (rho_a (V - U cos phi)^2) (Priestley & Ball 1955):
//   alpha = alpha_jet + (alpha_plume - alpha_jet) min(1, Ri / Ri_p),
//   Ri_p = 4 alpha_plume / 5 (the pure-plume value, Gamma = 1).
// Above a laminar exit (Reynolds number < 2000) the column does not entrain
// for `laminar_length_diameters` (automatic: 1 + kQuietLaminarDiameters
// (1 - release_turbulence) diameters): there it keeps its mass flux and
// accelerates under its buoyancy, narrowing as b ~ V^(-1/2).
//
// Release turbulence (Release::release_turbulence, tau in [0, 1]) scales the
// plume's own fluctuations: the puffs' cross-stream offsets (the puff size
// fraction tends to 1 - tau (1 - puff_size_fraction) instead of
// puff_size_fraction, so the mean profile keeps its width sigma_c with
// smaller offsets) and the axial speed fluctuations (x tau). The ambient
// air's meandering (Release::turbulence_intensity, draft_m_s) is not scaled.
//
// Profiles: the exit's top-hat profile (concentration width b/sqrt(2), plug
// speed V) develops over `development_length_diameters` into Gaussian
// similarity profiles: excess velocity 2 (V - W_a) exp(-r^2/b_g^2) with
// b_g = b/sqrt(2), concentration width sigma_c = lambda b_g / sqrt(2) per axis.
#pragma once

#include <array>
#include <vector>

#include "engine/synth/gas.h"
#include "engine/synth/model_options.h"
#include "engine/synth/release.h"

namespace qogi::synth {

inline constexpr int kMaxBands = 6;
// Extra laminar length of a quiet low-Reynolds-number release at
// release_turbulence = 0 [exit diameters] (the automatic laminar length is
// 1 + kQuietLaminarDiameters (1 - release_turbulence) diameters below
// Reynolds number 2000). Chosen so that the quiet lab column (5 SLPM CH4,
// 1.9 cm exit, release_turbulence 0.25) stays laminar over its first ~22 cm,
// the part of the view the lab validation measures in, as the column of a
// large-eddy simulation of that release does (qogi issue 31).
inline constexpr double kQuietLaminarDiameters = 14.0;

// The mean flow at one point of the axis. All doubles (interpolated field by
// field).
struct Station {
  double s;               // arc length from the exit [m]; < 0 inside the pipe
  double psi;             // structure age: eddy turnovers integral u_int dt / (c_psi sigma_c)
  double time_s;          // travel time from the exit at the mass-weighted speed [s]
  double pos[3];          // axis point [m]
  double tangent[3];      // unit tangent of the axis
  double n1[3], n2[3];    // unit normals (n2 horizontal, n1 = n2 x tangent)
  double ds_dpsi;         // [m]
  double radius_m;        // top-hat radius b [m]
  double velocity_m_s;    // top-hat speed along the axis V [m/s]
  double excess_m_s;      // V minus the wind's component along the axis (>= 0)
  double ambient_axial_m_s;  // wind's component along the axis W_a (>= 0)
  double mass_fraction;   // top-hat released-gas mass fraction Y
  double temperature_K;   // top-hat temperature
  double density;         // top-hat mixture density [kg/m3]
  double development;     // 0 at the exit .. 1 developed (phi)
  // Strength of turbulent fluctuations: phi, faded out where the mean
  // centreline is still nearly pure gas (the unmixed core carries none).
  double turbulence;
  double sigma_c;         // mean concentration width per axis [m]
  double sigma_puff;      // puff width [m]
  double offset_scale;    // RMS flux-weighted offset of puff centres per axis [m]
  double mass_weighted_speed;  // W_m [m/s]
  double profile_beta;    // puff-averaged excess-velocity factor beta
  double profile_b2;      // puff-averaged excess-velocity width B^2 [m2]
  double profile_k;       // scale K of the puff speed profile
  double profile_eps;     // edge fraction epsilon of the puff speed profile
  double internal_turbulence_m_s;  // RMS turbulent velocity inside the plume u_int
  double axial_turbulence;     // RMS relative axial speed fluctuation here
  double centre_partial_density;  // mean centreline rho_r = Q/(2 pi sigma_c^2 W_m)
  // Relative amplitude of the laminar column's axial speed wave here
  // (PlumeModelOptions::column_wave_amplitude), and its phase time
  // T(s) / c [s]: the travel time at the mass-weighted speed over the phase
  // speed fraction.
  double wave_amplitude;
  double wave_time_s;
  double band_w[kMaxBands];       // weights of the structure scale bands
  double band_dw_ds[kMaxBands];
};

// Field-by-field linear interpolation a + u (b - a).
Station LerpStation(const Station& a, const Station& b, double u);

class MeanFlow {
 public:
  // Solves the integral model from the exit until the axis is more than
  // `stop_distance_m` outside the axis-aligned box lo..hi (or 100 box sizes
  // along). Throws std::invalid_argument if the plume stalls (a fountain of a
  // release heavier than air in still air is not modelled).
  MeanFlow(const Release& release, const PlumeModelOptions& options, const MixingModel& mixing,
           const std::array<double, 3>& lo, const std::array<double, 3>& hi,
           double stop_distance_m);

  // Stations in pairs along s: stations 2p, 2p+1, 2p+2 are a pair's start,
  // midpoint and end. Steps keep psi changes <= 0.1 and s changes <=
  // 0.3 sigma_c per pair; s = 0 (the exit) is a pair boundary. The first is
  // the puffs' birth point inside the pipe (s = -3 sigma_c at the exit).
  const std::vector<Station>& stations() const { return stations_; }
  // Index of the station at the exit (s = 0).
  int exit_station() const { return exit_station_; }
  // Linear interpolation in s (clamped to the table).
  Station AtS(double s) const;
  double max_s() const { return stations_.back().s; }

  int num_bands() const { return num_bands_; }
  // Correlation time of band b in release time [s].
  double band_time_s(int b) const { return band_time_[b]; }

  double mass_rate_kg_s() const { return q_; }
  double exit_velocity_m_s() const { return v0_; }
  double exit_diameter_m() const { return d_; }
  double laminar_length_m() const { return l_lam_; }
  double development_length_m() const { return l_dev_; }
  double structure_persistence() const { return c_psi_; }

  // Puff speed along the axis (before the turbulent factor) for a puff whose
  // centre is r2 (squared offset, m2) from the axis at station st.
  static double PuffSpeed(const Station& st, double r2);

 private:
  std::vector<Station> stations_;
  int exit_station_ = 0;
  int num_bands_ = 1;
  std::array<double, kMaxBands> band_time_{};
  double q_, v0_, d_, l_lam_, l_dev_, c_psi_;
};

}  // namespace qogi::synth
