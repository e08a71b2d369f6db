// The per-scene table: the fast forward model (BinnedModel) of Gaussian
// plumes, tabulated once per recording so that a pixel's contrast and its
// derivatives cost about a microsecond instead of a millisecond.
//
// For one scene the ambient temperature T_amb and the pressure are fixed. The
// background temperature T_bg varies per pixel and channel, but it enters the
// binned model exactly through Planck moments: the layer scheme is linear in
// the source term D = Bbar_q(T(s)) - Bbar_q(T_bg), so channel c's contrast is
//   Delta L_c = E_c - sum_m B(nu_m, T_bg) A_c,m,
//   E_c   = sum_q W_q march_q(D = Bbar_q(T(s)))      (gas emission),
//   A_c,m = sum_q W_q M_qm alpha_q,  alpha_q = march_q(D = 1)  (absorptance),
// with W_q the bin weights, M the Chebyshev Planck map of the binned model and
// nu_m its Chebyshev wavenumbers. When no bin holds two species (true for
// CH4 and CO2, whose bands are 500 cm-1 apart), each species contributes
// separately, and for a Gaussian plume its contribution depends on the peak
// volume fraction x and depth sigma only through u = x sigma (the column-like
// product) and, through self-broadening, x itself:
//   Delta L_c = sum_i u_i g_c,i(ln u_i, x_i, T_peak; T_bg).
// g = (E - sum_m b_m A_m) / u is tabulated per channel and species over
// (ln u, x, T_peak) from the binned model's own kernels (MeanPlanck,
// BinCrossSections and the march of march.h) and interpolated with tricubic
// not-a-knot B-splines, which give exact analytic derivatives of the
// interpolant. The table holds E relative to a background at T_peak,
//   Etilde = (E - sum_r phi_r(T_peak) A_r) / u,   A_r / u,
// so that g = Etilde + sum_r (phi_r(T_peak) - phi_r(T_bg)) A_r / u: the steep
// Planck dependence on T_peak is evaluated exactly (phi is analytic), and
// the splines follow only the smooth absorptance and the small excess
// emission of a non-isothermal plume. Below the table's smallest u (where the strongest bin's peak
// optical depth is `thin_optical_depth`) the optically thin limit holds: g is
// constant and the contrast linear in u (also for u <= 0, so a solver may
// step there smoothly). Beyond the grid in x and T_peak the spline continues
// linearly. The moments b_m = B(nu_m, T_bg) are compressed to an orthonormal
// basis of rank R (singular vectors of b(T) over the background range,
// truncated at `planck_tolerance`), whose coefficients phi_r(T_bg) are cubic
// splines in T_bg; each pixel computes them once.
//
// The error of the table against BinnedModel::Contrast is measured by
// MeasureTableError() (tested and printed by benchmarks/bench_inversion.py).
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "engine/camera/radiometric_table.h"
#include "engine/inversion/bspline.h"
#include "engine/rte/binned_model.h"
#include "engine/util/parallel.h"

namespace qogi {

struct SceneTableOptions {
  double ambient_temperature_K = 296.0;  // T_amb of the scene [K]; inside the model's tables
  double min_peak_temperature_K = 0.0;   // lowest T_peak tabulated [K]; 0 = the model's lowest
  double max_peak_temperature_K = 0.0;   // highest T_peak tabulated [K]; 0 = the model's highest
  double temperature_step_K = 5.0;       // T_peak grid step [K], within [1, 50]
  double max_sigma_m = 2.0;  // largest plume depth sigma served [m] (u = x sigma <= it)
  int nodes_per_decade = 8;  // grid density in u = x sigma [nodes per factor 10], 2-40
  int fraction_nodes = 4;  // self-broadening grid over x in [0, 1], 4-21
  double thin_optical_depth =
      1e-5;  // strongest bin's peak optical depth at the smallest u, 1e-8-1e-3
  double min_background_K = 150.0;  // background temperatures served [K], >= 50
  double max_background_K = 700.0;  // [K], <= 2000
  double planck_tolerance = 1e-8;  // relative truncation of the background Planck basis, 1e-14-1e-4
  // Line-of-sight nodes of the table's march (odd, >= 5; 0 = the model's own
  // num_nodes). Fewer nodes build faster; the difference is part of the
  // measured table error.
  int num_nodes = 0;
  // Bins whose largest possible contrasts (weight x mean Planck function at
  // the hottest temperature served), summed, stay below this fraction of the
  // channel's band radiance at ambient are left out (e.g. one species' far
  // lines in the tail of another species' filter). 0 keeps every bin.
  // Default 1e-6 (about 1e-4 of a 1 K contrast), within [0, 1e-3].
  double negligible_fraction = 1e-6;
  // A bin whose whole-path optical depth at a node's u stays below this is
  // not marched there but scaled from its optically thin slope: linear in u
  // to within half of it (relative), so the table's nodes differ from the
  // binned model by at most ~this / 2 of a contrast (measured 1.3e-5 at
  // 1e-4), for ~30 % less build time than 1e-7. Within [1e-9, 1e-3].
  double linear_optical_depth = 1e-4;
  int num_threads = 0;  // build threads; 0 = all cores
  void Check() const;
};

class SceneTable {
 public:
  // Builds the table from `model` (kept alive by the table). Throws
  // std::invalid_argument for bad options, or when two species absorb in the
  // same bin of some channel (see SpectralOverlaps: such models are inverted
  // with the full binned model instead). Honours control (cancel, progress).
  SceneTable(std::shared_ptr<const BinnedModel> model, SceneTableOptions options,
             const RunControl* control = nullptr);

  // Human-readable descriptions of every channel in which two species absorb
  // in the same bin; empty when the species are spectrally separate.
  static std::vector<std::string> SpectralOverlaps(const BinnedModel& model);

  const BinnedModel& model() const { return *model_; }
  std::shared_ptr<const BinnedModel> model_ptr() const { return model_; }
  const SceneTableOptions& options() const { return options_; }
  std::size_t num_channels() const { return nc_; }
  std::size_t num_species() const { return ns_; }
  double ambient_temperature_K() const { return options_.ambient_temperature_K; }
  double min_peak_temperature_K() const { return t_lo_; }
  double max_peak_temperature_K() const { return t_hi_; }
  // Smallest and largest tabulated u = x sigma [m].
  double min_column_proxy_m() const { return std::exp(lu_lo_); }
  double max_column_proxy_m() const { return std::exp(lu_hi_); }
  // Grid sizes (u, x, T_peak) and the Planck basis rank of table (c, s) (0 if
  // species s does not absorb in channel c).
  int num_u_nodes() const { return nu_; }
  int num_fraction_nodes() const { return nx_; }
  int num_temperature_nodes() const { return nt_; }
  int basis_rank(std::size_t channel, std::size_t species) const;
  bool has_table(std::size_t channel, std::size_t species) const {
    return index_[channel * ns_ + species] >= 0;
  }
  double build_seconds() const { return build_seconds_; }
  // Bins tabulated, and the bound on the left-out bins' contribution to any
  // channel's contrast [W/(m2 sr)] (largest over channels).
  std::size_t num_tabulated_bins() const;
  double negligible_bound() const { return negligible_bound_; }
  double memory_bytes() const;

  // Number of per-pixel background coefficients (size of `phi` below).
  std::size_t background_size() const { return phi_size_; }
  // Background coefficients of one pixel from each channel's background
  // temperature t_bg[c] [K] (inside [min_background_K, max_background_K]).
  void Background(const double* t_bg, double* phi) const;

  // Contrast Delta L_c [W/(m2 sr)] of every channel of a Gaussian plume with
  // peak fractions x[i], peak temperature T_peak [K] and depth sigma [m], and,
  // when jacobian is not null, its derivatives into
  //   jacobian[c * (n_species + 2) + p], p = (x_0 .. x_{S-1}, T_peak, sigma).
  void Contrast(const double* x, double peak_temperature_K, double sigma_m, const double* phi,
                double* contrast, double* jacobian) const;

  // What Contrast() computes from T_peak alone (its spline weights and every
  // table's phi_r(T_peak) with d/dT): a solver that varies the other
  // parameters at a fixed temperature computes them once.
  struct PeakTerms {
    double peak_temperature_K = -1;  // [K]; -1 = not made yet
    SplineWeights wt;
    std::vector<double> phi, dphi;  // per table [table * max rank + r]
  };
  void MakePeakTerms(double peak_temperature_K, PeakTerms* terms) const;
  // Contrast() at terms' temperature.
  void Contrast(const double* x, const PeakTerms& terms, double sigma_m, const double* phi,
                double* contrast, double* jacobian) const;

  // The table at one fixed peak temperature: every (channel, species)
  // table contracted over the T_peak axis, and phi_r(T_peak). It does not
  // depend on the pixel, so an inversion builds slices once (e.g. at the
  // table's temperature nodes) and evaluates them for every pixel at a third
  // of the cost of Contrast(): a profile of chi2 over T_peak solves for the
  // fractions at fixed temperatures.
  struct Slice {
    double peak_temperature_K = 0;
    std::vector<std::size_t> offset;  // per table: start of its block in coef and phi
    std::vector<double> coef;  // per table [(ix * NU + iu) * (R + 1) + r]
    std::vector<double> phi;  // per table phi_r(T_peak), R values
  };
  Slice MakeSlice(double peak_temperature_K) const;
  // Contrast [W/(m2 sr)] of every channel at the slice's T_peak, fractions
  // x[s] and depth sigma [m], and, when d_dx is not null, d contrast / d x_s
  // at fixed sigma into d_dx[c * n_species + s]. Equals Contrast() at that
  // temperature (to rounding).
  void SliceContrast(const Slice& slice, const double* x, double sigma_m, const double* phi,
                     double* contrast, double* d_dx) const;

  // One species' contribution to one channel as u g(ln u, x, T_peak), with
  // d/du, d/dx (self-broadening axis at fixed u) and d/dT_peak.
  void SpeciesContrast(std::size_t channel, std::size_t species, double u, double x,
                       double peak_temperature_K, const double* phi, double* value, double* d_du,
                       double* d_dx, double* d_dt) const;

  // The optically thin limit of SpeciesContrast: d(Delta L)/du at u -> 0, x = 0.
  double ThinSlope(std::size_t channel, std::size_t species, double peak_temperature_K,
                   const double* phi) const;

  // Offset of table (c, s)'s coefficients within phi.
  std::size_t phi_offset(std::size_t channel, std::size_t species) const;

  // The table's raw functions before the background contraction, at
  // (ln u, x, T_peak): out[0] = E / u, out[1 + r] = A_r / u (r < rank), so that
  // g = out[0] - sum_r phi_r(T_bg) out[1 + r]. Returns the number of values (rank + 1).
  int RawValues(std::size_t channel, std::size_t species, double log_u, double x,
                double peak_temperature_K, double* out) const;
  // Data of table (c, s) for independent evaluators (e.g. a numpy one): its
  // coefficients as stored, the coefficients of the Planck-basis spline
  // psi_r(T_bg) (phi_r = psi_r B(nu_ref, T)) and nu_ref [cm-1].
  void Export(std::size_t channel, std::size_t species, std::vector<double>* coefficients,
              std::vector<double>* psi_coefficients, double* nu_ref_cm1) const;
  // Fraction nodes of species s's tables (1 without self-broadening).
  int fraction_axis(std::size_t species) const;
  double background_step_K() const { return h_bg_; }
  double min_log_u() const { return lu_lo_; }
  double log_u_step() const { return h_lu_; }

 private:
  struct Table {
    std::size_t channel = 0, species = 0;
    int rank = 0;  // R: number of Planck basis vectors
    int nx = 1;  // fraction nodes (1 without a self table)
    std::size_t phi_offset = 0;
    std::vector<double> coef;  // [((iT * NX + ix) * NU + iu) * (R + 1) + r], padded sizes
    std::vector<double> moment_nu_cm1;  // wavenumbers of the moments
    std::vector<double> basis;  // [m * R + r] orthonormal basis U
    double nu_ref_cm1 = 0;  // phi_r(T) = psi_r(T) B(nu_ref, T)
    UniformSpline psi;  // width R over background temperature
    UniformSpline thin;  // node values at the smallest u and x = 0, over T_peak
    std::size_t num_bins = 0;
  };
  // Planck basis coefficients phi_r(T) of table t and their T-derivatives.
  void Phi(const Table& t, double temperature_K, double* phi, double* dphi) const;
  void BuildTable(Table* t, const std::vector<std::size_t>& bins, double t_peak, int it,
                  std::vector<double>* values) const;
  // phi_tp, dphi_tp: phi_r(T_peak) and d/dT of table t (computed when null).
  void Accumulate(const Table& t, const SplineWeights& wu, const SplineWeights& wx,
                  const SplineWeights& wt, double peak_temperature_K, const double* phi, double* g,
                  double* g_lu, double* g_x, double* g_t, const double* phi_tp = nullptr,
                  const double* dphi_tp = nullptr) const;
  // Calls f(s, c, i, table, u, thin, wu, wx) for every (species, channel)
  // table of a plume with fractions x and depth sigma: u = x_s sigma, thin
  // when u is below the table's range, wu and wx the spline weights in ln u
  // and x_s (the loop shared by Contrast and SliceContrast).
  template <class F>
  void ForEachTable(const double* x, double sigma, F&& f) const;
  void ContrastAt(const double* x, const SplineWeights& wt, double peak_temperature_K,
                  const PeakTerms* terms, double sigma_m, const double* phi, double* contrast,
                  double* jacobian) const;

  std::shared_ptr<const BinnedModel> model_;
  SceneTableOptions options_;
  std::size_t nc_ = 0, ns_ = 0;
  int nu_ = 0, nx_ = 1, nt_ = 0;
  double lu_lo_ = 0, lu_hi_ = 0, h_lu_ = 1, t_lo_ = 0, t_hi_ = 0, h_t_ = 1, h_x_ = 1, h_bg_ = 1;
  CubicSplineAxis axis_u_, axis_x_, axis_t_, axis_one_;
  std::vector<Table> tables_;
  std::vector<int> index_;  // [c * ns + s] -> tables_ index or -1
  std::size_t phi_size_ = 0;
  double build_seconds_ = 0, negligible_bound_ = 0;
};

// Largest error of the table against BinnedModel::Contrast over `num_samples`
// random plumes (seeded): u log-uniform over the table's range, x uniform in
// [0, 1] (sigma = u / x within the table's limits), T_peak uniform over the
// tabulated range, T_bg uniform in [T_peak - 40, T_peak + 10] K (clipped to
// the background range), i.e. mostly warm plumes over colder backgrounds.
// Returns the largest |table - binned| / max(|binned|, floor) per channel,
// where floor = floor_fraction x the channel's dL/dT(T_bg) x 1 K.
struct TableErrorReport {
  double max_relative_error = 0;  // over all samples and channels
  double rms_relative_error = 0;
  double max_jacobian_error = 0;  // derivatives vs finite differences of the binned model, relative
  int num_samples = 0;
};
TableErrorReport MeasureTableError(const SceneTable& table, int num_samples, unsigned seed,
                                   double floor_fraction = 1e-3, bool check_jacobian = false);

// The band table (radiance <-> temperature) the inversion uses for
// backgrounds of `channel` in [min_background_K, max_background_K]: nodes as
// dense in 1/T as 512 over 150-700 K, at least 64 (L, dL/dT and T(L) within
// 1e-8, 1e-6 relative and 1e-6 K of the quadrature over 50-2000 K).
RadiometricTable BackgroundBandTable(const SpectralResponse& channel, double min_background_K,
                                     double max_background_K, int num_threads = 0);

}  // namespace qogi
