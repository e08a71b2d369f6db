#include "engine/inversion/inversion.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "engine/inversion/full_model.h"
#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

constexpr std::size_t kMaxChannels = 16;
constexpr std::size_t kMaxParams = 8;  // species + 2
constexpr double kConditionCap = 1e16;
constexpr double kLogEps = 1e-9;  // fractions enter the solver as ln(x + kLogEps)
const double kSqrt2Pi = std::sqrt(2.0 * constants::kPi);

void CheckSpec(const ParameterSpec& p, const std::string& name, const char* unit, double lo_limit,
               double hi_limit) {
  const int mode = static_cast<int>(p.mode);
  Require(mode >= 0 && mode <= 2, name + ": mode must be fixed (0), free (1) or prior (2)" +
                                      std::string(mode == 3 ? " (only fractions can be tied)" : "") +
                                      "; got " + std::to_string(mode));
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
  Require(ns >= 1 && ns + 2 <= kMaxParams,
          "the inversion handles 1 to " + std::to_string(kMaxParams - 2) + " species; got " +
              std::to_string(ns));
  Require(nc >= 1 && nc <= kMaxChannels, "the inversion handles 1 to " +
                                             std::to_string(kMaxChannels) + " channels; got " +
                                             std::to_string(nc));
  Require(fractions.empty() || fractions.size() == ns,
          "fractions needs one spec per species (" + std::to_string(ns) + ") or none; got " +
              std::to_string(fractions.size()));
  for (std::size_t s = 0; s < fractions.size(); ++s) {
    const ParameterSpec& f = fractions[s];
    const std::string name = "fractions[" + std::to_string(s) + "]";
    if (f.mode == ParameterMode::kTied) {
      Require(f.tied_to >= 0 && static_cast<std::size_t>(f.tied_to) < ns && f.tied_to != static_cast<int>(s),
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
  Require(netd_K.size() == 1 || netd_K.size() == nc,
          "netd_K needs 1 value or one per channel (" + std::to_string(nc) + "); got " +
              std::to_string(netd_K.size()));
  for (double v : netd_K) CheckInRange(v, 1e-6, 10.0, "netd_K", "K");
  CheckInRange(detection_sigma, 0.0, 1e3, "detection_sigma");
  CheckInRange(model_error_fraction, 0.0, 1.0, "model_error_fraction");
  CheckInRange(tolerance_chi2, 1e-12, 1.0, "tolerance_chi2");
  Require(max_iterations >= 1 && max_iterations <= 10000,
          "max_iterations must be within [1, 10000]; got " + std::to_string(max_iterations));
  const int ig = static_cast<int>(initial_guess);
  Require(ig >= 0 && ig <= 3, "initial_guess must be table (0), neighbour (1), previous (2) or "
                              "given (3); got " + std::to_string(ig));
  Require(num_starts >= 0 && num_starts <= 50,
          "num_starts must be within [0, 50] (0 = every candidate); got " + std::to_string(num_starts));
  Require(guess_iterations >= 0 && guess_iterations <= 100,
          "guess_iterations must be within [0, 100]; got " + std::to_string(guess_iterations));
  Require(temperature_candidates >= 1 && temperature_candidates <= 50,
          "temperature_candidates must be within [1, 50]; got " +
              std::to_string(temperature_candidates));
  const int cs = static_cast<int>(cold_start);
  Require(cs >= 0 && cs <= 1, "cold_start must be profile (0) or starts (1); got " + std::to_string(cs));
  const int sk = static_cast<int>(solver);
  Require(sk >= 0 && sk <= 2, "solver must be auto (0), table (1) or full_model (2); got " +
                                  std::to_string(sk));
  Require(num_threads >= 0, "num_threads must be >= 0 (0 = all cores); got " +
                                std::to_string(num_threads));
  bool any = temperature.mode != ParameterMode::kFixed || sigma.mode != ParameterMode::kFixed;
  if (fractions.empty()) any = true;
  for (const auto& f : fractions)
    any = any || f.mode == ParameterMode::kFree || f.mode == ParameterMode::kPrior;
  Require(any, "every parameter is fixed: make at least one species' fraction, the "
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

// ---------------------------------------------------------------------------

struct Inverter::Pixel {
  std::size_t nc = 0, ns = 0, np = 0;
  double y[kMaxChannels], noise[kMaxChannels], tbg[kMaxChannels];
  const double* phi = nullptr;
  double nominal[kMaxParams], lower[kMaxParams], upper[kMaxParams], prior_sigma[kMaxParams];
  bool est[kMaxParams];
  double scale[kMaxParams];
  int tie_ref[kMaxParams];      // species index this fraction follows, or -1
  double tie_ratio[kMaxParams];
  bool has_ties = false;
  // x_s = ratio x_ref for tied fractions.
  void ApplyTies(double* theta) const {
    if (!has_ties) return;
    for (std::size_t s = 0; s < ns; ++s)
      if (tie_ref[s] >= 0) theta[s] = tie_ratio[s] * theta[tie_ref[s]];
  }
  // Moves tied fractions' Jacobian columns [c * np + p] onto their references.
  void FoldJacobian(double* jac, std::size_t rows) const {
    if (!has_ties) return;
    for (std::size_t s = 0; s < ns; ++s)
      if (tie_ref[s] >= 0)
        for (std::size_t c = 0; c < rows; ++c) {
          jac[c * np + tie_ref[s]] += tie_ratio[s] * jac[c * np + s];
          jac[c * np + s] = 0.0;
        }
  }
  // Results.
  double theta[kMaxParams];
  PixelStatus status = PixelStatus::kFailed;
  std::uint8_t bound_mask = 0;
  std::uint8_t flags = 0;
  double prior_chi2 = 0;  // sum of squared prior residuals at the solution
  double log_det = 0;     // ln det of the estimated parameters' covariance
  int iterations = 0;
  double curvature = 0;  // of the chi2 profile over T_peak at the solution (ProfileLm)
  double chi2 = 0, cond = 0;
  double cov[kMaxParams * kMaxParams];
  double psig[kMaxParams];
  double col[kMaxParams], col_sig[kMaxParams], ppm[kMaxParams], ppm_sig[kMaxParams];
  bool solved() const {
    return status == PixelStatus::kConverged || status == PixelStatus::kAtBound;
  }
};

struct Inverter::Workspace {
  std::vector<double> phi;
  // The T_peak profile: cost and parameters per temperature.
  std::vector<double> profile_cost;
  std::vector<std::array<double, kMaxParams>> profile_theta;
  std::vector<double> profile_predicted;  // per local minimum
  // Newton curve cache.
  std::size_t curve_channel = static_cast<std::size_t>(-1), curve_species = 0;
  double curve_t = -1, curve_sigma = -1;
  int curve_r1 = 0;
  std::vector<double> curve_nodes;  // [node * r1 + r]
  std::vector<double> curve_u;      // u at the nodes [m]
  UniformSpline curve;
  SceneTable::PeakTerms peak;  // the table's terms at the last T_peak evaluated
  // Profile integral cache.
  double int_t = -1, int_i = 0, int_di = 0;
  std::vector<Inverter::GuessCandidate> guesses;
  std::vector<Inverter::Pixel> solutions;
  // Warm start of the neighbour path.
  double last_theta[kMaxParams];
  double last_curvature = 0;
  bool last_ok = false;
  void Integral(double tp, double ta) {
    if (tp != int_t) {
      GaussianProfileIntegral(tp, ta, &int_i, &int_di);
      int_t = tp;
    }
  }
};

Inverter::Inverter(std::shared_ptr<const BinnedModel> model, std::shared_ptr<const SceneTable> table,
                   double t_amb, InversionOptions options)
    : model_(std::move(model)), table_(std::move(table)), t_amb_(t_amb), options_(std::move(options)) {
  Require(model_ != nullptr, "the inversion needs a forward model");
  const std::size_t ns = model_->num_species(), nc = model_->num_channels();
  options_.Check(ns, nc);
  CheckInRange(t_amb, model_->min_temperature_K(), model_->max_temperature_K(),
               "ambient_temperature_K (within the cross-section tables)", "K");
  if (table_) {
    Require(&table_->model() == model_.get(), "the scene table was built from another model");
    Require(std::abs(table_->ambient_temperature_K() - t_amb) <= 1e-9 * t_amb,
            "the scene table was built for ambient temperature " +
                FormatNumber(table_->ambient_temperature_K()) + " K, not " + FormatNumber(t_amb) +
                " K; build one for this scene");
  }
  switch (options_.solver) {
    case SolverKind::kAuto: use_table_ = table_ != nullptr; break;
    case SolverKind::kTable:
      Require(table_ != nullptr, "solver 'table' needs a scene table (the species overlap "
                                 "spectrally or none was built); use solver 'full_model'");
      use_table_ = true;
      break;
    case SolverKind::kFullModel: use_table_ = false; break;
  }
  // Resolve the parameter specs.
  const double t_lo = table_ ? table_->min_peak_temperature_K() : model_->min_temperature_K();
  const double t_hi = table_ ? table_->max_peak_temperature_K() : model_->max_temperature_K();
  const double s_hi = table_ ? table_->options().max_sigma_m : 1e3;
  specs_.resize(ns + 2);
  for (std::size_t s = 0; s < ns; ++s) {
    ParameterSpec p = options_.fractions.empty()
                          ? ParameterSpec{ParameterMode::kFree, 1e-3, 0.0, 0.0, 1.0}
                          : options_.fractions[s];
    if (p.lower == 0 && p.upper == 0) p.upper = 1.0;
    specs_[s] = p;
  }
  ParameterSpec& tp = specs_[ns];
  tp = options_.temperature;
  if (tp.value == 0) tp.value = t_amb;
  if (tp.lower == 0 && tp.upper == 0) {
    tp.lower = t_lo;
    tp.upper = t_hi;
  }
  Require(tp.lower >= t_lo - 1e-9 && tp.upper <= t_hi + 1e-9,
          "temperature bounds [" + FormatNumber(tp.lower) + ", " + FormatNumber(tp.upper) +
              "] K must lie inside the tabulated range [" + FormatNumber(t_lo) + ", " +
              FormatNumber(t_hi) + "] K");
  Require(tp.value >= t_lo && tp.value <= t_hi,
          "temperature value " + FormatNumber(tp.value) + " K is outside the tabulated range [" +
              FormatNumber(t_lo) + ", " + FormatNumber(t_hi) + "] K");
  ParameterSpec& sg = specs_[ns + 1];
  sg = options_.sigma;
  if (sg.lower == 0 && sg.upper == 0) {
    sg.lower = 1e-4;
    sg.upper = s_hi;
  }
  Require(sg.upper <= s_hi * (1 + 1e-12),
          "sigma upper bound " + FormatNumber(sg.upper) + " m exceeds the table's max_sigma_m " +
              FormatNumber(s_hi) + " m; build the table with a larger max_sigma_m");
  Require(sg.value <= s_hi * (1 + 1e-12),
          "sigma value " + FormatNumber(sg.value) + " m exceeds the table's max_sigma_m " +
              FormatNumber(s_hi) + " m");

  // Per-channel band tables and noise.
  const double bg_lo = table_ ? table_->options().min_background_K : 150.0;
  const double bg_hi = table_ ? table_->options().max_background_K : 700.0;
  for (std::size_t c = 0; c < nc; ++c)
    bands_.emplace_back(model_->channels()[c], bg_lo, bg_hi, 0.5);
  netd_.assign(nc, options_.netd_K[0]);
  if (options_.netd_K.size() == nc) netd_ = options_.netd_K;
  for (std::size_t s = 0; s < ns; ++s)
    column_factor_.push_back(model_->molar_masses()[s] * model_->pressure_Pa() /
                             (constants::kAvogadro * constants::kBoltzmann));

  // The one-unknown Newton path: one channel, one free fraction, nothing else estimated.
  int n_est = 0, which = -1;
  for (std::size_t p = 0; p < ns + 2; ++p)
    if (specs_[p].mode == ParameterMode::kFree || specs_[p].mode == ParameterMode::kPrior) {
      ++n_est;
      which = static_cast<int>(p);
    }
  bool ties = false;
  for (std::size_t s = 0; s < ns; ++s) ties = ties || specs_[s].mode == ParameterMode::kTied;
  newton_ = use_table_ && nc == 1 && n_est == 1 && !ties && which < static_cast<int>(ns) &&
            specs_[which].mode == ParameterMode::kFree;
  newton_param_ = which < 0 ? 0 : static_cast<std::size_t>(which);
  // The profile's temperatures: the bounds of T_peak and the table's nodes
  // strictly between them.
  if (use_table_ && !newton_ && options_.cold_start == ColdStart::kProfile &&
      (tp.mode == ParameterMode::kFree || tp.mode == ParameterMode::kPrior)) {
    const double lo = tp.lower, hi = tp.upper;
    const int nt = table_->num_temperature_nodes();
    const double t0 = table_->min_peak_temperature_K();
    const double h = (table_->max_peak_temperature_K() - t0) / (nt - 1);
    slices_.push_back(table_->MakeSlice(lo));
    for (int k = 0; k < nt; ++k) {
      const double tk = t0 + k * h;
      if (tk > lo + 0.25 * h && tk < hi - 0.25 * h) slices_.push_back(table_->MakeSlice(tk));
    }
    slices_.push_back(table_->MakeSlice(hi));
  }
}

double Inverter::ChannelNoise(std::size_t c, double t_bg) const {
  return netd_[c] * bands_[c].Derivative(t_bg);
}

bool Inverter::PreparePixel(const PixelBatch& b, std::size_t f, std::size_t i, Pixel* px) const {
  const std::size_t nc = model_->num_channels(), ns = model_->num_species(), np = ns + 2;
  const std::size_t n = b.num_pixels;
  px->nc = nc;
  px->ns = ns;
  px->np = np;
  // Parameters.
  for (std::size_t p = 0; p < np; ++p) {
    const ParameterSpec& sp = specs_[p];
    double v = sp.value;
    if (p == ns && b.peak_temperature_K) v = b.peak_temperature_K[i];
    if (p == ns + 1 && b.sigma_m) v = b.sigma_m[i];
    px->nominal[p] = v;
    px->est[p] = sp.mode == ParameterMode::kFree || sp.mode == ParameterMode::kPrior;
    px->prior_sigma[p] = sp.mode == ParameterMode::kPrior ? sp.prior_sigma : 0.0;
    px->lower[p] = px->est[p] ? sp.lower : v;
    px->upper[p] = px->est[p] ? sp.upper : v;
    px->theta[p] = v;
  }
  px->has_ties = false;
  for (std::size_t s2 = 0; s2 < ns; ++s2) {
    px->tie_ref[s2] = -1;
    px->tie_ratio[s2] = 0.0;
    if (specs_[s2].mode != ParameterMode::kTied) continue;
    px->has_ties = true;
    px->tie_ref[s2] = specs_[s2].tied_to;
    px->tie_ratio[s2] = specs_[s2].value;
    px->est[s2] = false;
    px->prior_sigma[s2] = 0.0;
  }
  for (std::size_t s2 = 0; s2 < ns; ++s2) {
    const int r = px->tie_ref[s2];
    if (r < 0) continue;
    // The tied fraction must stay <= 1 too.
    px->upper[r] = std::min(px->upper[r], 1.0 / px->tie_ratio[s2]);
  }
  for (std::size_t s2 = 0; s2 < ns; ++s2) {
    const int r = px->tie_ref[s2];
    if (r < 0) continue;
    px->nominal[s2] = px->tie_ratio[s2] * px->nominal[r];
    px->lower[s2] = px->tie_ratio[s2] * px->lower[r];
    px->upper[s2] = px->tie_ratio[s2] * px->upper[r];
    px->theta[s2] = px->nominal[s2];
  }
  bool ok = true;
  const double tp = px->nominal[ns], sg = px->nominal[ns + 1];
  if (!(std::isfinite(tp) && tp >= specs_[ns].lower && tp <= specs_[ns].upper)) ok = false;
  if (!(std::isfinite(sg) && sg > 0 && sg <= specs_[ns + 1].upper)) ok = false;
  // Measured contrast, background and noise.
  const std::size_t fb = b.background_per_frame ? f : 0;
  for (std::size_t c = 0; c < nc; ++c) {
    const double l = b.radiance[(f * nc + c) * n + i];
    double t_bg = 0, l_bg = 0, dl_dt = 0;
    if (b.background_temperature_K) {
      t_bg = b.background_temperature_K[(fb * nc + c) * n + i];
      if (!(std::isfinite(t_bg) && t_bg >= bands_[c].min_temperature_K() &&
            t_bg <= bands_[c].max_temperature_K())) {
        ok = false;
        t_bg = bands_[c].min_temperature_K();
      }
      bands_[c].RadianceAndDerivative(t_bg, &l_bg, &dl_dt);
    } else {
      l_bg = b.background_radiance[(fb * nc + c) * n + i];
      if (!bands_[c].Temperature(l_bg, &t_bg)) {
        ok = false;
        t_bg = bands_[c].min_temperature_K();
      }
      dl_dt = bands_[c].Derivative(t_bg);
    }
    const double y = l - l_bg;
    if (!std::isfinite(y)) ok = false;
    px->y[c] = std::isfinite(y) ? y : 0.0;
    px->tbg[c] = t_bg;
    double noise = netd_[c] * dl_dt;
    if (options_.model_error_fraction > 0) {
      const double me = options_.model_error_fraction * px->y[c];
      noise = std::sqrt(noise * noise + me * me);
    }
    px->noise[c] = noise;
  }
  // Scales: fractions by their start magnitude, T_peak by 10 K, sigma by itself.
  for (std::size_t s = 0; s < ns; ++s) px->scale[s] = 1e-3;
  px->scale[ns] = 10.0;
  px->scale[ns + 1] = std::max(sg, 1e-6);
  return ok;
}

// Small non-negative least squares min ||A u - b|| (A: m x k, k <= 6) by active sets.
static void SmallNnls(const Eigen::MatrixXd& a, const Eigen::VectorXd& b, Eigen::VectorXd* u) {
  const int k = static_cast<int>(a.cols());
  std::vector<bool> on(k, true);
  u->setZero(k);
  for (int iter = 0; iter <= k; ++iter) {
    std::vector<int> idx;
    for (int j = 0; j < k; ++j)
      if (on[j]) idx.push_back(j);
    if (idx.empty()) return;
    Eigen::MatrixXd as(a.rows(), idx.size());
    for (std::size_t j = 0; j < idx.size(); ++j) as.col(j) = a.col(idx[j]);
    Eigen::MatrixXd n = as.transpose() * as;
    n.diagonal().array() += 1e-12 * (n.diagonal().maxCoeff() + 1e-300);
    const Eigen::VectorXd sol = n.ldlt().solve(as.transpose() * b);
    int worst = -1;
    double wv = 0;
    for (std::size_t j = 0; j < idx.size(); ++j)
      if (!(sol[j] >= 0) && (worst < 0 || sol[j] < wv)) {
        worst = static_cast<int>(j);
        wv = sol[j];
      }
    if (worst < 0) {
      u->setZero(k);
      for (std::size_t j = 0; j < idx.size(); ++j) (*u)[idx[j]] = sol[j];
      return;
    }
    on[idx[worst]] = false;
  }
}

// --- the small bounded Levenberg-Marquardt solver -----------------------------

namespace {

constexpr std::size_t kMaxRows = kMaxChannels + kMaxParams;  // channels and priors

// Solver coordinates of parameter p (S = number of species): ln(theta + kLogEps)
// for the fractions and sigma (x sigma is what the radiance sees: the
// column-temperature trade-off is a straight valley there), T_peak / 10 K.
inline double ToParam(std::size_t p, std::size_t ns, double theta) {
  return p == ns ? theta / 10.0 : std::log(theta + kLogEps);
}
inline double ToTheta(std::size_t p, std::size_t ns, double v) {
  return p == ns ? 10.0 * v : std::exp(v) - kLogEps;
}
inline double Slope(std::size_t p, std::size_t ns, double theta) {  // d theta / d v
  return p == ns ? 10.0 : theta + kLogEps;
}

// x = (A + extra I)^-1 b for a symmetric positive semi-definite n x n A
// (row-major, n <= kMaxParams), computed on A scaled to unit diagonal (a
// ridge of 1e-10 keeps singular directions finite); returns b . x.
double SolveScaled(const double* a, const double* b, int n, double extra, double* x) {
  double d[kMaxParams], l[kMaxParams * kMaxParams], z[kMaxParams];
  for (int i = 0; i < n; ++i) d[i] = std::sqrt(std::max(a[i * n + i], 1e-300));
  for (double ridge = 1e-10;; ridge *= 1e3) {
    bool ok = true;
    for (int i = 0; i < n && ok; ++i)
      for (int j = 0; j <= i; ++j) {
        double v = a[i * n + j] / (d[i] * d[j]) + (i == j ? ridge + extra : 0.0);
        for (int k = 0; k < j; ++k) v -= l[i * n + k] * l[j * n + k];
        if (i == j) {
          if (!(v > 0)) {
            ok = false;
            break;
          }
          l[i * n + i] = std::sqrt(v);
        } else {
          l[i * n + j] = v / l[j * n + j];
        }
      }
    if (ok || ridge > 1) break;
  }
  for (int i = 0; i < n; ++i) {
    double v = b[i] / d[i];
    for (int k = 0; k < i; ++k) v -= l[i * n + k] * z[k];
    z[i] = v / l[i * n + i];
  }
  double dot = 0;
  for (int i = n - 1; i >= 0; --i) {
    double v = z[i];
    for (int k = i + 1; k < n; ++k) v -= l[k * n + i] * z[k];
    z[i] = v / l[i * n + i];
    x[i] = z[i] / d[i];
    dot += b[i] * x[i];
  }
  return std::isfinite(dot) ? dot : 0.0;
}

// chi2 decrease predicted by a Gauss-Newton step over the parameters in
// set[0..n) (g = J^T r, h = J^T J over all np parameters, row-major).
double PredictedDecrease(const double* g, const double* h, std::size_t np, const int* set, int n) {
  if (n == 0) return 0.0;
  double hs[kMaxParams * kMaxParams], gs[kMaxParams], step[kMaxParams];
  for (int a = 0; a < n; ++a) {
    gs[a] = g[set[a]];
    for (int b = 0; b < n; ++b) hs[a * n + b] = h[set[a] * np + set[b]];
  }
  return SolveScaled(hs, gs, n, 0.0, step);
}

struct LmSettings {
  std::uint8_t estimate = 0;  // bit p: parameter p is varied
  int max_iterations = 100;
  double tolerance = 0.01;    // converged: the Gauss-Newton step would lower chi2 by less
  double stop = 1e-5;         // iterate on while it would lower chi2 by more than this (<= tolerance)
  // Stop at the first failed or slow Gauss-Newton step below the tolerance
  // (false: iterate on to `stop`, however slowly).
  bool stop_when_slow = true;
};

// Minimises the sum of squares of eval's residuals over the parameters in
// settings.estimate within [px.lower, px.upper], from theta (updated in
// place, ties applied), with Levenberg-Marquardt steps in the solver
// coordinates. A step crossing a bound is cut there and the parameter held
// (*held, bit p); a held parameter is released when its multiplier points
// inside and releasing it would lower chi2 by more than the tolerance (a
// fraction released from 0 restarts at its one-dimensional Newton step); a
// free parameter converging onto a bound (within 1e-3 of its conditional
// standard deviation; fractions approach 0 asymptotically in log
// coordinates) is held there. eval(theta, r, jac) fills the residuals r and
// their derivatives jac[row * np + p] (ties folded) and returns false when
// they are not finite. On return r, jac and *cost belong to theta. Returns
// whether it converged.
template <class Eval>
bool BoundedLm(const Inverter::Pixel& px, const LmSettings& set, std::size_t nr, Eval&& eval,
               double* theta, std::uint8_t* held_io, double* r, double* jac, double* cost,
               int* iterations) {
  const std::size_t np = px.np, ns = px.ns;
  std::uint8_t held = *held_io;
  auto sum_sq = [&](const double* v) {
    double c = 0;
    for (std::size_t k = 0; k < nr; ++k) c += v[k] * v[k];
    return c;
  };
  // A parameter starting on a bound is held there until its multiplier
  // releases it (in log coordinates a fraction at 0 could not move).
  for (std::size_t p = 0; p < np; ++p)
    if ((set.estimate >> p & 1) && (theta[p] <= px.lower[p] || theta[p] >= px.upper[p]))
      held |= static_cast<std::uint8_t>(1u << p);
  if (!eval(theta, r, jac)) return false;
  *cost = sum_sq(r);
  double mu = 1e-3, nu = 2.0, last_dec = 0;
  int it = 0, changes = 0;
  bool gn_accepted = false, gn_failed = false;
  int accepted_since_gn_failure = 3;
  bool ok = false;
  double g[kMaxParams], h[kMaxParams * kMaxParams];
  double rt[kMaxRows], jt[kMaxRows * kMaxParams], trial[kMaxParams];
  int act[kMaxParams], est[kMaxParams];
  for (;;) {
    // Gradient and Gauss-Newton matrix over the varied parameters.
    int ne = 0, na = 0;
    for (std::size_t p = 0; p < np; ++p) {
      if (!(set.estimate >> p & 1)) continue;
      est[ne++] = static_cast<int>(p);
      if (!(held >> p & 1)) act[na++] = static_cast<int>(p);
    }
    for (int a = 0; a < ne; ++a) {
      const int p = est[a];
      double gp = 0;
      for (std::size_t k = 0; k < nr; ++k) gp += r[k] * jac[k * np + p];
      g[p] = gp;
      for (int b = 0; b <= a; ++b) {
        const int q = est[b];
        double hv = 0;
        for (std::size_t k = 0; k < nr; ++k) hv += jac[k * np + p] * jac[k * np + q];
        h[p * np + q] = h[q * np + p] = hv;
      }
    }
    const double dec = PredictedDecrease(g, h, np, act, na);
    // Below the tolerance, iterate on while Gauss-Newton converges fast
    // (small residuals: quadratically, and solutions from different starts
    // then agree to many digits); stop at the first slow or failed
    // Gauss-Newton step (with larger residuals, in a curved valley, the
    // linear model no longer describes the last digits, which are far below
    // the noise anyway).
    const bool slow = set.stop_when_slow && dec < set.tolerance &&
                      (gn_failed || (gn_accepted && dec > 0.1 * last_dec));
    gn_accepted = false;
    if (dec < set.stop || slow || it >= set.max_iterations || mu > 1e12) {
      if (dec >= set.tolerance) break;  // out of iterations (or no progress possible)
      // Release the held parameter whose multiplier points inside with the
      // largest predicted gain.
      int release = -1;
      double best = set.tolerance;
      if (changes < 3 * static_cast<int>(np) + 2) {
        for (int a = 0; a < ne; ++a) {
          const int p = est[a];
          if (!(held >> p & 1)) continue;
          const bool at_lower = theta[p] <= px.lower[p];
          if (!(at_lower ? g[p] < 0 : g[p] > 0)) continue;
          int with[kMaxParams];
          std::copy(act, act + na, with);
          with[na] = p;
          const double gain = PredictedDecrease(g, h, np, with, na + 1) - dec;
          if (gain > best) {
            best = gain;
            release = p;
          }
        }
      }
      if (release >= 0) {
        held &= static_cast<std::uint8_t>(~(1u << release));
        ++changes;
        // Released from a bound: the one-dimensional Newton step (a fraction at
        // 0 has no leverage in log coordinates).
        const double step = h[release * np + release] > 0 ? -g[release] / h[release * np + release] : 0.0;
        double v = theta[release] + step;
        v = std::min(std::max(v, px.lower[release]), px.upper[release]);
        std::copy(theta, theta + np, trial);
        trial[release] = v;
        px.ApplyTies(trial);
        if (eval(trial, rt, jt)) {
          const double ct = sum_sq(rt);
          if (ct < *cost) {
            std::copy(trial, trial + np, theta);
            std::copy(rt, rt + nr, r);
            std::copy(jt, jt + nr * np, jac);
            *cost = ct;
          }
        }
        mu = 1e-3;
        nu = 2.0;
        ++it;
        continue;
      }
      // Hold a free parameter whose Gauss-Newton step would cross its bound
      // (fractions approach 0 only asymptotically in log coordinates), or
      // that converged onto its bound.
      int snap = -1;
      if (na > 0 && changes < 3 * static_cast<int>(np) + 2) {
        double hs[kMaxParams * kMaxParams], gs[kMaxParams], dx[kMaxParams];
        for (int a = 0; a < na; ++a) {
          gs[a] = -g[act[a]];
          for (int b = 0; b < na; ++b) hs[a * na + b] = h[act[a] * np + act[b]];
        }
        SolveScaled(hs, gs, na, 0.0, dx);
        double worst = 0, snap_value = 0;
        for (int a = 0; a < na; ++a) {
          const int p = act[a];
          const double sd = h[p * np + p] > 0 ? 1.0 / std::sqrt(h[p * np + p]) : 0.0;
          if (!(sd > 0)) continue;
          const double below = (px.lower[p] - (theta[p] + dx[a])) / sd;
          const double above = ((theta[p] + dx[a]) - px.upper[p]) / sd;
          if (below > worst) {
            worst = below;
            snap = p;
            snap_value = px.lower[p];
          }
          if (above > worst) {
            worst = above;
            snap = p;
            snap_value = px.upper[p];
          }
        }
        // Only when the bound fits as well (the step of an ill-conditioned
        // valley can be far longer than its chi2 gain suggests).
        if (snap >= 0) {
          std::copy(theta, theta + np, trial);
          trial[snap] = snap_value;
          px.ApplyTies(trial);
          if (eval(trial, rt, jt) && sum_sq(rt) <= *cost + set.tolerance) {
            held |= static_cast<std::uint8_t>(1u << snap);
            ++changes;
            std::copy(trial, trial + np, theta);
            std::copy(rt, rt + nr, r);
            std::copy(jt, jt + nr * np, jac);
            *cost = sum_sq(rt);
            continue;
          }
          snap = -1;
        }
      }
      for (int a = 0; a < na && snap < 0 && changes < 3 * static_cast<int>(np) + 2; ++a) {
        const int p = act[a];
        const double sd = h[p * np + p] > 0 ? 1.0 / std::sqrt(h[p * np + p]) : 0.0;
        if (theta[p] - px.lower[p] < 1e-3 * sd && theta[p] != px.lower[p]) {
          theta[p] = px.lower[p];
          snap = p;
        } else if (px.upper[p] - theta[p] < 1e-3 * sd && theta[p] != px.upper[p]) {
          theta[p] = px.upper[p];
          snap = p;
        } else if (theta[p] == px.lower[p] || theta[p] == px.upper[p]) {
          snap = p;
        }
      }
      if (snap >= 0) {
        held |= static_cast<std::uint8_t>(1u << snap);
        ++changes;
        px.ApplyTies(theta);
        if (!eval(theta, r, jac)) break;
        *cost = sum_sq(r);
        continue;
      }
      ok = true;
      break;
    }
    ++it;
    gn_failed = false;
    // Levenberg-Marquardt step in solver coordinates, cut at the first bound.
    double gs[kMaxParams], hs[kMaxParams * kMaxParams], sl[kMaxParams], dv[kMaxParams];
    for (int a = 0; a < na; ++a) {
      const int p = act[a];
      sl[a] = Slope(p, ns, theta[p]);
      gs[a] = -g[p] * sl[a];
    }
    for (int a = 0; a < na; ++a)
      for (int b = 0; b < na; ++b) hs[a * na + b] = h[act[a] * np + act[b]] * sl[a] * sl[b];
    // Near the optimum pure Gauss-Newton steps (quadratic convergence for
    // small residuals); damped steps elsewhere.
    // (After a failed one, only once a few damped steps have succeeded.)
    const bool gn = dec < set.tolerance && nu <= 2.0 && accepted_since_gn_failure >= 3;
    SolveScaled(hs, gs, na, gn ? 0.0 : mu, dv);
    // A trust region in log coordinates: at most a factor e^5 per step.
    double alpha = 1.0, hit_value = 0;
    for (int a = 0; a < na; ++a)
      if (act[a] != static_cast<int>(ns) && std::abs(dv[a]) * alpha > 5.0) alpha = 5.0 / std::abs(dv[a]);
    int hit = -1;
    for (int a = 0; a < na; ++a) {
      const int p = act[a];
      const double v = ToParam(p, ns, theta[p]);
      if (dv[a] < 0) {
        const double lo = ToParam(p, ns, px.lower[p]);
        if (v + dv[a] < lo) {
          const double al = (lo - v) / dv[a];
          if (al < alpha) {
            alpha = al;
            hit = p;
            hit_value = px.lower[p];
          }
        }
      } else if (dv[a] > 0) {
        const double hi = ToParam(p, ns, px.upper[p]);
        if (v + dv[a] > hi) {
          const double al = (hi - v) / dv[a];
          if (al < alpha) {
            alpha = al;
            hit = p;
            hit_value = px.upper[p];
          }
        }
      }
    }
    alpha = std::max(alpha, 0.0);
    std::copy(theta, theta + np, trial);
    for (int a = 0; a < na; ++a) {
      const int p = act[a];
      trial[p] = std::min(std::max(ToTheta(p, ns, ToParam(p, ns, theta[p]) + alpha * dv[a]),
                                   px.lower[p]),
                          px.upper[p]);
    }
    if (hit >= 0) trial[hit] = hit_value;
    if (hit >= 0 && alpha < 1e-12) {
      // Already on that bound and pushing out of it: hold it there.
      held |= static_cast<std::uint8_t>(1u << hit);
      ++changes;
      continue;
    }
    px.ApplyTies(trial);
    double ct = std::numeric_limits<double>::infinity();
    if (eval(trial, rt, jt)) ct = sum_sq(rt);
    if (ct < *cost) {
      // Gain ratio against the linear model's decrease.
      double model = 0;
      for (int a = 0; a < na; ++a) {
        double hv = 0;
        for (int b = 0; b < na; ++b) hv += hs[a * na + b] * alpha * dv[b];
        model += alpha * dv[a] * (2.0 * gs[a] - hv);
      }
      const double rho = model > 0 ? (*cost - ct) / model : 1.0;
      std::copy(trial, trial + np, theta);
      std::copy(rt, rt + nr, r);
      std::copy(jt, jt + nr * np, jac);
      *cost = ct;
      if (hit >= 0) {
        held |= static_cast<std::uint8_t>(1u << hit);
        ++changes;
      }
      const double t = 2.0 * rho - 1.0;
      mu *= std::max(1.0 / 3.0, 1.0 - t * t * t);
      nu = 2.0;
      gn_accepted = gn && hit < 0;
      last_dec = dec;
      ++accepted_since_gn_failure;
    } else {
      gn_failed = gn;
      if (gn) accepted_since_gn_failure = 0;
      mu *= nu;
      nu *= 2.0;
    }
  }
  *held_io = held;
  *iterations += it;
  return ok;
}

// Minimises like BoundedLm, with T_peak (parameter S) estimated, by variable
// projection: the other parameters z are solved by BoundedLm at fixed T_peak
// (nearly linear and well conditioned: a few Gauss-Newton steps), and the
// profile chi2_min(T_peak) is minimised in one dimension. Joint steps do
// poorly here: in the curved column-temperature valley their quadratic model
// holds only for tiny steps, and the residuals' curvature (absent from
// J^T J) dominates the profile's (by two orders of magnitude on noisy
// pixels), so Gauss-Newton overestimates steps along the valley. The
// profile's slope is exact (envelope theorem: the T_peak component of the
// gradient at the fixed-T_peak solution); its curvature comes from the
// slopes at the last two temperatures with the same parameters on bounds
// (a bound that becomes active kinks the profile's slope), first from the
// caller's estimate. Newton steps on the slope, safeguarded by the bracket
// of its sign change (bisection when a step leaves it or it stops halving).
// Each new temperature starts z from the valley's tangent
// dz/dT = -H_zz^-1 H_zT (Gauss-Newton).
// curvature: first estimate of d(slope)/dT_peak (slope = J_T . r, half the
// chi2 derivative) [1/K^2], 0 when unknown (then a 1 K trial step); on
// return the last estimate. Converged when z has converged and a Newton
// step in T_peak would lower chi2 by less than set.stop (or, with
// stop_when_slow, the tolerance); T_peak is held on a bound where its slope
// points out.
template <class Eval>
bool ProfileLm(const Inverter::Pixel& px, const LmSettings& set, std::size_t nr, Eval&& eval,
               double* theta, std::uint8_t* held_io, double* r, double* jac, double* cost,
               int* iterations, double* curvature) {
  const std::size_t np = px.np, ns = px.ns;
  const std::uint8_t t_bit = static_cast<std::uint8_t>(1u << ns);
  // A first step of at most kMaxStep: starts come from the profile over the
  // table's temperature nodes (5 K apart), which has located the minimum
  // within a node spacing, and with a composition known the profile can be
  // narrow (a longer step would cross into the next minimum).
  constexpr double kTrialStep = 1.0, kMaxStep = 2.5;  // [K]
  LmSettings inner = set;
  inner.estimate = static_cast<std::uint8_t>(set.estimate & ~t_bit);
  const double lo = px.lower[ns], hi = px.upper[ns];
  // Bracket [a, b] of the slope's sign change (a: slope < 0, b: slope > 0
  // once known; the bounds until then), and the last step's length.
  double a = lo, b = hi, last_step = hi - lo;
  bool a_known = false, b_known = false;
  // The last temperature and slope per set of held parameters (branch).
  struct Point {
    std::uint8_t held;
    double t, g;
  };
  Point last[4];
  int num_last = 0;
  double t = std::min(std::max(theta[ns], lo), hi);
  double s = *curvature;
  std::uint8_t held = static_cast<std::uint8_t>(*held_io & ~t_bit);
  bool ok = false;
  int used = 0;
  // Far from the profile's minimum z need not be solved to the last digit:
  // the inner solves stop at 1e-3 of the last predicted profile decrease
  // (within [set.stop, tolerance]; the reduced slope is then accurate to
  // second order), and at set.stop before convergence is declared.
  double max_step = kMaxStep, dec = std::numeric_limits<double>::infinity();
  for (;;) {
    theta[ns] = t;
    inner.stop = std::min(std::max(1e-3 * dec, set.stop), std::max(set.tolerance, set.stop));
    inner.max_iterations = std::max(set.max_iterations - used, 1);
    int it = 0;
    const bool inner_ok = BoundedLm(px, inner, nr, eval, theta, &held, r, jac, cost, &it);
    used += it + 1;  // its iterations and its first evaluation
    if (!inner_ok) break;
    // The profile's slope: the T_peak gradient reduced by z's (zero once z
    // has converged; the reduction removes the first-order error of an
    // inexact z, which the ill-conditioning amplifies), and the tangent.
    int act[kMaxParams], na = 0;
    for (std::size_t p = 0; p < np; ++p)
      if ((inner.estimate >> p & 1) && !(held >> p & 1)) act[na++] = static_cast<int>(p);
    double g = 0;
    for (std::size_t k = 0; k < nr; ++k) g += r[k] * jac[k * np + ns];
    double dz[kMaxParams];
    if (na > 0) {
      double hzz[kMaxParams * kMaxParams], hzt[kMaxParams], gz[kMaxParams], x[kMaxParams];
      for (int i = 0; i < na; ++i) {
        double v = 0, w = 0;
        for (std::size_t k = 0; k < nr; ++k) {
          v += jac[k * np + act[i]] * jac[k * np + ns];
          w += jac[k * np + act[i]] * r[k];
        }
        hzt[i] = v;
        gz[i] = w;
        for (int j = 0; j <= i; ++j) {
          double h = 0;
          for (std::size_t k = 0; k < nr; ++k) h += jac[k * np + act[i]] * jac[k * np + act[j]];
          hzz[i * na + j] = hzz[j * na + i] = h;
        }
      }
      SolveScaled(hzz, hzt, na, 0.0, x);
      for (int i = 0; i < na; ++i) {
        g -= x[i] * gz[i];
        dz[i] = -x[i];
      }
    }
    // Curvature: secant with the last temperature on the same branch.
    int same = -1;
    for (int k = 0; k < num_last; ++k)
      if (last[k].held == held) same = k;
    if (same >= 0 && last[same].t != t) {
      const double secant = (g - last[same].g) / (t - last[same].t);
      if (secant > 0) s = secant;
    }
    if (same < 0 && num_last > 0) s = 0;  // a new branch: the old curvature does not hold
    if (same < 0) same = num_last < 4 ? num_last++ : 3;
    last[same] = Point{held, t, g};
    // Done at a bound where the slope points out, or when a Newton step
    // would gain less than set.stop (the tolerance); z to set.stop first.
    // A Newton step that would cross a bound leads there instead (on flat
    // profiles the bound is the minimum, however small the predicted gain).
    const bool at_bound = (t <= lo && g >= 0) || (t >= hi && g <= 0);
    const double dec_t = s > 0 ? g * g / s : std::numeric_limits<double>::infinity();
    const bool crosses = s > 0 && (t - g / s < lo || t - g / s > hi);
    if (at_bound || (!crosses && (dec_t < set.stop || (set.stop_when_slow && dec_t < set.tolerance)))) {
      if (inner.stop > set.stop && !set.stop_when_slow) {
        dec = 0;
        continue;
      }
      if (at_bound) held |= t_bit;
      ok = true;
      break;
    }
    dec = dec_t;
    if (used >= set.max_iterations) break;
    if (g > 0) {
      b = t;
      b_known = true;
    } else {
      a = t;
      a_known = true;
    }
    const bool bracketed = a_known && b_known;
    double tn;
    if (s > 0) {
      tn = t - g / s;
    } else if (bracketed) {
      tn = 0.5 * (a + b);
    } else {
      tn = t + (g > 0 ? -kTrialStep : kTrialStep);
    }
    // Steps of at most max_step, doubled while the slope keeps its sign
    // (a long descent, e.g. to a bound).
    const bool clamped = std::abs(tn - t) > max_step;
    tn = std::min(std::max(tn, t - max_step), t + max_step);
    if (clamped && !bracketed) max_step *= 2;
    if (bracketed && (!(tn > a && tn < b) || std::abs(tn - t) > 0.5 * last_step)) {
      tn = 0.5 * (a + b);  // bisection when the step leaves the bracket or does not shrink
    } else {
      if (tn <= a) tn = a_known ? 0.5 * (a + t) : a;
      if (tn >= b) tn = b_known ? 0.5 * (b + t) : b;
    }
    last_step = std::abs(tn - t);
    if (tn == t) {  // the bracket has shrunk to rounding
      ok = dec < set.tolerance;
      break;
    }
    for (int i = 0; i < na; ++i) {
      const int p = act[i];
      // In solver coordinates, at most a factor e per temperature step.
      const double dv = std::min(std::max(dz[i] * (tn - t) / Slope(p, ns, theta[p]), -1.0), 1.0);
      theta[p] = std::min(std::max(ToTheta(p, ns, ToParam(p, ns, theta[p]) + dv), px.lower[p]),
                          px.upper[p]);
    }
    px.ApplyTies(theta);
    t = tn;
  }
  *held_io = held;
  *iterations += used;
  *curvature = s;
  return ok;
}

// Residual rows of a pixel: one per channel, then one per estimated
// parameter with a prior.
std::size_t NumRows(const Inverter::Pixel& px) {
  std::size_t n = px.nc;
  for (std::size_t p = 0; p < px.np; ++p)
    if (px.est[p] && px.prior_sigma[p] > 0) ++n;
  return n;
}

// The 99 % quantile of chi2 (with priors) for the pixel's degrees of freedom
// (residual rows minus estimated parameters, at least 1), by the
// Wilson-Hilferty approximation (within 1 % for one degree of freedom).
double FitThreshold(const Inverter::Pixel& px) {
  int ne = 0;
  for (std::size_t p = 0; p < px.np; ++p) ne += px.est[p] ? 1 : 0;
  const double k = std::max(1.0, static_cast<double>(NumRows(px)) - ne);
  const double c = 2.0 / (9.0 * k);
  const double q = 1.0 - c + 2.3263 * std::sqrt(c);
  return k * q * q * q;
}

// Fills the prior rows (from row nc on) of the residuals and their derivatives.
void PriorRows(const Inverter::Pixel& px, const double* theta, double* r, double* jac) {
  std::size_t row = px.nc;
  for (std::size_t p = 0; p < px.np; ++p) {
    if (!(px.est[p] && px.prior_sigma[p] > 0)) continue;
    r[row] = (theta[p] - px.nominal[p]) / px.prior_sigma[p];
    if (jac) {
      std::fill(jac + row * px.np, jac + (row + 1) * px.np, 0.0);
      jac[row * px.np + p] = 1.0 / px.prior_sigma[p];
    }
    ++row;
  }
}

}  // namespace

void Inverter::ThinGuess(const Pixel& px, double tc, double* th) const {
  const std::size_t nc = px.nc, ns = px.ns;
  const SceneTable& t = *table_;
  const double sigma = th[ns + 1];
  std::vector<int> free_s;
  for (std::size_t s = 0; s < ns; ++s)
    if (px.est[s]) free_s.push_back(static_cast<int>(s));
  th[ns] = tc;
  for (int s : free_s) th[s] = 0.0;
  px.ApplyTies(th);
  if (free_s.empty()) return;
  double con[kMaxChannels];
  t.Contrast(th, tc, sigma, px.phi, con, nullptr);  // the fixed species
  Eigen::MatrixXd a(nc, free_s.size());
  Eigen::VectorXd b(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    b[c] = (px.y[c] - con[c]) / px.noise[c];
    for (std::size_t j = 0; j < free_s.size(); ++j) {
      double slope = t.ThinSlope(c, free_s[j], tc, px.phi);
      for (std::size_t s2 = 0; s2 < ns; ++s2)  // tied species follow (u_s2 = ratio u)
        if (px.tie_ref[s2] == free_s[j]) slope += px.tie_ratio[s2] * t.ThinSlope(c, s2, tc, px.phi);
      a(c, j) = slope / px.noise[c];
    }
  }
  Eigen::VectorXd u;
  SmallNnls(a, b, &u);
  for (std::size_t j = 0; j < free_s.size(); ++j) {
    const int s = free_s[j];
    th[s] = std::min(std::max(u[j] / sigma, px.lower[s]), px.upper[s]);
  }
  px.ApplyTies(th);
}

void Inverter::TableGuess(const Pixel& px, std::vector<GuessCandidate>* out, Workspace*) const {
  const std::size_t nc = px.nc, ns = px.ns, np = px.np;
  const SceneTable& t = *table_;
  std::vector<double> cands;
  cands.push_back(px.nominal[ns]);
  if (px.est[ns]) {
    const int n = options_.temperature_candidates;
    for (int k = 0; k < n; ++k)
      cands.push_back(n == 1 ? 0.5 * (px.lower[ns] + px.upper[ns])
                             : px.lower[ns] + (px.upper[ns] - px.lower[ns]) * k / (n - 1));
  }
  std::uint8_t fractions = 0;
  for (std::size_t s = 0; s < ns; ++s)
    if (px.est[s]) fractions |= static_cast<std::uint8_t>(1u << s);
  const std::size_t nr = NumRows(px);
  auto eval = [&](const double* th, double* r, double* jac) {
    double con[kMaxChannels];
    t.Contrast(th, th[ns], th[ns + 1], px.phi, con, jac);
    px.FoldJacobian(jac, nc);
    for (std::size_t c = 0; c < nc; ++c) {
      r[c] = (con[c] - px.y[c]) / px.noise[c];
      for (std::size_t p = 0; p < np; ++p) jac[c * np + p] /= px.noise[c];
    }
    PriorRows(px, th, r, jac);
    return std::all_of(r, r + nr, [](double v) { return std::isfinite(v); });
  };
  std::vector<GuessCandidate>& all = *out;
  all.clear();
  for (double tc : cands) {
    GuessCandidate k;
    for (std::size_t p = 0; p < np; ++p) k.th[p] = px.nominal[p];
    ThinGuess(px, tc, k.th);
    double r[kMaxRows], jac[kMaxRows * kMaxParams];
    if (!eval(k.th, r, jac)) continue;
    k.cost = 0;
    for (std::size_t i = 0; i < nr; ++i) k.cost += r[i] * r[i];
    // The thin limit underestimates optically thick columns: with several
    // candidates (a coarse profile of chi2 over T_peak) refine the fractions
    // of each by a few iterations with the temperature held.
    if (cands.size() > 1 && fractions && options_.guess_iterations > 0) {
      GuessCandidate refined = k;
      LmSettings set;
      set.estimate = fractions;
      set.max_iterations = options_.guess_iterations;
      set.tolerance = set.stop = options_.tolerance_chi2;
      std::uint8_t held = 0;
      int it = 0;
      BoundedLm(px, set, nr, eval, refined.th, &held, r, jac, &refined.cost, &it);
      if (refined.cost < k.cost) k = refined;
    }
    all.push_back(k);
  }
  std::sort(all.begin(), all.end(),
            [](const GuessCandidate& a, const GuessCandidate& b) { return a.cost < b.cost; });
}

void Inverter::ProfileGuess(const Pixel& px, std::vector<GuessCandidate>* out, int* iterations,
                            Workspace* ws) const {
  const std::size_t nc = px.nc, ns = px.ns, np = px.np, m = slices_.size();
  const SceneTable& t = *table_;
  std::uint8_t fractions = 0;
  for (std::size_t s = 0; s < ns; ++s)
    if (px.est[s]) fractions |= static_cast<std::uint8_t>(1u << s);
  const std::size_t nr = NumRows(px);
  const double sigma = px.nominal[ns + 1];
  const SceneTable::Slice* slice = nullptr;
  auto eval = [&](const double* th, double* r, double* jac) {
    double con[kMaxChannels], d_dx[kMaxChannels * kMaxParams];
    t.SliceContrast(*slice, th, sigma, px.phi, con, d_dx);
    for (std::size_t c = 0; c < nc; ++c) {
      r[c] = (con[c] - px.y[c]) / px.noise[c];
      double* row = jac + c * np;
      for (std::size_t s = 0; s < ns; ++s) row[s] = d_dx[c * ns + s] / px.noise[c];
      row[ns] = row[ns + 1] = 0.0;
    }
    px.FoldJacobian(jac, nc);
    PriorRows(px, th, r, jac);
    return std::all_of(r, r + nr, [](double v) { return std::isfinite(v); });
  };
  ws->profile_cost.resize(m);
  ws->profile_theta.resize(m);
  double th[kMaxParams];
  for (std::size_t p = 0; p < np; ++p) th[p] = px.nominal[p];
  // From the hottest temperature down: there the optically thin guess is
  // close, and continuing from it towards colder (thicker) solutions follows
  // the branch on which the contrast grows with the column. (Starting cold
  // would follow the self-absorbed branch beyond the contrast's maximum,
  // where the plume's cooler edges hide its hot core.)
  ThinGuess(px, slices_[m - 1].peak_temperature_K, th);
  LmSettings set;
  set.estimate = fractions;
  set.max_iterations = 20;
  // A profile locates minima; the full solve polishes them. Its costs must
  // be accurate well below the tolerance: on flat profiles (a weakly
  // determined temperature) their errors would make spurious local minima.
  set.tolerance = set.stop = std::max(0.3 * options_.tolerance_chi2, 3e-3);
  std::uint8_t held = 0;
  double r[kMaxRows], jac[kMaxRows * kMaxParams];
  for (std::size_t jj = 0; jj < m; ++jj) {
    // Continuation: the fractions of the neighbouring temperature.
    const std::size_t j = m - 1 - jj;
    slice = &slices_[j];
    th[ns] = slice->peak_temperature_K;
    // ... extrapolated (in log) along the last two temperatures, where the
    // fraction is off its bounds at both.
    if (jj >= 2) {
      const auto& p1 = ws->profile_theta[j + 1];
      const auto& p2 = ws->profile_theta[j + 2];
      const double w = (th[ns] - p1[ns]) / (p1[ns] - p2[ns]);
      for (std::size_t s = 0; s < ns; ++s) {
        if (!px.est[s] || (held >> s & 1)) continue;
        if (!(p1[s] > px.lower[s] && p2[s] > px.lower[s] && p1[s] < px.upper[s] && p2[s] < px.upper[s]))
          continue;
        const double l1 = std::log(p1[s] + kLogEps), l2 = std::log(p2[s] + kLogEps);
        const double dl = std::min(std::max(w * (l1 - l2), -1.0), 1.0);
        th[s] = std::min(std::max(std::exp(l1 + dl) - kLogEps, px.lower[s]), px.upper[s]);
      }
    }
    px.ApplyTies(th);
    double cost = std::numeric_limits<double>::infinity();
    if (fractions) {
      BoundedLm(px, set, nr, eval, th, &held, r, jac, &cost, iterations);
    } else if (eval(th, r, jac)) {
      cost = 0;
      for (std::size_t i = 0; i < nr; ++i) cost += r[i] * r[i];
    }
    ws->profile_cost[j] = std::isfinite(cost) ? cost : std::numeric_limits<double>::max();
    std::copy(th, th + np, ws->profile_theta[j].begin());
  }
  // Local minima, each refined by the parabola through it and its neighbours.
  const std::vector<double>& f = ws->profile_cost;
  std::vector<GuessCandidate>& all = *out;
  all.clear();
  ws->profile_predicted.clear();
  for (std::size_t j = 0; j < m; ++j) {
    if (j > 0 && f[j] > f[j - 1]) continue;
    if (j + 1 < m && f[j] >= f[j + 1]) continue;
    GuessCandidate k;
    std::copy(ws->profile_theta[j].begin(), ws->profile_theta[j].end(), k.th);
    k.cost = f[j];
    double predicted = f[j];  // the parabola's minimum (a poor guess on steep profiles: only a filter)
    if (j > 0 && j + 1 < m) {
      const double a = slices_[j - 1].peak_temperature_K, b = slices_[j].peak_temperature_K,
                   c = slices_[j + 1].peak_temperature_K;
      const double fa = f[j - 1], fb = f[j], fc = f[j + 1];
      const double num = (b - a) * (b - a) * (fb - fc) - (b - c) * (b - c) * (fb - fa);
      const double den = (b - a) * (fb - fc) - (b - c) * (fb - fa);
      if (den < 0) {  // convex
        const double tm = std::min(std::max(b - 0.5 * num / den, a), c);
        // The parabola's value at tm (Lagrange form).
        const double pm = fa * (tm - b) * (tm - c) / ((a - b) * (a - c)) +
                          fb * (tm - a) * (tm - c) / ((b - a) * (b - c)) +
                          fc * (tm - a) * (tm - b) / ((c - a) * (c - b));
        predicted = std::max(std::min(fb, pm), 0.0);
        // Half the parabola's second derivative: the profile's curvature for
        // ProfileLm, unless a fraction reaches a bound between the nodes
        // (which kinks the profile).
        auto on_bound = [&](std::size_t node) {
          unsigned mask = 0;
          for (std::size_t s = 0; s < ns; ++s) {
            const double v = ws->profile_theta[node][s];
            if (px.est[s] && (v <= px.lower[s] || v >= px.upper[s])) mask |= 1u << s;
          }
          return mask;
        };
        if (on_bound(j - 1) == on_bound(j) && on_bound(j) == on_bound(j + 1))
          k.curvature = fa / ((a - b) * (a - c)) + fb / ((b - a) * (b - c)) + fc / ((c - a) * (c - b));
        // Fractions interpolated (in log) towards the neighbour on tm's side.
        const std::size_t o = tm < b ? j - 1 : j + 1;
        const double w = (tm - b) / (slices_[o].peak_temperature_K - b);
        for (std::size_t s = 0; s < ns; ++s) {
          if (!px.est[s]) continue;
          const double l0 = std::log(k.th[s] + kLogEps), l1 = std::log(ws->profile_theta[o][s] + kLogEps);
          k.th[s] = std::min(std::max(std::exp(l0 + w * (l1 - l0)) - kLogEps, px.lower[s]), px.upper[s]);
        }
        k.th[ns] = tm;
        px.ApplyTies(k.th);
      }
    }
    all.push_back(k);
    ws->profile_predicted.push_back(predicted);
  }
  // The nodes beside the best minimum start solves too: a second minimum
  // closer than the node spacing (a well-determined temperature) shows no
  // local minimum of its own on the nodes.
  std::size_t jb = 0;
  for (std::size_t j = 1; j < m; ++j)
    if (f[j] < f[jb]) jb = j;
  double best_curvature = 0;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (all[i].cost == f[jb]) best_curvature = all[i].curvature;
  for (std::size_t j : {jb - 1, jb + 1}) {
    if (jb == 0 && j == jb - 1) continue;
    if (j >= m) continue;
    GuessCandidate k;
    std::copy(ws->profile_theta[j].begin(), ws->profile_theta[j].end(), k.th);
    k.cost = f[j];
    k.curvature = best_curvature;
    all.push_back(k);
    ws->profile_predicted.push_back(f[jb]);
  }
  // Best node first; minima that cannot come within 25 of it carry no
  // likelihood weight (exp(-12.5)) and are dropped; at most 4 are polished.
  const double best = *std::min_element(f.begin(), f.end());
  std::size_t keep = 0;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (ws->profile_predicted[i] <= best + 25.0) all[keep++] = all[i];
  all.resize(keep);
  std::sort(all.begin(), all.end(),
            [](const GuessCandidate& a, const GuessCandidate& b) { return a.cost < b.cost; });
  if (all.size() > 6) all.resize(6);
}

void Inverter::SolveTable(Pixel* px, const double* start, Workspace* ws, bool precise,
                          double curvature) const {
  const std::size_t nc = px->nc, ns = px->ns, np = px->np;
  const SceneTable& t = *table_;
  double theta[kMaxParams];
  LmSettings set;
  for (std::size_t p = 0; p < np; ++p) {
    theta[p] = px->est[p] ? std::min(std::max(start[p], px->lower[p]), px->upper[p]) : px->nominal[p];
    if (px->est[p]) set.estimate |= static_cast<std::uint8_t>(1u << p);
  }
  px->ApplyTies(theta);
  set.max_iterations = options_.max_iterations;
  set.tolerance = options_.tolerance_chi2;
  // Precise: iterate on to 1e-10 of the tolerance, so that solutions from
  // different starts (cold, warm) agree to many digits (with T_peak
  // estimated, ProfileLm gets there in a few steps; joint steps in the
  // curved column-temperature valley would take dozens). Otherwise stop
  // once below the tolerance (or as soon as Gauss-Newton steps slow down or
  // fail).
  set.stop = 1e-10 * options_.tolerance_chi2;
  set.stop_when_slow = !precise;
  const std::size_t nr = NumRows(*px);
  const Pixel& cpx = *px;
  auto eval = [&](const double* th, double* r, double* jac) {
    double con[kMaxChannels];
    // The T_peak terms are reused while T_peak stays (ProfileLm's inner solves).
    if (ws->peak.peak_temperature_K != th[ns]) t.MakePeakTerms(th[ns], &ws->peak);
    t.Contrast(th, ws->peak, th[ns + 1], cpx.phi, con, jac);
    if (jac) cpx.FoldJacobian(jac, nc);
    for (std::size_t c = 0; c < nc; ++c) {
      r[c] = (con[c] - cpx.y[c]) / cpx.noise[c];
      if (jac)
        for (std::size_t p = 0; p < np; ++p) jac[c * np + p] /= cpx.noise[c];
    }
    PriorRows(cpx, th, r, jac);
    return std::all_of(r, r + nr, [](double v) { return std::isfinite(v); }) &&
           (!jac || std::all_of(jac, jac + nr * np, [](double v) { return std::isfinite(v); }));
  };
  std::uint8_t held = 0;
  double r[kMaxRows], jac[kMaxRows * kMaxParams], cost = 0;
  int iters = 0;
  const bool ok = px->est[ns] ? ProfileLm(*px, set, nr, eval, theta, &held, r, jac, &cost, &iters,
                                          &curvature)
                              : BoundedLm(*px, set, nr, eval, theta, &held, r, jac, &cost, &iters);
  px->curvature = curvature;
  for (std::size_t p = 0; p < np; ++p) px->theta[p] = theta[p];
  px->iterations += iters;
  px->bound_mask = held;
  if (!ok) {
    px->status = PixelStatus::kFailed;
    return;
  }
  px->status = held ? PixelStatus::kAtBound : PixelStatus::kConverged;
  double con[kMaxChannels];
  for (std::size_t c = 0; c < nc; ++c) {
    con[c] = r[c] * px->noise[c] + px->y[c];
    for (std::size_t p = 0; p < np; ++p) jac[c * np + p] *= px->noise[c];
  }
  FinishWith(px, con, jac, ws);
}


void Inverter::Columns(Pixel* px, Workspace* ws) const {
  const std::size_t ns = px->ns, np = px->np;
  const double tp = px->theta[ns], sg = px->theta[ns + 1];
  ws->Integral(tp, t_amb_);
  const double i = ws->int_i, di = ws->int_di;
  const double t_min = std::min(t_amb_, px->lower[ns]);
  for (std::size_t s = 0; s < ns; ++s) {
    const double k = column_factor_[s], x = px->theta[s];
    px->col[s] = k * x * sg * i;
    px->ppm[s] = 1e6 * kSqrt2Pi * x * sg;
    // Gradients over (x_s, T_peak, sigma).
    const int idx[3] = {static_cast<int>(s), static_cast<int>(ns), static_cast<int>(ns + 1)};
    const double gc[3] = {k * sg * i, k * x * sg * di, k * x * i};
    const double gp[3] = {1e6 * kSqrt2Pi * sg, 0.0, 1e6 * kSqrt2Pi * x};
    double vc = 0, vp = 0;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        const double cv = px->cov[idx[a] * np + idx[b]];
        vc += gc[a] * cv * gc[b];
        vp += gp[a] * cv * gp[b];
      }
    const double cap_c = k * px->upper[s] * px->upper[ns + 1] * kSqrt2Pi / t_min;
    const double cap_p = 1e6 * kSqrt2Pi * px->upper[s] * px->upper[ns + 1];
    px->col_sig[s] = std::min(std::sqrt(std::max(vc, 0.0)), cap_c);
    px->ppm_sig[s] = std::min(std::sqrt(std::max(vp, 0.0)), cap_p);
  }
}

void Inverter::FinishWith(Pixel* px, const double* con, const double* jac_in, Workspace* ws) const {
  const std::size_t nc = px->nc, np = px->np, ns = px->ns;
  px->prior_chi2 = 0;
  for (std::size_t p = 0; p < np; ++p)
    if (px->est[p] && px->prior_sigma[p] > 0) {
      const double r = (px->theta[p] - px->nominal[p]) / px->prior_sigma[p];
      px->prior_chi2 += r * r;
    }
  double jac[kMaxChannels * kMaxParams];
  std::copy(jac_in, jac_in + nc * np, jac);
  px->FoldJacobian(jac, nc);
  px->chi2 = 0;
  for (std::size_t c = 0; c < nc; ++c) {
    const double r = (con[c] - px->y[c]) / px->noise[c];
    px->chi2 += r * r;
  }
  int est[kMaxParams];
  int ne = 0, npr = 0;
  for (std::size_t p = 0; p < np; ++p)
    if (px->est[p]) {
      est[ne++] = static_cast<int>(p);
      if (px->prior_sigma[p] > 0) ++npr;
    }
  std::fill(px->cov, px->cov + np * np, 0.0);
  std::fill(px->psig, px->psig + np, 0.0);
  if (ne > 0) {
    const int nr = static_cast<int>(nc) + npr;
    // Fixed largest sizes: no heap allocations per pixel.
    using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, kMaxRows, kMaxParams>;
    using Square = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, kMaxParams, kMaxParams>;
    using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxParams, 1>;
    Matrix j = Matrix::Zero(nr, ne);
    int row = static_cast<int>(nc);
    for (int e = 0; e < ne; ++e) {
      const int p = est[e];
      for (std::size_t c = 0; c < nc; ++c) j(c, e) = jac[c * np + p] / px->noise[c];
      if (px->prior_sigma[p] > 0) j(row++, e) = 1.0 / px->prior_sigma[p];
    }
    Vector d(ne);
    for (int e = 0; e < ne; ++e) {
      d[e] = j.col(e).norm();
      if (!(d[e] > 0) || !std::isfinite(d[e])) d[e] = 1.0;
      j.col(e) /= d[e];
    }
    Eigen::JacobiSVD<Matrix> svd(j, Eigen::ComputeThinV);
    const Vector sv = svd.singularValues();
    const double smax = sv.size() ? sv[0] : 0.0;
    const double smin = (sv.size() == ne) ? sv[ne - 1] : 0.0;
    px->cond = (smin > 0 && smax / smin < kConditionCap) ? smax / smin : kConditionCap;
    const double floor = std::max(smax, 1e-300) * 1e-8;
    Vector inv2 = Vector::Zero(ne);
    for (int k = 0; k < ne; ++k) {
      const double s = k < sv.size() ? std::max(sv[k], floor) : floor;
      inv2[k] = 1.0 / (s * s);
    }
    const Square& v = svd.matrixV();
    const Square covn = v * inv2.asDiagonal() * v.transpose();
    px->log_det = 0;
    for (int k = 0; k < ne; ++k) px->log_det += std::log(inv2[k]) - 2.0 * std::log(d[k]);
    for (int a = 0; a < ne; ++a)
      for (int b = 0; b < ne; ++b)
        px->cov[est[a] * np + est[b]] = covn(a, b) / (d[a] * d[b]);
    for (int a = 0; a < ne; ++a) {
      const int p = est[a];
      px->psig[p] = std::min(std::sqrt(std::max(px->cov[p * np + p], 0.0)), px->upper[p] - px->lower[p]);
    }
    // Tied fractions: x_s = ratio x_ref.
    for (std::size_t s = 0; s < ns; ++s) {
      const int r = px->tie_ref[s];
      if (r < 0) continue;
      const double k = px->tie_ratio[s];
      for (std::size_t q = 0; q < np; ++q) px->cov[s * np + q] = k * px->cov[r * np + q];
      for (std::size_t q = 0; q < np; ++q) px->cov[q * np + s] = k * px->cov[q * np + r];
      px->psig[s] = k * px->psig[r];
    }
  } else {
    px->cond = 1.0;
  }
  Columns(px, ws);
}

void Inverter::FillFailed(Pixel* px) const {
  const std::size_t ns = px->ns, np = px->np;
  px->status = PixelStatus::kFailed;
  for (std::size_t p = 0; p < np; ++p) {
    px->theta[p] = (p >= ns && std::isfinite(px->nominal[p])) ? px->nominal[p] : 0.0;
    px->psig[p] = 0;
  }
  std::fill(px->cov, px->cov + np * np, 0.0);
  for (std::size_t s = 0; s < ns; ++s) px->col[s] = px->col_sig[s] = px->ppm[s] = px->ppm_sig[s] = 0;
  px->chi2 = 0;
  px->cond = 0;
  px->bound_mask = 0;
}

void Inverter::FillBelowDetection(Pixel* px, Workspace* ws) const {
  const std::size_t nc = px->nc, ns = px->ns, np = px->np;
  px->status = PixelStatus::kBelowDetection;
  for (std::size_t p = 0; p < np; ++p) px->theta[p] = (p < ns && px->est[p]) ? 0.0 : px->nominal[p];
  px->ApplyTies(px->theta);
  std::fill(px->cov, px->cov + np * np, 0.0);
  std::fill(px->psig, px->psig + np, 0.0);
  px->chi2 = 0;
  for (std::size_t c = 0; c < nc; ++c) px->chi2 += (px->y[c] / px->noise[c]) * (px->y[c] / px->noise[c]);
  px->cond = 0;
  px->bound_mask = 0;
  Columns(px, ws);
  // Noise-equivalent column (1 sigma) of each estimated species in the thin
  // limit: the column whose contrast equals the noise, combined over
  // channels (tied species contribute to their reference's signal).
  const double tp = px->theta[ns], sg = px->theta[ns + 1];
  double thin[kMaxChannels * kMaxParams];  // [c * ns + s] d(Delta L)/du_s
  if (use_table_) {
    for (std::size_t c = 0; c < nc; ++c)
      for (std::size_t s = 0; s < ns; ++s) thin[c * ns + s] = table_->ThinSlope(c, s, tp, px->phi);
  } else {
    double th[kMaxParams], con[kMaxChannels], jac[kMaxChannels * kMaxParams];
    for (std::size_t p = 0; p < np; ++p) th[p] = px->theta[p];
    for (std::size_t s = 0; s < ns; ++s)
      if (px->est[s] || px->tie_ref[s] >= 0) th[s] = 1e-9;
    FullModelContrast(*model_, t_amb_, th, px->tbg, con, jac);
    for (std::size_t c = 0; c < nc; ++c)
      for (std::size_t s = 0; s < ns; ++s) thin[c * ns + s] = jac[c * np + s] / sg;
  }
  ws->Integral(tp, t_amb_);
  const double t_min = std::min(t_amb_, px->lower[ns]);
  for (std::size_t s = 0; s < ns; ++s) {
    if (!px->est[s]) continue;
    const double k = column_factor_[s];
    double sc = 0, sp = 0;
    for (std::size_t c = 0; c < nc; ++c) {
      double g = thin[c * ns + s];
      for (std::size_t s2 = 0; s2 < ns; ++s2)
        if (px->tie_ref[s2] == static_cast<int>(s)) g += px->tie_ratio[s2] * thin[c * ns + s2];
      const double dc = g / (k * ws->int_i) / px->noise[c];
      const double dp = g / (1e6 * kSqrt2Pi) / px->noise[c];
      sc += dc * dc;
      sp += dp * dp;
    }
    const double cap_c = k * px->upper[s] * px->upper[ns + 1] * kSqrt2Pi / t_min;
    const double cap_p = 1e6 * kSqrt2Pi * px->upper[s] * px->upper[ns + 1];
    px->col_sig[s] = sc > 0 ? std::min(1.0 / std::sqrt(sc), cap_c) : cap_c;
    px->ppm_sig[s] = sp > 0 ? std::min(1.0 / std::sqrt(sp), cap_p) : cap_p;
    for (std::size_t s2 = 0; s2 < ns; ++s2)
      if (px->tie_ref[s2] == static_cast<int>(s)) {
        px->col_sig[s2] = px->tie_ratio[s2] * column_factor_[s2] / k * px->col_sig[s];
        px->ppm_sig[s2] = px->tie_ratio[s2] * px->ppm_sig[s];
      }
  }
}

void Inverter::SolveNewton(Pixel* px, Workspace* ws) const {
  const std::size_t ns = px->ns, np = px->np, s = newton_param_, c = 0;
  const SceneTable& t = *table_;
  const double tp = px->nominal[ns], sg = px->nominal[ns + 1];
  const int r1 = t.basis_rank(c, s) + 1;
  const int nu = t.num_u_nodes();
  const double lu0 = t.min_log_u(), h = t.log_u_step(), u_min = std::exp(lu0);
  if (ws->curve_channel != c || ws->curve_species != s || ws->curve_t != tp ||
      ws->curve_sigma != sg) {
    ws->curve_nodes.assign(static_cast<std::size_t>(nu) * r1, 0.0);
    ws->curve_u.resize(nu);
    for (int i = 0; i < nu; ++i) {
      const double lu = lu0 + i * h;
      ws->curve_u[i] = std::exp(lu);
      t.RawValues(c, s, lu, std::exp(lu) / sg, tp, &ws->curve_nodes[static_cast<std::size_t>(i) * r1]);
    }
    ws->curve = UniformSpline(lu0, h, nu, r1, ws->curve_nodes, Extrapolation::kHold,
                              Extrapolation::kLinear);
    ws->curve_channel = c;
    ws->curve_species = s;
    ws->curve_t = tp;
    ws->curve_sigma = sg;
    ws->curve_r1 = r1;
  }
  const double* phi = px->phi + t.phi_offset(c, s);
  auto contract = [&](const double* raw) {
    double g = raw[0];
    for (int r = 1; r < r1; ++r) g -= phi[r - 1] * raw[r];
    return g;
  };
  const double g0 = contract(&ws->curve_nodes[0]);
  double raw[64], slope[64];
  // F(u) = u g(ln u) and dF/du, from u (or, when known, ln u).
  auto eval_lu = [&](double u, double lu, double* f, double* df) {
    if (!(u > u_min)) {
      *f = u * g0;
      *df = g0;
      return;
    }
    ws->curve.Evaluate(lu, raw, slope);
    const double g = contract(raw);
    *f = u * g;
    *df = g + contract(slope);  // d(u g)/du = g + dg/d(ln u)
  };
  auto eval = [&](double u, double* f, double* df) {
    eval_lu(u, u > u_min ? std::log(u) : 0.0, f, df);
  };
  // Other species (fixed) add a constant.
  double offset = 0;
  for (std::size_t s2 = 0; s2 < ns; ++s2) {
    if (s2 == s || !(px->nominal[s2] > 0)) continue;
    double v, a, b, d;
    t.SpeciesContrast(c, s2, px->nominal[s2] * sg, px->nominal[s2], tp, px->phi, &v, &a, &b, &d);
    offset += v;
  }
  const double target = px->y[c] - offset;
  const double u_lo = px->lower[s] * sg, u_hi = px->upper[s] * sg;
  int iters = 0;
  // Scan for the first bracket of F(u) - target from u_lo upwards.
  double fa, dfa;
  eval(u_lo, &fa, &dfa);
  fa -= target;
  double a = u_lo, b = u_lo, fb = fa;
  bool bracket = fa == 0;
  double root = u_lo;
  if (!bracket) {
    auto try_point = [&](double u, double f) {
      if (bracket) return;
      if ((f - target > 0) != (fa > 0) || f == target) {
        b = u;
        fb = f - target;
        bracket = true;
      } else {
        a = u;
        fa = f - target;
      }
    };
    if (u_min > u_lo && u_min < u_hi) try_point(u_min, u_min * g0);
    for (int i = 0; i < nu && !bracket; ++i) {
      const double u = ws->curve_u[i];
      if (u <= std::max(u_lo, u_min) || u >= u_hi) continue;
      try_point(u, u * contract(&ws->curve_nodes[static_cast<std::size_t>(i) * r1]));
    }
    if (!bracket) {
      double f, d;
      eval(u_hi, &f, &d);
      try_point(u_hi, f);
    }
  }
  bool at_bound = false;
  if (bracket && fa == 0) {
    root = a;
  } else if (bracket && fb == 0) {
    root = b;
  } else if (bracket && b <= u_min) {
    root = g0 != 0 ? target / g0 : a;  // optically thin: linear
    root = std::min(std::max(root, a), b);
  } else if (bracket) {
    // Safeguarded Newton in ln u inside [a, b].
    double la = std::log(std::max(a, u_min)), lb = std::log(b);
    double lu = la + (lb - la) * fa / (fa - fb);
    for (iters = 1; iters <= 60; ++iters) {
      double f, df;
      const double u = std::exp(lu);
      eval_lu(u, lu, &f, &df);
      f -= target;
      if ((f > 0) == (fa > 0)) la = lu; else lb = lu;
      const double dfl = u * df;
      double next = dfl != 0 ? lu - f / dfl : 0.5 * (la + lb);
      if (!(next > la && next < lb)) next = 0.5 * (la + lb);
      const double step = std::abs(next - lu);
      lu = next;
      if (step < 1e-12 || std::abs(f) < 1e-12 * px->noise[c]) break;
    }
    root = std::exp(lu);
  } else {
    // No solution inside the bounds: the nearer bound.
    double fl, fh, d;
    eval(u_lo, &fl, &d);
    eval(u_hi, &fh, &d);
    root = std::abs(fl - target) <= std::abs(fh - target) ? u_lo : u_hi;
    at_bound = true;
  }
  double f, df;
  eval(root, &f, &df);
  for (std::size_t p = 0; p < np; ++p) px->theta[p] = px->nominal[p];
  px->theta[s] = root / sg;
  std::fill(px->cov, px->cov + np * np, 0.0);
  std::fill(px->psig, px->psig + np, 0.0);
  const double su = df != 0 ? std::min(px->noise[c] / std::abs(df), u_hi - u_lo) : u_hi - u_lo;
  px->psig[s] = su / sg;
  px->cov[s * np + s] = px->psig[s] * px->psig[s];
  px->chi2 = ((f - target) / px->noise[c]) * ((f - target) / px->noise[c]);
  px->cond = 1.0;
  px->iterations = iters;
  px->bound_mask = at_bound ? static_cast<std::uint8_t>(1u << s) : 0;
  px->status = at_bound ? PixelStatus::kAtBound : PixelStatus::kConverged;
  Columns(px, ws);
}

void Inverter::FullModelGuess(const Pixel& px, double* theta) const {
  const std::size_t nc = px.nc, ns = px.ns, np = px.np;
  double th[kMaxParams], con[kMaxChannels], jac[kMaxChannels * kMaxParams];
  for (std::size_t p = 0; p < np; ++p) th[p] = px.nominal[p];
  std::vector<int> free_s;
  for (std::size_t s = 0; s < ns; ++s)
    if (px.est[s]) {
      free_s.push_back(static_cast<int>(s));
      th[s] = 1e-9;
    }
  px.ApplyTies(th);
  FullModelContrast(*model_, t_amb_, th, px.tbg, con, jac);
  px.FoldJacobian(jac, nc);
  for (std::size_t p = 0; p < np; ++p) theta[p] = px.nominal[p];
  if (free_s.empty()) return;
  Eigen::MatrixXd a(nc, free_s.size());
  Eigen::VectorXd b(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    b[c] = (px.y[c] - con[c]) / px.noise[c];
    for (std::size_t k = 0; k < free_s.size(); ++k) a(c, k) = jac[c * np + free_s[k]] / px.noise[c];
  }
  Eigen::VectorXd u;
  SmallNnls(a, b, &u);
  for (std::size_t k = 0; k < free_s.size(); ++k) {
    const int s = free_s[k];
    theta[s] = std::min(std::max(u[k] + 1e-9, std::max(px.lower[s], 1e-7)), px.upper[s]);
  }
  px.ApplyTies(theta);
}

void Inverter::SolveFull(Pixel* px, const double* start, Workspace* ws) const {
  const std::size_t ns = px->ns, np = px->np;
  double theta[kMaxParams];
  if (start) {
    for (std::size_t p = 0; p < np; ++p) theta[p] = start[p];
  } else {
    FullModelGuess(*px, theta);
  }
  for (std::size_t p = 0; p < np; ++p) {
    if (!px->est[p]) {
      theta[p] = px->nominal[p];
      continue;
    }
    // Strictly inside: a fraction at exactly 0 has no derivative in the full model.
    const double lo = p < ns ? std::max(px->lower[p], std::min(1e-7, 0.5 * px->upper[p])) : px->lower[p];
    theta[p] = std::min(std::max(theta[p], lo), px->upper[p]);
  }
  FullModelProblem fp;
  fp.model = model_.get();
  fp.ambient_temperature_K = t_amb_;
  fp.num_channels = px->nc;
  fp.num_species = ns;
  fp.measured_contrast = px->y;
  fp.noise = px->noise;
  fp.background_temperature_K = px->tbg;
  fp.estimated = px->est;
  fp.lower = px->lower;
  fp.upper = px->upper;
  fp.prior_mean = px->nominal;
  fp.prior_sigma = px->prior_sigma;
  fp.tie_ref = px->tie_ref;
  fp.tie_ratio = px->tie_ratio;
  fp.max_iterations = options_.max_iterations;
  int it = 0;
  const bool ok = SolveFullModel(fp, theta, &it);
  px->iterations += it;
  px->ApplyTies(theta);
  for (std::size_t p = 0; p < np; ++p) px->theta[p] = theta[p];
  if (!ok || !std::all_of(theta, theta + np, [](double v) { return std::isfinite(v); })) {
    px->status = PixelStatus::kFailed;
    return;
  }
  px->bound_mask = 0;
  for (std::size_t p = 0; p < np; ++p) {
    if (!px->est[p]) continue;
    const double tol = 1e-9 * std::max(1.0, std::abs(px->upper[p] - px->lower[p]));
    if (theta[p] <= px->lower[p] + tol || theta[p] >= px->upper[p] - tol)
      px->bound_mask |= static_cast<std::uint8_t>(1u << p);
  }
  px->status = px->bound_mask ? PixelStatus::kAtBound : PixelStatus::kConverged;
  double con[kMaxChannels], jac[kMaxChannels * kMaxParams];
  FullModelContrast(*model_, t_amb_, px->theta, px->tbg, con, jac);
  FinishWith(px, con, jac, ws);
}

bool Inverter::Distinct(const Pixel& a, const Pixel& b) {
  for (std::size_t p = 0; p < a.np; ++p) {
    if (!a.est[p]) continue;
    const double s = std::sqrt(a.psig[p] * a.psig[p] + b.psig[p] * b.psig[p]);
    if (std::abs(a.theta[p] - b.theta[p]) > 0.5 * s) return true;
  }
  return false;
}

void Inverter::MergeModes(Pixel* a, const Pixel& b) const {
  const std::size_t ns = a->ns, np = a->np;
  if (!Distinct(*a, b)) return;  // the same minimum reached twice
  const double da = a->chi2 + a->prior_chi2, db = b.chi2 + b.prior_chi2;
  if (db - da < 4.0) a->flags |= kFlagAmbiguous;
  // The two minima weighted by their likelihoods exp(-chi2 / 2).
  const double lw = -0.5 * (db - da);
  if (lw < -40) return;
  const double wb = 1.0 / (1.0 + std::exp(-lw)), wa = 1.0 - wb;
  auto spread = [&](double sa, double sb, double va, double vb) {
    return std::sqrt(wa * sa * sa + wb * (sb * sb + (vb - va) * (vb - va)));
  };
  double d[kMaxParams];
  for (std::size_t p = 0; p < np; ++p) d[p] = b.theta[p] - a->theta[p];
  for (std::size_t i = 0; i < np; ++i)
    for (std::size_t j = 0; j < np; ++j)
      a->cov[i * np + j] = wa * a->cov[i * np + j] + wb * (b.cov[i * np + j] + d[i] * d[j]);
  for (std::size_t p = 0; p < np; ++p)
    if (a->est[p] || (p < ns && a->tie_ref[p] >= 0))
      a->psig[p] = std::min(spread(a->psig[p], b.psig[p], a->theta[p], b.theta[p]),
                            std::max(a->upper[p] - a->lower[p], a->psig[p]));
  for (std::size_t s = 0; s < ns; ++s) {
    a->col_sig[s] = spread(a->col_sig[s], b.col_sig[s], a->col[s], b.col[s]);
    a->ppm_sig[s] = spread(a->ppm_sig[s], b.ppm_sig[s], a->ppm[s], b.ppm[s]);
  }
}

void Inverter::WritePixel(const Pixel& px, const InversionOutput& o, std::size_t idx) const {
  const std::size_t ns = px.ns, np = px.np;
  o.status[idx] = static_cast<std::uint8_t>(px.status);
  if (o.bound_mask) o.bound_mask[idx] = px.bound_mask;
  if (o.flags) o.flags[idx] = px.flags;
  if (o.parameters) std::copy(px.theta, px.theta + np, o.parameters + idx * np);
  if (o.parameter_sigma) std::copy(px.psig, px.psig + np, o.parameter_sigma + idx * np);
  if (o.covariance) std::copy(px.cov, px.cov + np * np, o.covariance + idx * np * np);
  if (o.column_density) std::copy(px.col, px.col + ns, o.column_density + idx * ns);
  if (o.column_density_sigma) std::copy(px.col_sig, px.col_sig + ns, o.column_density_sigma + idx * ns);
  if (o.path_concentration) std::copy(px.ppm, px.ppm + ns, o.path_concentration + idx * ns);
  if (o.path_concentration_sigma)
    std::copy(px.ppm_sig, px.ppm_sig + ns, o.path_concentration_sigma + idx * ns);
  if (o.chi2) o.chi2[idx] = px.chi2;
  if (o.condition_number) o.condition_number[idx] = px.cond;
  if (o.iterations) o.iterations[idx] = px.iterations;
}

void Inverter::InvertRow(const PixelBatch& b, const InversionOutput& out, std::size_t begin,
                         std::size_t end, Workspace* ws) const {
  const std::size_t nc = model_->num_channels(), np = model_->num_species() + 2;
  const std::size_t n = b.num_pixels;
  for (std::size_t f = 0; f < b.num_frames; ++f) {
    ws->last_ok = false;
    for (std::size_t i = begin; i < end; ++i) {
      const std::size_t idx = f * n + i;
      Pixel px;
      px.iterations = 0;
      std::fill(px.cov, px.cov + kMaxParams * kMaxParams, 0.0);
      std::fill(px.psig, px.psig + kMaxParams, 0.0);
      std::fill(px.col, px.col + kMaxParams, 0.0);
      std::fill(px.col_sig, px.col_sig + kMaxParams, 0.0);
      std::fill(px.ppm, px.ppm + kMaxParams, 0.0);
      std::fill(px.ppm_sig, px.ppm_sig + kMaxParams, 0.0);
      const bool ok = PreparePixel(b, f, i, &px);
      if (!ok) {
        FillFailed(&px);
        WritePixel(px, out, idx);
        ws->last_ok = false;
        continue;
      }
      if (use_table_) {
        table_->Background(px.tbg, ws->phi.data());
        px.phi = ws->phi.data();
      }
      bool below = true;
      for (std::size_t c = 0; c < nc; ++c)
        below = below && std::abs(px.y[c]) < options_.detection_sigma * px.noise[c];
      if (below) {
        FillBelowDetection(&px, ws);
        WritePixel(px, out, idx);
        ws->last_ok = false;
        continue;
      }
      double start[kMaxParams];
      bool warm = false;
      switch (options_.initial_guess) {
        case InitialGuess::kNeighbour:
          if (ws->last_ok && i > begin) {
            std::copy(ws->last_theta, ws->last_theta + np, start);
            warm = true;
          }
          break;
        case InitialGuess::kPrevious:
          if (f > 0 && out.parameters) {
            const std::size_t prev = (f - 1) * n + i;
            const auto st = static_cast<PixelStatus>(out.status[prev]);
            if (st == PixelStatus::kConverged || st == PixelStatus::kAtBound) {
              std::copy(out.parameters + prev * np, out.parameters + (prev + 1) * np, start);
              warm = true;
            }
          }
          break;
        case InitialGuess::kGiven:
          std::copy(b.initial + i * np, b.initial + (i + 1) * np, start);
          warm = std::all_of(start, start + np, [](double v) { return std::isfinite(v); });
          break;
        case InitialGuess::kTable: break;
      }
      if (newton_) {
        SolveNewton(&px, ws);
      } else if (use_table_) {
        const Pixel fresh = px;
        const bool profile = !slices_.empty() && px.est[model_->num_species()];
        auto cold = [&](Pixel* out) {
          // Full solves from the profile's minima (or the coarse lookup's
          // best candidates); the best fit is kept and a distinct second
          // minimum widens the uncertainty.
          int total = 0;
          std::size_t starts = 0;
          if (profile) {
            ProfileGuess(*out, &ws->guesses, &total, ws);
            starts = ws->guesses.size();
          } else {
            TableGuess(*out, &ws->guesses, ws);
            starts = options_.num_starts == 0
                         ? ws->guesses.size()
                         : std::min<std::size_t>(ws->guesses.size(),
                                                 static_cast<std::size_t>(options_.num_starts));
          }
          if (starts == 0) {
            out->status = PixelStatus::kFailed;
            out->iterations = total;
            return;
          }
          const Pixel base = *out;
          std::vector<Pixel>& sol = ws->solutions;
          sol.assign(starts, base);
          for (std::size_t k = 0; k < starts; ++k) {
            SolveTable(&sol[k], ws->guesses[k].th, ws, starts == 1, ws->guesses[k].curvature);
            total += sol[k].iterations;
          }
          std::size_t best = 0;
          for (std::size_t k = 1; k < starts; ++k)
            if (sol[k].solved() && (!sol[best].solved() || sol[k].chi2 + sol[k].prior_chi2 <
                                                           sol[best].chi2 + sol[best].prior_chi2))
              best = k;
          if (starts > 1 && sol[best].solved()) {
            // The best minimum converged to full precision, and so is any
            // distinct one within the tolerance of it (which of the two fits
            // best is decided only at full precision).
            const double best_cost = sol[best].chi2 + sol[best].prior_chi2;
            std::size_t chosen = best;
            for (std::size_t k = 0; k < starts; ++k) {
              if (!sol[k].solved()) continue;
              if (k != best && !(sol[k].chi2 + sol[k].prior_chi2 < best_cost + options_.tolerance_chi2 &&
                                 Distinct(sol[k], sol[best])))
                continue;
              Pixel precise = base;
              SolveTable(&precise, sol[k].theta, ws, true, sol[k].curvature);
              total += precise.iterations;
              if (!precise.solved()) continue;
              sol[k] = precise;  // (before the comparison: k may be the chosen one)
              if (precise.chi2 + precise.prior_chi2 < sol[chosen].chi2 + sol[chosen].prior_chi2)
                chosen = k;
            }
            best = chosen;
          }
          *out = sol[best];
          if (out->solved()) {
            // The best other minimum (distinct from the best one), if any.
            for (std::size_t k = 0; k < starts; ++k) {
              if (k == best || !sol[k].solved()) continue;
              MergeModes(out, sol[k]);
              if (out->flags & kFlagAmbiguous) break;
            }
          }
          out->iterations = total;
        };
        if (warm) {
          SolveTable(&px, start, ws, true, ws->last_curvature);
          // A warm start that fails, or whose fit is improbable (it may have
          // reached a local minimum), is retried cold.
          if (!px.solved() || px.chi2 + px.prior_chi2 > FitThreshold(px)) {
            Pixel alt = fresh;
            cold(&alt);
            alt.iterations += px.iterations;
            if (alt.solved() && (!px.solved() || alt.chi2 < px.chi2)) px = alt;
            else px.iterations = alt.iterations;
          }
        } else {
          cold(&px);
        }
      } else {
        SolveFull(&px, warm ? start : nullptr, ws);
      }
      if (px.status == PixelStatus::kFailed) {
        const int it = px.iterations;
        FillFailed(&px);
        px.iterations = it;
      }
      WritePixel(px, out, idx);
      ws->last_ok = px.solved();
      std::copy(px.theta, px.theta + np, ws->last_theta);
      ws->last_curvature = px.curvature;
    }
  }
}

void Inverter::Invert(const PixelBatch& b, const InversionOutput& out, const RunControl* control) const {
  Require(b.num_pixels > 0, "the batch has no pixels");
  Require(b.num_frames >= 1, "num_frames must be >= 1");
  Require(b.radiance != nullptr, "radiance is missing");
  Require((b.background_radiance != nullptr) != (b.background_temperature_K != nullptr),
          "give exactly one of background_radiance and background_temperature_K");
  Require(out.status != nullptr, "the status output is required");
  Require(options_.initial_guess != InitialGuess::kGiven || b.initial != nullptr,
          "initial_guess 'given' needs per-pixel start parameters (initial)");
  const std::size_t chunk = b.row_length > 0 ? b.row_length : 256;
  ParallelFor(
      b.num_pixels, chunk,
      [&](std::size_t lo, std::size_t hi) {
        Workspace ws;
        ws.phi.assign(use_table_ ? table_->background_size() : 0, 0.0);
        InvertRow(b, out, lo, hi, &ws);
      },
      options_.num_threads, control);
}

}  // namespace qogi
