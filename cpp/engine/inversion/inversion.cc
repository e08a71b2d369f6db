// The inversion's options (checks), its result arrays, the status names and
// the Gaussian profile integral. The Inverter itself: inversion_driver.cc
// (set-up and the row loop), inversion_guesses.cc, inversion_solve.cc
// (the table path), inversion_newton.cc, inversion_ceres.cc (the full
// model), bounded_lm_internal.h (the solver).
#include "engine/inversion/inversion.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "engine/inversion/bounded_lm_internal.h"
#include "engine/inversion/full_model.h"
#include "engine/inversion/inversion_internal.h"
#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {

using namespace inversion_detail;  // NOLINT: the module's own internals

namespace {

void CheckSpec(const ParameterSpec& p, const std::string& name, const char* unit, double lo_limit,
               double hi_limit) {
  const int mode = static_cast<int>(p.mode);
  Require(mode >= 0 && mode <= 2,
          name + ": mode must be fixed (0), free (1) or prior (2)" +
              std::string(mode == 3 ? " (only fractions can be tied)" : "") + "; got " +
              std::to_string(mode));
  CheckFinite(p.value, (name + " value").c_str());
  CheckFinite(p.lower, (name + " lower").c_str());
  CheckFinite(p.upper, (name + " upper").c_str());
  if (p.mode == ParameterMode::kPrior)
    CheckPositive(p.prior_sigma, (name + " prior_sigma").c_str(), unit);
  const bool bounds_given = !(p.lower == 0 && p.upper == 0);
  if (bounds_given) {
    CheckInRange(p.lower, lo_limit, hi_limit, (name + " lower bound").c_str(), unit);
    CheckInRange(p.upper, lo_limit, hi_limit, (name + " upper bound").c_str(), unit);
    Require(p.lower < p.upper, name + ": lower bound " + FormatNumber(p.lower) +
                                   " must be below the upper bound " + FormatNumber(p.upper));
  }
}

}  // namespace

const char* PixelStatusName(PixelStatus s) {
  switch (s) {
    case PixelStatus::kConverged: return "converged";
    case PixelStatus::kAtBound: return "at_bound";
    case PixelStatus::kBelowDetection: return "below_detection";
    case PixelStatus::kFailed: return "failed";
  }
  return "unknown";
}

void InversionOptions::Check(std::size_t ns, std::size_t nc) const {
  Require(ns >= 1 && ns + 2 <= kMaxParams, "the inversion handles 1 to " +
                                               std::to_string(kMaxParams - 2) + " species; got " +
                                               std::to_string(ns));
  Require(nc >= 1 && nc <= kMaxChannels, "the inversion handles 1 to " +
                                             std::to_string(kMaxChannels) + " channels; got " +
                                             std::to_string(nc));
  Require(fractions.empty() || fractions.size() == ns, "fractions needs one spec per species (" +
                                                           std::to_string(ns) + ") or none; got " +
                                                           std::to_string(fractions.size()));
  for (std::size_t s = 0; s < fractions.size(); ++s) {
    const ParameterSpec& f = fractions[s];
    const std::string name = "fractions[" + std::to_string(s) + "]";
    if (f.mode == ParameterMode::kTied) {
      Require(f.tied_to >= 0 && static_cast<std::size_t>(f.tied_to) < ns &&
                  f.tied_to != static_cast<int>(s),
              name + ": tied_to must be the index of another species (0-" + std::to_string(ns - 1) +
                  "); got " + std::to_string(f.tied_to));
      const ParameterMode m = fractions[f.tied_to].mode;
      Require(m == ParameterMode::kFree || m == ParameterMode::kPrior,
              name + ": the species it is tied to (" + std::to_string(f.tied_to) +
                  ") must be estimated (free or prior), not fixed or tied");
      CheckPositive(f.value, (name + " ratio (value)").c_str());
      continue;
    }
    CheckSpec(f, name, "", 0.0, 1.0);
    CheckInRange(f.value, 0.0, 1.0, (name + " value").c_str());
  }
  CheckSpec(temperature, "temperature", "K", 100.0, 2000.0);
  Require(temperature.value == 0 || (temperature.value >= 100 && temperature.value <= 2000),
          "temperature value must be 0 (ambient) or within [100, 2000] K; got " +
              FormatNumber(temperature.value));
  CheckSpec(sigma, "sigma", "m", 1e-6, 1e3);
  CheckInRange(sigma.value, 1e-6, 1e3, "sigma value", "m");
  Require(netd_K.size() == 1 || netd_K.size() == nc, "netd_K needs 1 value or one per channel (" +
                                                         std::to_string(nc) + "); got " +
                                                         std::to_string(netd_K.size()));
  for (double v : netd_K) CheckInRange(v, 1e-6, 10.0, "netd_K", "K");
  CheckInRange(detection_sigma, 0.0, 1e3, "detection_sigma");
  CheckInRange(model_error_fraction, 0.0, 1.0, "model_error_fraction");
  CheckInRange(tolerance_chi2, 1e-12, 1.0, "tolerance_chi2");
  Require(max_iterations >= 1 && max_iterations <= 10000,
          "max_iterations must be within [1, 10000]; got " + std::to_string(max_iterations));
  const int ig = static_cast<int>(initial_guess);
  Require(ig >= 0 && ig <= 3,
          "initial_guess must be table (0), neighbour (1), previous (2) or "
          "given (3); got " +
              std::to_string(ig));
  Require(
      num_starts >= 0 && num_starts <= 50,
      "num_starts must be within [0, 50] (0 = every candidate); got " + std::to_string(num_starts));
  Require(guess_iterations >= 0 && guess_iterations <= 100,
          "guess_iterations must be within [0, 100]; got " + std::to_string(guess_iterations));
  Require(temperature_candidates >= 1 && temperature_candidates <= 50,
          "temperature_candidates must be within [1, 50]; got " +
              std::to_string(temperature_candidates));
  const int cs = static_cast<int>(cold_start);
  Require(cs >= 0 && cs <= 1,
          "cold_start must be profile (0) or starts (1); got " + std::to_string(cs));
  const int sk = static_cast<int>(solver);
  Require(sk >= 0 && sk <= 2,
          "solver must be auto (0), table (1) or full_model (2); got " + std::to_string(sk));
  Require(num_threads >= 0,
          "num_threads must be >= 0 (0 = all cores); got " + std::to_string(num_threads));
  bool any = temperature.mode != ParameterMode::kFixed || sigma.mode != ParameterMode::kFixed;
  if (fractions.empty()) any = true;
  for (const auto& f : fractions)
    any = any || f.mode == ParameterMode::kFree || f.mode == ParameterMode::kPrior;
  Require(any,
          "every parameter is fixed: make at least one species' fraction, the "
          "temperature or sigma free");
}

void InversionResult::Allocate(std::size_t n, std::size_t f, std::size_t ns) {
  num_pixels = n;
  num_frames = f;
  num_species = ns;
  const std::size_t m = n * f, np = ns + 2;
  status.assign(m, 0);
  bound_mask.assign(m, 0);
  flags.assign(m, 0);
  parameters.assign(m * np, 0.0);
  parameter_sigma.assign(m * np, 0.0);
  covariance.assign(m * np * np, 0.0);
  column_density.assign(m * ns, 0.0);
  column_density_sigma.assign(m * ns, 0.0);
  path_concentration.assign(m * ns, 0.0);
  path_concentration_sigma.assign(m * ns, 0.0);
  chi2.assign(m, 0.0);
  condition_number.assign(m, 0.0);
  iterations.assign(m, 0);
}

InversionOutput InversionResult::Output() {
  InversionOutput o;
  o.status = status.data();
  o.bound_mask = bound_mask.data();
  o.flags = flags.data();
  o.parameters = parameters.data();
  o.parameter_sigma = parameter_sigma.data();
  o.covariance = covariance.data();
  o.column_density = column_density.data();
  o.column_density_sigma = column_density_sigma.data();
  o.path_concentration = path_concentration.data();
  o.path_concentration_sigma = path_concentration_sigma.data();
  o.chi2 = chi2.data();
  o.condition_number = condition_number.data();
  o.iterations = iterations.data();
  return o;
}

void GaussianProfileIntegral(double tp, double ta, double* i_out, double* di_out) {
  const int n = 73;
  const double z_max = 9.0, h = 2 * z_max / (n - 1);
  double i = 0, di = 0;
  for (int k = 0; k < n; ++k) {
    const double z = -z_max + k * h;
    const double g = std::exp(-0.5 * z * z);
    const double t = ta + (tp - ta) * g;
    i += g / t;
    di -= g * g / (t * t);
  }
  *i_out = i * h;
  if (di_out) *di_out = di * h;
}

}  // namespace qogi
