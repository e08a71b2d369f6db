// Exact ground truth of a synthetic plume, computed from the puffs themselves
// (thesis section 4.3.2 definitions), and the samples along pixel rays that a
// renderer integrates.
//
// All quantities refer to the released gas as a whole; species s is the
// fraction w_s (its mass fraction in the released gas) of any mass quantity,
// and X_s = x_s X_r of the released gas's mole fraction X_r (x_s its volume
// fraction in the released gas).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/synth/plume.h"

namespace qogi::synth {

// A plane through `point` with normal `normal` (need not be unit length).
struct ControlPlane {
  double point[3] = {0, 0, 0};
  double normal[3] = {0, 0, 1};
};

// Mass flux of released gas through the (infinite) plane at one frame [kg/s],
// positive along the normal:
//   F = sum_k m_k g(d_k; sigma_k) [n.u_k + (sigma_dot_k/sigma_k) d_k],
// d_k the signed distance from puff k's centre to the plane and g the 1-D
// normal density; exact for the puff field (no discretisation).
double PlaneMassFlux(const std::vector<PuffState>& puffs, const ControlPlane& plane);

// Per-pixel line-of-sight integrals at one frame, row-major (height, width),
// row 0 at the top:
//   column   = integral rho_r dl                      [kg/m2]
//   flux_x   = integral rho_r u_x dl, flux_z likewise  [kg/(m s)]
//   velocity_x = flux_x / column, velocity_z likewise  [m/s] (NaN where the
//                column is 0: no gas within 6 widths of any puff)
// x is to the right in the image and z up (image y down is -z). Each puff's
// integral along a ray is closed form (Gaussian), cut off beyond 6 widths
// (the mass left out is exp(-18) = 1.5e-8 of the puff's).
struct TruthMaps {
  int width = 0, height = 0;
  std::vector<double> column, flux_x, flux_z, velocity_x, velocity_z;
};
TruthMaps ComputeTruthMaps(const PlumeSimulation& sim, int frame, int num_threads = 0);
// The same for any set of puffs seen through `view`.
TruthMaps ComputeTruthMaps(const std::vector<PuffState>& puffs, const View& view,
                           int num_threads = 0);

// A regular grid: node (i, j, k) at (x0 + i dx, y0 + j dy, z0 + k dz), arrays
// indexed [k][j][i] (z slowest, x fastest).
struct Grid {
  double x0 = 0, y0 = 0, z0 = 0;
  double dx = 1e-3, dy = 1e-3, dz = 1e-3;
  int nx = 1, ny = 1, nz = 1;
  void Check() const;
  std::size_t size() const { return static_cast<std::size_t>(nx) * ny * nz; }
};

// The default grid of a simulation: its box at the view's pixel footprint
// (capped at 64 M nodes by coarsening).
Grid DefaultGrid(const PlumeSimulation& sim);

// 3-D fields at the grid nodes at one frame.
struct Fields {
  Grid grid;
  std::vector<float> partial_density;  // rho_r [kg/m3]
  std::vector<float> mole_fraction;    // X_r, released gas [1]
  std::vector<float> temperature;      // [K]
  std::vector<float> velocity_x, velocity_y, velocity_z;  // [m/s]; mean wind where rho_r = 0
  std::uint64_t over_pure = 0;  // nodes denser than the pure released gas (0 expected)
};
// `with_velocity` false skips the three velocity arrays (left empty).
Fields ComputeFields(const PlumeSimulation& sim, int frame, const Grid& grid,
                     bool with_velocity = true, int num_threads = 0);
// The same for any set of puffs; `wind` [m/s] fills the velocity where there
// is no released gas.
Fields ComputeFields(const std::vector<PuffState>& puffs, const MixingModel& mixing,
                     const std::array<double, 3>& wind, const Grid& grid, bool with_velocity = true,
                     int num_threads = 0);

// Samples along the pixel rays of a rectangle of the image at one frame, for a
// renderer. Samples lie on planes y = y_m[p] (p = 0 farthest from the camera,
// so increasing p runs from the background towards the camera), spaced by
// step_m. On each plane the sample of pixel (column, row) is where that
// pixel's ray crosses it; it stands for a path length path_m of that pixel
// (= step_m * PathPerDepth(column, row), midpoint rule).
// Only the gas-bearing stretch of each ray is kept: pixel i (row-major in the
// rectangle) owns samples offset[i] .. offset[i+1]-1, on planes first_plane[i],
// first_plane[i]+1, ... (contiguous; rays meeting no gas own none). Outside
// them the ray sees no released gas (ambient temperature, zero mole fraction).
// step_m is the smallest puff width reaching the rectangle: the midpoint rule
// then integrates each Gaussian puff with a relative error below 1e-8; the
// columns agree with the truth maps to < 0.5 % wherever they exceed 1e-3 of
// the image's peak and to < 0.1 % above 1e-2 of it (the limit is each puff's
// cut-off sphere of 5 widths).
struct RaySamples {
  int row0 = 0, col0 = 0, rows = 0, cols = 0, planes = 0;
  double step_m = 0;
  std::vector<double> y_m;             // (planes)
  std::vector<float> path_m;           // (rows * cols) [m]
  std::vector<std::int64_t> offset;    // (rows * cols + 1)
  std::vector<int> first_plane;        // (rows * cols)
  std::vector<float> partial_density;  // (samples) rho_r [kg/m3]
  std::vector<float> temperature;      // (samples) [K]
  // Per species (simulation order), (samples): mole fraction [1].
  std::vector<std::vector<float>> mole_fraction;
  std::uint64_t over_pure = 0;  // samples denser than the pure released gas
};
RaySamples SampleRays(const PlumeSimulation& sim, int frame, int row0, int row1, int col0, int col1,
                      int num_threads = 0);
// The same for any set of puffs seen through `view`.
RaySamples SampleRays(const std::vector<PuffState>& puffs, const View& view,
                      const MixingModel& mixing, int row0, int row1, int col0, int col1,
                      int num_threads = 0);

}  // namespace qogi::synth
