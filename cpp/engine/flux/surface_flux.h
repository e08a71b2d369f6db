// The flux integral across a control surface: the emission rate of a species
// from its column densities, the gas's normal velocity and the surface's
// segment lengths, frame by frame (thesis eq. 12).
#pragma once

#include <cstddef>
#include <vector>

namespace qogi {

struct SurfaceFluxOptions {
  // Molar mass of the species [kg/mol]. 0 (default): the columns and their
  // sigma are mass columns [kg/m2]; > 0: they are molar columns [mol/m2]
  // and are converted with it.
  double molar_mass_kg_mol = 0.0;

  // Throws std::invalid_argument on a negative or non-finite molar mass.
  void Check() const;
};

// Per-frame emission rate through a surface sampled at S points.
struct SurfaceRate {
  // [kg/s] per frame: sum over the samples of c v_n dl. Samples without a
  // finite column count as no gas; NaN for a frame with no finite column,
  // and wherever a non-finite velocity or length meets a sample (as the
  // numpy pipeline had it: such a frame is not measured).
  std::vector<double> rate;
  // Samples with a finite column, per frame.
  std::vector<int> samples;
  // [(kg/s)^2] per frame: sum over the samples of (v_n sigma_c dl)^2, the
  // columns' random term (non-finite velocities count as 0).
  std::vector<double> rate_variance;

  // Sum of `rate_variance` over the frames [(kg/s)^2].
  double column_variance() const;
};

// The rate series of one species through one surface. All arrays are
// row-major (frames, samples) except `length_m` (samples):
//   column            column density [kg/m2] (or [mol/m2], see options); NaN = not measured
//   column_sigma      its 1-sigma, same unit (may be null: no column term)
//   normal_velocity   gas velocity along the surface normal [m/s]; the sign
//                     says the direction (positive: along the normal)
//   length_m          each sample's segment length along the surface [m]
SurfaceRate SurfaceFluxRate(const double* column, const double* column_sigma,
                            const double* normal_velocity, const double* length_m,
                            std::size_t frames, std::size_t samples,
                            const SurfaceFluxOptions& options = {});

}  // namespace qogi
