// The exact (line-by-line) forward model: the reference every faster path is
// measured against.
//
// Spectral radiance at the camera from the integral RTE (thesis eq. 5) on the
// cross-section tables' own wavenumber grid, then band radiance through each
// channel's response (eq. 14):
//   L_c = int r_c(nu) B(nu, T_bg,c) dnu + sum_i r_c(nu_i) Delta L(nu_i) dnu
// The first term is the background through the channel (exact quadrature of
// SpectralResponse); the second is the gas's contrast on the fine grid, zero
// wherever no table has absorption. Along the line of sight the layer scheme
// of march.h is used with options.num_nodes nodes (for a Gaussian plume,
// uniformly in s/sigma over [-z_max, z_max]); halving the node spacing changes
// band radiance by < 1e-4 relative at the defaults (tested; ~2e-5 measured).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "engine/optics/spectral_response.h"
#include "engine/rte/absorber_table.h"
#include "engine/rte/path.h"
#include "engine/util/parallel.h"

namespace qogi {

struct ExactModelOptions {
  int num_nodes = 401;   // line-of-sight nodes for a Gaussian plume, >= 3, odd keeps the centre
  double z_max = 6.5;  // Gaussian plume sampled over [-z_max, z_max] sigma (column beyond: 8e-11)
  // Combine the march on all nodes with the march on every other node,
  // (4 fine - coarse) / 3, cancelling the layer scheme's second-order error
  // (applied when the path has an odd number of nodes).
  bool richardson = true;
  int num_threads = 0;  // 0 = all cores
  void Check() const;
};

// An optional homogeneous atmospheric layer between the plume and the camera.
struct AtmosphericPath {
  double distance_m = 0;  // path length [m]; 0 = no atmosphere
  double temperature_K = 288.15;  // air temperature [K]
  double relative_humidity = 0.5;  // [0, 1]; H2O from the saturation pressure (needs an H2O table)
  double co2_ppm = 420;  // ambient CO2 [ppm] (used if the model has a CO2 table)
  double ch4_ppm = 1.9;  // ambient CH4 [ppm] (used if the model has a CH4 table)
  void Check() const;
};

// Saturation vapour pressure of water [Pa] over liquid water (Buck 1996).
double SaturationVaporPressure(double temperature_K);

// Per channel: the fine-grid points where some table has data and the
// response is non-zero, with the interpolation into each species' table.
struct ChannelGrid {
  std::vector<double> nu_cm1;  // grid wavenumbers [cm-1]
  std::vector<long> grid_index;  // index on the common uniform grid (consecutive = adjacent)
  double dnu_cm1 = 0;  // the common grid step [cm-1]
  std::vector<double> weight;  // response(nu) * dnu [cm-1]
  // Per species: lower table index (or -1 outside the table) and weight of the
  // upper neighbour, for linear interpolation in wavenumber.
  std::vector<std::vector<long>> index;
  std::vector<std::vector<double>> frac;
};

ChannelGrid MakeChannelGrid(const SpectralResponse& channel,
                            const std::vector<AbsorberTable>& tables);

// Planck radiance B(nu_i, T) [W/(m2 sr cm-1)] at grid points [begin, end).
void PlanckOnGrid(const ChannelGrid& grid, std::size_t begin, std::size_t end, double temperature_K,
                  double* out);

class ExactModel {
 public:
  ExactModel(std::vector<SpectralResponse> channels, std::vector<AbsorberTable> tables,
             ExactModelOptions options = {});

  std::size_t num_channels() const { return channels_.size(); }
  std::size_t num_species() const { return tables_.size(); }
  const std::vector<SpectralResponse>& channels() const { return channels_; }
  const std::vector<AbsorberTable>& tables() const { return tables_; }
  std::vector<std::string> species() const;
  std::vector<double> molar_masses() const;
  // Temperatures the tables cover [K]; paths must stay inside.
  double min_temperature_K() const { return t_min_; }
  double max_temperature_K() const { return t_max_; }

  // Band radiance [W/(m2 sr)] per channel of a Gaussian plume in front of
  // blackbody backgrounds (one temperature, or one per channel).
  std::vector<double> BandRadiance(const GaussianPlume& plume,
                                   const std::vector<double>& background_temperature_K,
                                   const AtmosphericPath& atmosphere = {},
                                   const RunControl* control = nullptr) const;
  // The same for a general node-sampled path.
  std::vector<double> BandRadiance(const Path& path,
                                   const std::vector<double>& background_temperature_K,
                                   const AtmosphericPath& atmosphere = {},
                                   const RunControl* control = nullptr) const;
  // Spectral contrast Delta L(nu) [W/(m2 sr cm-1)] on channel c's fine grid
  // (no atmosphere), for plots and checks.
  void SpectralContrast(std::size_t channel, const Path& path, double background_temperature_K,
                        std::vector<double>* nu_cm1, std::vector<double>* contrast) const;

  // The path the model uses for a Gaussian plume (validated).
  Path GaussianPath(const GaussianPlume& plume) const;

 private:
  void CheckPathAgainstTables(const Path& path) const;
  // Contrast sum_i weight_i Delta L_i over grid points [begin, end) of a channel.
  double ContrastSum(std::size_t channel, const Path& path, double t_bg, std::size_t begin,
                     std::size_t end, const std::vector<double>* atm_transmittance,
                     std::vector<double>* spectral_out) const;

  std::vector<SpectralResponse> channels_;
  std::vector<AbsorberTable> tables_;
  std::vector<std::vector<double>> log_air_, log_self_;  // ln sigma per table
  ExactModelOptions options_;
  std::vector<ChannelGrid> grids_;
  double t_min_ = 0, t_max_ = 0;
};

// Checks that tables and channels can form a model (same pressure, distinct
// species, valid tables) and returns the common temperature range.
void CheckModelTables(const std::vector<AbsorberTable>& tables, double* t_min, double* t_max);

}  // namespace qogi
