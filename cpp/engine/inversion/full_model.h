// The general inversion path: ceres::Solve on the full BinnedModel, with
// automatic differentiation (ceres::Jet through BinnedModel::Contrast) and
// Ceres' own parameter bounds. Used when the species overlap spectrally (no
// per-scene table), on request, and to cross-check the fast path.
#pragma once

#include <cstddef>

#include "engine/rte/binned_model.h"

namespace qogi {

// A pixel's least-squares problem over the parameters
// theta = (x_0 .. x_{S-1}, T_peak [K], sigma [m]).
struct FullModelProblem {
  const BinnedModel* model = nullptr;
  double ambient_temperature_K = 0;
  std::size_t num_channels = 0, num_species = 0;
  const double* measured_contrast = nullptr;  // y_c = L_c - L_bg,c [W/(m2 sr)]
  const double* noise = nullptr;              // n_c [W/(m2 sr)]
  const double* background_temperature_K = nullptr;  // T_bg,c [K]
  const bool* estimated = nullptr;    // [P] parameter p is estimated (else held at theta[p])
  const double* lower = nullptr;      // [P] bounds of estimated parameters
  const double* upper = nullptr;
  const double* prior_mean = nullptr;   // [P]
  const double* prior_sigma = nullptr;  // [P]; 0 = no prior
  const int* tie_ref = nullptr;       // [S] species a fraction follows (-1: none), or null
  const double* tie_ratio = nullptr;  // [S] x_s = ratio x_ref
  int max_iterations = 50;
};

// Contrast of every channel and its Jacobian [c * P + p] at theta (Jet<8>;
// P = S + 2 <= 8).
void FullModelContrast(const BinnedModel& model, double ambient_temperature_K, const double* theta,
                       const double* background_temperature_K, double* contrast, double* jacobian);

// Solves from theta (in: start, inside the bounds; out: solution). Returns
// true when Ceres reports convergence; *iterations receives its count.
bool SolveFullModel(const FullModelProblem& problem, double* theta, int* iterations);

}  // namespace qogi
