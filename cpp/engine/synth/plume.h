// The turbulent plume as Lagrangian Gaussian puffs carried by the mean flow
// (mean_flow.h) with coherent random displacements, evaluated at frame times.
//
// Each puff k carries a fixed mass m_k of released gas, has an isotropic
// Gaussian shape of width sigma_k and moves with velocity u_k while growing at
// sigma_dot_k. Its contribution to the released gas's partial density and
// mass flux is
//   rho_k(x) = m_k G(x - x_k; sigma_k),
//   J_k(x)   = rho_k(x) [u_k + (sigma_dot_k / sigma_k)(x - x_k)],
// which satisfies the continuity equation d rho_k/dt + div J_k = 0 exactly
// (the second term is the self-similar expansion of the Gaussian). The field
// is the sum over puffs, so mass is conserved exactly and the gas velocity is
// u = J / rho.
//
// Puff motion: each puff follows the mean axis; its cross-stream offset is
// offset_scale(s) * (xi1 n1 + xi2 n2) and its axial speed is the
// puff-averaged similarity profile times (1 + a(s) 3 tanh(zeta/3)). xi1, xi2,
// zeta are random fields of the puff's release time tau, a random label
// (2-D standard normal) and its structure age psi (eddy turnovers, integral of
// u_int dt / (c_psi sigma_c), u_int the plume's internal turbulent velocity):
// sums of random Fourier modes (kinematic simulation, Kraichnan 1970) in
// scale bands whose release-time correlation follows the local eddy time
// sigma_c / W_m. Puffs released close in time with close labels move together
// (coherent eddies and puffs); structures renew as psi advances. Ambient
// turbulence adds a spatially uniform random velocity with Gaussian time
// correlation (meandering). See docs/synthetic.md.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/synth/gas.h"
#include "engine/synth/mean_flow.h"
#include "engine/synth/model_options.h"
#include "engine/synth/release.h"
#include "engine/synth/view.h"
#include "engine/util/parallel.h"

namespace qogi::synth {

// One puff at one frame time (world frame, SI units).
struct PuffState {
  float x, y, z;        // centre [m]
  float u, v, w;        // centre velocity [m/s]
  float sigma;          // width (standard deviation per axis) [m]
  float sigma_rate;     // d sigma / dt [m/s]
  float mass;           // released-gas mass [kg]
  std::uint32_t id;     // release index (modulo 2^32), stable across frames
};

// An axis-aligned box lo..hi [m].
struct Box {
  std::array<double, 3> lo, hi;
};

struct SimulationStats {
  std::uint64_t puffs_emitted = 0;   // including spin-up
  std::uint64_t max_live_puffs = 0;
  // Puffs that reached the end of the mean-flow table while still inside the
  // box (should be 0: the table extends well beyond the view).
  std::uint64_t puffs_lost_inside = 0;
};

class PlumeSimulation {
 public:
  // Runs the simulation and keeps every frame's puffs. Frame n is at time
  // n / frame_rate_hz [s], n = 0 .. round(duration_s * frame_rate_hz) - 1.
  // num_threads: 0 = all cores. control: progress over frames and cancellation
  // (throws qogi::Cancelled).
  PlumeSimulation(const Release& release, const View& view, double duration_s, double frame_rate_hz,
                  const PlumeModelOptions& options = {}, int num_threads = 0,
                  const RunControl* control = nullptr);
  ~PlumeSimulation();
  PlumeSimulation(PlumeSimulation&&) noexcept;

  const Release& release() const { return release_; }
  const View& view() const { return view_; }
  const PlumeModelOptions& options() const { return options_; }
  const MixingModel& mixing() const { return *mixing_; }
  const MeanFlow& mean_flow() const { return *mean_flow_; }

  int num_frames() const { return static_cast<int>(frames_.size()); }
  double frame_rate_hz() const { return frame_rate_hz_; }
  double frame_time(int frame) const { return frame / frame_rate_hz_; }
  // Puffs of a frame (throws std::out_of_range for a bad index).
  const std::vector<PuffState>& puffs(int frame) const;

  // Region outside which puffs have no effect on the view (|x - box| > 6
  // sigma for every puff that is kept) [m].
  const Box& box() const { return box_; }
  double mass_rate_kg_s() const { return mean_flow_->mass_rate_kg_s(); }
  double puff_rate_per_s() const { return puff_rate_; }
  double spin_up_s() const { return spin_up_; }
  const SimulationStats& stats() const { return stats_; }

  // Released species (composition order) and their mass fractions in the
  // released gas.
  const std::vector<std::string>& species() const { return mixing_->released().names(); }
  const std::vector<double>& species_mass_fractions() const {
    return mixing_->released().mass_fractions();
  }
  const std::vector<double>& species_mole_fractions() const {
    return mixing_->released().mole_fractions();
  }

 private:
  Release release_;
  View view_;
  PlumeModelOptions options_;
  double frame_rate_hz_;
  std::unique_ptr<MixingModel> mixing_;
  std::unique_ptr<MeanFlow> mean_flow_;
  Box box_;
  double puff_rate_ = 0, spin_up_ = 0;
  SimulationStats stats_;
  std::vector<std::vector<PuffState>> frames_;
};

}  // namespace qogi::synth
