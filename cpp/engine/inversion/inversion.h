// Per-pixel inversion: Gaussian-plume parameters, column densities and their
// uncertainties from measured band radiances (thesis section on the
// inversion; eqs. 4-6 for the plume, eq. 14 for the channels).
//
// Each pixel's measured contrast y_c = L_c - L_bg,c in channel c is matched
// by the forward model's contrast Delta L_c(x_1..x_S, T_peak, sigma) in the
// least-squares sense, with residuals normalised by the channel's noise
//   n_c = NETD_c x dL_c/dT (T_bg,c)   (radiance noise of the camera),
// optionally widened by a relative model error, plus one residual
// (theta - mean) / prior_sigma per Gaussian prior. Which parameters are
// estimated is set per parameter: fixed, free within bounds, or free with a
// Gaussian prior, or (fractions) tied to another species' fraction by a known
// ratio (a known composition, e.g. a 50/50 CH4/CO2 release). The typical modes:
//   single channel: one species' peak fraction free, T_peak fixed (ambient by
//     default) and sigma fixed (given, or from the plume width);
//   multichannel: the species' fractions and T_peak free, sigma fixed or with
//     a prior (a free sigma is nearly degenerate with the fractions: without
//     self-broadening the radiance depends on x_i and sigma only through
//     x_i sigma; the column densities stay well determined either way). The
//     peak temperature is then measured only through the bands' shapes and is
//     weakly determined; a known composition (tied fractions) lets the
//     ratio of different bands' contrasts measure it (Planck's law differs
//     between bands).
//
// Solvers. The default fast path evaluates the per-scene table (SceneTable)
// and solves with a small Levenberg-Marquardt solver on parameters of order
// one (ln(x + 1e-9) for fractions, ln sigma, T_peak / 10 K) with bounds
// handled by an explicit active set: a step that crosses a bound is cut at the
// bound, the parameter is held there, and it is released again when its
// multiplier points back inside (KKT check). With T_peak estimated, cold
// starts profile chi2 over T_peak (the fractions solved at each of the
// table's temperature nodes, where the table is pre-contracted: variable
// projection), and polish every local minimum of the profile with all
// parameters free; the best is reported, and a distinct second minimum within
// chi2 + 4 sets kFlagAmbiguous and widens the uncertainties (see MergeModes).
// Every solve with T_peak estimated (polish or warm start) is itself a
// variable projection: the other parameters by Levenberg-Marquardt at fixed
// T_peak, the profile minimised in T_peak by safeguarded Newton steps with its
// exact slope (joint steps crawl along the curved column-temperature valley).
// With one
// channel and one unknown fraction the problem is a root: a bracketed
// Newton iteration on a per-(T_peak, sigma) curve of the table. The general
// path (SolverKind::kFullModel, and the only one when species overlap
// spectrally) runs ceres::Solve on the full BinnedModel with automatic
// differentiation and Ceres' own bounds.
//
// Every pixel ends with a status; nothing is clamped silently and no output is
// NaN (fill values are documented on InversionOutput).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/camera/radiometric_table.h"
#include "engine/inversion/scene_table.h"
#include "engine/rte/binned_model.h"
#include "engine/util/parallel.h"

namespace qogi {

enum class PixelStatus : std::uint8_t {
  kConverged = 0,       // the solver converged with every estimated parameter inside its bounds
  kAtBound = 1,  // converged with one or more parameters held on a bound (bound_mask says which)
  kBelowDetection = 2,  // |L - L_bg| < k x noise in every channel: not inverted
  kFailed = 3,  // invalid pixel input (non-finite, background outside the tables) or no convergence
};
const char* PixelStatusName(PixelStatus s);

enum class ParameterMode : int {
  kFixed = 0,  // held at `value` (or the per-pixel array)
  kFree = 1,  // estimated within [lower, upper]
  kPrior = 2,  // estimated within [lower, upper] with a Gaussian prior N(value, prior_sigma^2)
  kTied = 3,  // fractions only: x = value * x[tied_to] (a known composition ratio)
};

struct ParameterSpec {
  ParameterMode mode = ParameterMode::kFixed;
  double value = 0.0;  // fixed value, prior mean, start value when free, or the ratio when tied
  double prior_sigma = 0.0;  // 1-sigma width of the prior (kPrior; > 0), same unit
  double lower = 0.0;  // lower bound (same unit)
  double upper = 0.0;  // upper bound (> lower)
  int tied_to = -1;  // kTied: index of the (estimated) species this fraction follows
};

enum class InitialGuess : int {
  kTable = 0,  // coarse lookup: optically thin least squares over candidate temperatures
  kNeighbour = 1,  // the previous pixel of the same row (same frame) when it converged, else kTable
  kPrevious = 2,  // the same pixel in the previous frame when it converged, else kTable
  kGiven = 3,  // the caller's per-pixel start parameters (PixelBatch::initial)
};

enum class ColdStart : int {
  // Profile chi2 over T_peak: at each temperature node of the table (and the
  // bounds) the fractions are solved with T_peak and sigma held (the
  // fractions problem is small and nearly linear; the table is
  // pre-contracted at the nodes), continuing from the neighbouring node;
  // every local minimum of the profile within chi2 + 25 of the best, refined
  // by a parabola, and the two nodes beside the best one (at most 6 starts)
  // are polished with all parameters free.
  kProfile = 0,
  // Full solves from several candidates of a coarse lookup (temperature_candidates,
  // guess_iterations, num_starts). Slower; kept for comparison.
  kStarts = 1,
};

enum class SolverKind : int {
  kAuto = 0,  // the per-scene table when the species are spectrally separate, else the full model
  kTable = 1,  // the per-scene table (Levenberg-Marquardt / Newton); fails if species overlap
  kFullModel = 2,  // ceres::Solve on the full BinnedModel (automatic differentiation); slow
};

struct InversionOptions {
  // One spec per species (peak volume fraction, dimensionless). Default
  // (empty): every species free in [0, 1], start 1e-3.
  std::vector<ParameterSpec> fractions;
  // Peak temperature T_peak [K]. Default: fixed at the ambient temperature
  // (value 0 = ambient; bounds 0 = the table's range).
  ParameterSpec temperature{ParameterMode::kFixed, 0.0, 0.0, 0.0, 0.0};
  // Gaussian depth sigma [m]. Default: fixed at 0.05 m (bounds 0 = [1e-4 m,
  // the table's max_sigma_m]).
  ParameterSpec sigma{ParameterMode::kFixed, 0.05, 0.0, 0.0, 0.0};
  // NETD per channel [K] (one value = every channel); noise n_c = NETD_c dL_c/dT(T_bg,c). Default 0.017 K.
  std::vector<double> netd_K{0.017};
  // Below detection when |y_c| < detection_sigma x n_c in every channel. Default 3.
  double detection_sigma = 3.0;
  // A pixel below detection gets column 0 (default), or with this set its
  // thin-limit weighted least-squares column from the contrasts,
  // sum_c (y_c / n_c) d_c / sum_c d_c^2 with d_c = d(y_c / n_c)/d(column),
  // signed and noisy: unbiased, so that summed over many pixels a faint
  // plume's wings are not lost (the status stays below detection, the
  // column's sigma the noise-equivalent column).
  bool signed_below_detection = false;
  // Relative model uncertainty f per channel, added in quadrature to the noise:
  // n_c^2 + (f y_c)^2. Default 0 (measurement noise only), within [0, 1].
  double model_error_fraction = 0.0;
  int max_iterations = 100;  // solver iterations per solve (>= 1). Default 100
  // A solve has converged when a Gauss-Newton step from its end would lower
  // chi2 by less than this: the parameters are then within ~sqrt(tolerance)
  // standard deviations of the optimum (0.1 sigma at the default), far below
  // the noise. Default 0.01, within [1e-12, 1].
  double tolerance_chi2 = 0.01;
  InitialGuess initial_guess = InitialGuess::kTable;  // default kTable
  // How a pixel without a warm start is solved when T_peak is estimated (the
  // table path). With the temperature free the chi2 landscape often has two
  // branches (a thin hot plume and a thick cooler one give nearly the same
  // contrasts in broadband channels): both cold starts look for every minimum.
  // Default kProfile.
  ColdStart cold_start = ColdStart::kProfile;
  // kStarts only: T_peak candidates of the coarse lookup (the nominal value
  // and this many across the bounds), 1-50. Default 5
  int temperature_candidates = 5;
  int guess_iterations = 3;  // kStarts only: fraction refinements per candidate, 0-100. Default 3
  // kStarts only: full solves from the best candidates of the coarse lookup,
  // 0-50 (0 = every candidate; default). The best fit is kept; distinct other
  // minima widen its uncertainty by their likelihood weight.
  int num_starts = 0;
  SolverKind solver = SolverKind::kAuto;  // default kAuto
  int num_threads = 0;  // threads over pixels; 0 = all cores
  // Validates against the model; throws std::invalid_argument.
  void Check(std::size_t num_species, std::size_t num_channels) const;
};

// One batch of pixels (and optionally frames). Arrays are row-major; C =
// channels, N = pixels, F = frames, P = species + 2.
struct PixelBatch {
  std::size_t num_pixels = 0;
  std::size_t num_frames = 1;
  // Pixels per image row: neighbour warm starts stay inside a row, and rows
  // are the units of work. 0 = the whole batch is one row.
  std::size_t row_length = 0;
  const double* radiance = nullptr;  // [F][C][N] measured band radiance L [W/(m2 sr)]
  // The background, one of the two ([C][N], or [F][C][N] when background_per_frame):
  const double* background_radiance = nullptr;  // L_bg [W/(m2 sr)]
  const double* background_temperature_K = nullptr;  // blackbody T_bg per channel [K]
  bool background_per_frame = false;
  // Optional per-pixel values [N] overriding the spec's `value` (fixed value,
  // prior mean, or start value): sigma [m] and T_peak [K].
  const double* sigma_m = nullptr;
  const double* peak_temperature_K = nullptr;
  const double* initial = nullptr;  // [N][P] start parameters for InitialGuess::kGiven
};

// Where results go: caller-owned arrays ([F][N] for per-pixel scalars,
// [F][N][S] per species, [F][N][P] per parameter, [F][N][P][P] covariance).
// Any pointer may be null (not wanted) except status.
// Fill values (never NaN): below detection -> fractions 0, T_peak and sigma
// their fixed/prior/start values, column densities 0 with column_sigma the
// 1-sigma noise-equivalent column (thin limit, all channels); failed -> every
// value 0 (T_peak and sigma their nominal values), sigmas 0, chi2 0.
// Uncertainties are capped at the width of the parameter's bounds (and column
// uncertainties at the column of the bounds' corner) when the data do not
// constrain a parameter at all.
struct InversionOutput {
  std::uint8_t* status = nullptr;  // PixelStatus
  std::uint8_t* bound_mask = nullptr;  // bit p: parameter p held on a bound
  double* parameters = nullptr;  // x_0 .. x_{S-1}, T_peak [K], sigma [m]
  double* parameter_sigma = nullptr;  // 1-sigma (0 for fixed parameters)
  double* covariance = nullptr;  // of the parameters (rows/cols of fixed ones 0)
  double* column_density = nullptr;  // [kg/m2] (eq. 6)
  double* column_density_sigma = nullptr;  // [kg/m2]
  double* path_concentration = nullptr;  // 1e6 integral x_i ds [ppm m]
  double* path_concentration_sigma = nullptr;
  double* chi2 = nullptr;  // sum of squared normalised channel residuals
  double* condition_number = nullptr;  // of the column-normalised residual Jacobian
  std::int32_t* iterations = nullptr;  // solver iterations (all solves)
  // Bit 0 (kFlagAmbiguous): a second, distinct solution fits the pixel within
  // chi2 + 4 of the reported one; the reported uncertainties then include the
  // spread between the solutions (see Inverter::MergeModes).
  std::uint8_t* flags = nullptr;
};
constexpr std::uint8_t kFlagAmbiguous = 1;

// Owned result arrays (C++ convenience); Output() points into them.
struct InversionResult {
  std::size_t num_pixels = 0, num_frames = 1, num_species = 0;
  std::vector<std::uint8_t> status, bound_mask, flags;
  std::vector<double> parameters, parameter_sigma, covariance, column_density, column_density_sigma,
      path_concentration, path_concentration_sigma, chi2, condition_number;
  std::vector<std::int32_t> iterations;
  void Allocate(std::size_t num_pixels, std::size_t num_frames, std::size_t num_species);
  InversionOutput Output();
};

// Column density [kg/m2] of one species of a Gaussian plume (eq. 6) as
// K x sigma I(T_peak), K = M p / (N_A k_B), I = integral g(z) / T(z) dz, and
// dI/dT_peak; the integral is the trapezoid rule on 73 nodes over +-9 sigma
// (spectrally accurate for this smooth, Gaussian-decaying integrand).
void GaussianProfileIntegral(double peak_temperature_K, double ambient_temperature_K, double* i,
                             double* di_dt);

class Inverter {
 public:
  // `table` may be null: then only the full model is used (needed when the
  // species overlap spectrally). The options are checked here.
  Inverter(std::shared_ptr<const BinnedModel> model, std::shared_ptr<const SceneTable> table,
           double ambient_temperature_K, InversionOptions options);

  const InversionOptions& options() const { return options_; }
  const BinnedModel& model() const { return *model_; }
  std::size_t num_parameters() const { return model_->num_species() + 2; }
  // Whether the per-scene table serves the pixels (else the full model).
  bool uses_table() const { return use_table_; }
  // Whether the one-unknown Newton path applies.
  bool uses_newton() const { return newton_; }
  double ambient_temperature_K() const { return t_amb_; }
  // Channel noise [W/(m2 sr)] for a background temperature.
  double ChannelNoise(std::size_t channel, double background_temperature_K) const;
  const RadiometricTable& band_table(std::size_t channel) const { return bands_[channel]; }

  // Inverts every pixel (and frame) of the batch into `out`; parallel over
  // rows; honours control (cancel -> qogi::Cancelled, progress).
  void Invert(const PixelBatch& batch, const InversionOutput& out,
              const RunControl* control = nullptr) const;

 public:
  // Implementation details (per-pixel state and per-thread scratch).
  struct Workspace;
  struct Pixel;

 private:
  void InvertRow(const PixelBatch& batch, const InversionOutput& out, std::size_t begin,
                 std::size_t end, Workspace* ws) const;
  bool PreparePixel(const PixelBatch& batch, std::size_t frame, std::size_t pixel, Pixel* px) const;
  // precise: converge far below the tolerance (see LmSettings in the .cc).
  // With T_peak estimated the solve is a variable projection over T_peak
  // (ProfileLm in the .cc); curvature is a first estimate of the chi2
  // profile's curvature there (d^2 chi2 / dT_peak^2 / 2 [1/K^2]; 0 = unknown).
  void SolveTable(Pixel* px, const double* start, Workspace* ws, bool precise = true,
                  double curvature = 0.0) const;
  void SolveNewton(Pixel* px, Workspace* ws) const;
  void SolveFull(Pixel* px, const double* start, Workspace* ws) const;
  struct GuessCandidate {
    double cost;  // chi2 (with priors) of the candidate
    double th[8];  // parameters (species + 2 <= 8)
    double curvature = 0;  // of the chi2 profile over T_peak there (see SolveTable; 0 = unknown)
  };
  // Coarse lookup: per candidate peak temperature, the optically thin least
  // squares for the fractions, refined by a few iterations; sorted by cost.
  void TableGuess(const Pixel& px, std::vector<GuessCandidate>* candidates, Workspace* ws) const;
  // The profile of chi2 over T_peak (ColdStart::kProfile): its local minima,
  // best first, as starts for full solves. Adds its iterations to *iterations.
  void ProfileGuess(const Pixel& px, std::vector<GuessCandidate>* minima, int* iterations,
                    Workspace* ws) const;
  // Optically thin non-negative least squares for the free fractions at
  // temperature tc (theta's other entries kept).
  void ThinGuess(const Pixel& px, double tc, double* theta) const;
  // Whether two solutions of one pixel are distinct minima (some estimated
  // parameter differs by more than half their combined uncertainty).
  static bool Distinct(const Pixel& a, const Pixel& b);
  // Combines two solutions of one pixel (two minima).
  void MergeModes(Pixel* best, const Pixel& other) const;
  void FullModelGuess(const Pixel& px, double* theta) const;
  // Covariance, uncertainties and column densities from the contrast and
  // its Jacobian [c * P + p] at the solution px->theta.
  void FinishWith(Pixel* px, const double* contrast, const double* jacobian, Workspace* ws) const;
  void FillBelowDetection(Pixel* px, Workspace* ws) const;
  void FillFailed(Pixel* px) const;
  void Columns(Pixel* px, Workspace* ws) const;
  void WritePixel(const Pixel& px, const InversionOutput& out, std::size_t index) const;

  std::shared_ptr<const BinnedModel> model_;
  std::shared_ptr<const SceneTable> table_;
  double t_amb_ = 0;
  InversionOptions options_;
  std::vector<ParameterSpec>
      specs_;  // per parameter (S fractions, T_peak, sigma), defaults resolved
  std::vector<RadiometricTable> bands_;
  std::vector<double> netd_;  // per channel
  std::vector<double> column_factor_;  // K_s = M_s p / (N_A k_B)
  // The table contracted at the profile's temperatures (the bounds of T_peak
  // and the table's nodes between them); empty unless T_peak is estimated on the table path.
  std::vector<SceneTable::Slice> slices_;
  bool use_table_ = false;
  bool newton_ = false;
  std::size_t newton_param_ = 0;
};

}  // namespace qogi
