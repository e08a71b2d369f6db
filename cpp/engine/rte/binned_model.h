// The fast forward model: spectral binning of the line-by-line tables.
//
// The exact model's spectral points in each channel are grouped into bins of
// points whose cross-sections agree, for every species, within a ratio
// `bin_ratio` at each of several key temperatures (and, with self-broadening
// tables, in the self-broadened cross-section too). Two points with the same
// cross-sections at all temperatures have the same spectral radiance along any
// path, so a bin can stand for all its points: its weight is the sum of their
// response x dnu, its cross-sections are their weighted means (so the
// optically thin limit is exact at every temperature), and its Planck function
// is the weighted mean of B over its points, obtained exactly from a
// Chebyshev interpolant of B(nu, T) across the channel segment. Grouping by
// cross-section at several temperatures (not by rank at one temperature, as in
// a correlated-k model) keeps hot bands and lines of different lower-state
// energy apart, so non-isothermal paths stay accurate.
//
// Each bin is then solved with the same layer scheme as the exact model
// (march.h). Everything is templated on the scalar type, so Ceres' automatic
// differentiation (ceres::Jet) flows through; doubles take vectorised loops.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/optics/spectral_response.h"
#include "engine/rte/absorber_table.h"
#include "engine/rte/march.h"
#include "engine/rte/path.h"

namespace qogi {

struct BinnedModelOptions {
  double bin_ratio = 1.5;  // max ratio of cross-sections within a bin at each key temperature (> 1)
  std::vector<double> key_temperatures_K = {250.0, 350.0,
                                            500.0};  // binning temperatures [K], within the tables
  double floor_fraction =
      1e-8;  // cross-sections below this fraction of a species' maximum count as zero
  bool self_key =
      false;  // also bin by the self-broadened cross-section (at the first key temperature); off: within 0.5 % without it, at half the bins
  int chebyshev_nodes = 12;  // Planck interpolation nodes per segment (4-32)
  double segment_width_cm1 = 300.0;  // max width of a Chebyshev segment [cm-1]
  int num_nodes = 129;  // line-of-sight nodes for Gaussian plumes (>= 3; odd for Richardson)
  double z_max = 5.5;  // Gaussian plume sampled over [-z_max, z_max] sigma
  // Combine the march on all nodes with the march on every other node,
  // (4 fine - coarse) / 3, cancelling the scheme's second-order error
  // (used when the path has an odd number of nodes).
  bool richardson = true;
  void Check() const;
};

class BinnedModel {
 public:
  BinnedModel(std::vector<SpectralResponse> channels, std::vector<AbsorberTable> tables,
              BinnedModelOptions options = {});

  std::size_t num_channels() const { return channels_.size(); }
  std::size_t num_species() const { return species_.size(); }
  const std::vector<std::string>& species() const { return species_; }
  const std::vector<double>& molar_masses() const { return molar_masses_; }
  const std::vector<SpectralResponse>& channels() const { return channels_; }
  const BinnedModelOptions& options() const { return options_; }
  double min_temperature_K() const { return t_min_; }
  double max_temperature_K() const { return t_max_; }
  double pressure_Pa() const { return pressure_Pa_; }
  // Number of bins of channel c (the model's cost is proportional to it).
  std::size_t num_bins(std::size_t channel) const { return bins_[channel].weight.size(); }
  // Largest relative error of the Chebyshev Planck interpolation, measured at
  // build time over all grid points at 200, 300 and 600 K.
  double planck_interpolation_error() const { return planck_error_; }

  // Band radiance [W/(m2 sr)] per channel for a Gaussian plume
  // (background_temperature_K: one value or one per channel).
  std::vector<double> BandRadiance(const GaussianPlume& plume,
                                   const std::vector<double>& background_temperature_K) const;
  // The same for a general path.
  std::vector<double> BandRadiance(const Path& path,
                                   const std::vector<double>& background_temperature_K) const;

  // Templated kernels (no argument checks; the callers check once):
  // contrast Delta L = L - L_bg [W/(m2 sr)] of every channel, into out[c].
  template <typename S>
  void Contrast(const PathT<S>& path, const S* background_temperature_K, S* out) const;
  // Background band radiance of channel c at temperature T (quadrature of
  // SpectralResponse, templated).
  template <typename S>
  S BackgroundRadiance(std::size_t channel, const S& temperature_K) const;
  // Gaussian plume path with this model's node settings.
  template <typename S>
  PathT<S> GaussianPath(const S* peak_fractions, const S& peak_temperature_K,
                        double ambient_temperature_K, const S& sigma_m) const {
    return SampleGaussianPlume<S>(peak_fractions, species_.size(), peak_temperature_K,
                                  ambient_temperature_K, sigma_m, pressure_Pa_, options_.num_nodes,
                                  options_.z_max);
  }
  void CheckPath(const Path& path) const;

  // Per-bin contrast Delta L_q [W/(m2 sr cm-1)] of channel c (not yet
  // weighted: the channel's contrast is sum_q weight(c)[q] * out[q]).
  void BinContrasts(const Path& path, std::size_t channel, double background_temperature_K,
                    std::vector<double>* out) const;
  const std::vector<double>& weights(std::size_t channel) const { return bins_[channel].weight; }

  // A model keeping, per channel, only the listed bins, with new weights
  // [cm-1] (e.g. chosen to reproduce the full model on a scene; see
  // qogi.render). bins[c] and weights[c] have equal lengths.
  BinnedModel Subset(const std::vector<std::vector<int>>& bins,
                     const std::vector<std::vector<double>>& weights) const;

  // Tabulates every bin's cross-sections on a fine temperature grid
  // [t_lo, t_hi] with step `step_K`, interpolated linearly from then on for
  // path temperatures inside it (error ~1e-5 relative at 1 K steps; the
  // log-cubic table interpolation is used outside). For renderers that march
  // many paths within a known temperature range.
  void UseFineTemperatureGrid(double t_lo, double t_hi, double step_K);

  // Contrast of many rays of uniformly spaced samples (see render.h): the
  // renderer's kernel. Needs UseFineTemperatureGrid covering every sample,
  // ambient and background temperature; gives the same result as Contrast()
  // on the equivalent Path up to the fine-grid interpolation.
  void RenderRays(std::size_t ray_begin, std::size_t ray_end, const std::int64_t* offset,
                  const float* step_m, const float* temperature_K,
                  const std::vector<const float*>& fractions, double ambient_temperature_K,
                  const double* background_temperature_K, std::size_t background_stride,
                  float* out) const;

  // The pieces of Contrast(), for evaluators built on this model (the
  // inversion's per-scene tables reuse them to reproduce its results):
  //
  // A read-only view of channel c's bins: bin q has weight weight[q] [cm-1]
  // (sum of response x dnu over its points) and lies in Chebyshev segment
  // segment[q]; its mean Planck function is
  //   Bbar_q(T) = sum_m planck_map[q * num_chebyshev + m] B(nu_{segment[q], m}, T)
  // with nu_{g, m} = segment_nodes[g * num_chebyshev + m] [cm-1].
  struct BinView {
    std::size_t num_bins = 0;
    std::size_t num_segments = 0;
    int num_chebyshev = 0;
    const double* weight = nullptr;
    const int* segment = nullptr;
    const double* planck_map = nullptr;
    const double* segment_nodes = nullptr;
  };
  BinView bins(std::size_t channel) const;
  // Whether species s has a self-broadened table.
  bool has_self(std::size_t species) const { return has_self_[species]; }
  // Whether species s absorbs in bin q of channel c (a non-zero mean
  // cross-section at some table temperature).
  bool BinAbsorbs(std::size_t channel, std::size_t species, std::size_t bin) const;
  // Mean Planck function Bbar_q(T) [W/(m2 sr cm-1)] of every bin of channel c, into out[q].
  void MeanPlanck(std::size_t channel, double temperature_K, double* out) const;
  // Mean cross-sections [cm2/molecule] of species s in every bin of channel c
  // at temperature T, interpolated in temperature exactly as Contrast() does:
  // air-broadened into air[q] and, when the species has a self table,
  // self-broadened into self[q] (self may be null otherwise); 0 where the
  // species does not absorb.
  void BinCrossSections(std::size_t channel, std::size_t species, double temperature_K, double* air,
                        double* self) const;

 private:
  struct Bins {
    std::vector<double> weight;  // [bin] sum of response * dnu [cm-1]
    // sigma_air[(s * n_T + j) * n_bins + q], sigma_self likewise (empty if no self table)
    std::vector<std::vector<double>> sigma_air, sigma_self;  // per species
    std::vector<std::vector<double>> log_sigma_air,
        log_sigma_self;  // ln of the above (-1e300 for 0)
    std::vector<std::vector<int>> active;  // per species: bins where it absorbs at some T
    std::vector<std::vector<char>> positive_air,
        positive_self;  // per species, per bin: > 0 at every T
    // Optional fine temperature grid (UseFineTemperatureGrid): per species
    // [n_fine * n_bins] cross-sections at fine_t0 + k fine_dt.
    std::vector<std::vector<double>> fine_air, fine_self;
    std::vector<double> fine_planck;  // [n_fine * n_bins] bin-mean Planck, when small enough
    std::vector<int> segment;  // [bin]
    // planck_map[q * n_cheb + m]: bin q's mean Planck from the segment's node values
    std::vector<double> planck_map;
    std::vector<double> segment_nodes;  // [segment * n_cheb] Chebyshev wavenumbers
    std::size_t num_segments = 0;
  };
  void BuildChannel(std::size_t c, const std::vector<AbsorberTable>& tables);
  template <typename S>
  S ChannelContrast(const PathT<S>& path, bool symmetric, std::size_t channel, const S& t_bg,
                    std::vector<S>* per_bin) const;

  std::vector<SpectralResponse> channels_;
  std::vector<std::string> species_;
  std::vector<double> molar_masses_;
  std::vector<std::vector<double>> table_temperatures_;  // per species
  std::vector<bool> has_self_;
  BinnedModelOptions options_;
  std::vector<Bins> bins_;
  double fine_t0_ = 0, fine_dt_ = 0;
  std::size_t fine_n_ = 0;
  double t_min_ = 0, t_max_ = 0, pressure_Pa_ = 0, planck_error_ = 0;
};

// ---------------------------------------------------------------------------
// Template implementation.

template <typename S>
S PlanckT(double nu_cm1, const S& temperature_K) {
  using std::expm1;
  return constants::kC1 * nu_cm1 * nu_cm1 * nu_cm1 / expm1(constants::kC2 * nu_cm1 / temperature_K);
}

template <typename S>
S BinnedModel::BackgroundRadiance(std::size_t c, const S& t) const {
  const SpectralResponse& ch = channels_[c];
  const auto& nu = ch.quadrature_nu_cm1();
  const auto& w = ch.quadrature_weights();
  S sum = S(0.0);
  for (std::size_t k = 0; k < nu.size(); ++k) sum += w[k] * PlanckT(nu[k], t);
  return sum;
}

template <typename S>
void BinnedModel::Contrast(const PathT<S>& path, const S* t_bg, S* out) const {
  const std::size_t ns = species_.size();
  const std::size_t nn = path.size();
  // A symmetric path (a Gaussian plume) has the same node state at k and
  // nn-1-k: the first half is computed once and reused.
  bool symmetric = true;
  for (std::size_t k = 0; k < nn / 2 && symmetric; ++k) {
    symmetric =
        ValueOfScalar(path.temperature_K[k]) == ValueOfScalar(path.temperature_K[nn - 1 - k]);
    for (std::size_t s = 0; s < ns && symmetric; ++s)
      symmetric = ValueOfScalar(path.fraction[k * ns + s]) ==
                  ValueOfScalar(path.fraction[(nn - 1 - k) * ns + s]);
  }
  for (std::size_t c = 0; c < channels_.size(); ++c)
    out[c] = ChannelContrast<S>(path, symmetric, c, t_bg[c], nullptr);
}

template <typename S>
S BinnedModel::ChannelContrast(const PathT<S>& path, bool symmetric, std::size_t c, const S& t_bg_c,
                               std::vector<S>* per_bin) const {
  using std::exp;
  const std::size_t ns = species_.size();
  const std::size_t nn = path.size();
  {
    const Bins& b = bins_[c];
    const std::size_t nq = b.weight.size();
    const int nm = options_.chebyshev_nodes;
    if (nq == 0) {
      if (per_bin) per_bin->clear();
      return S(0.0);
    }
    std::vector<S> node_b(b.num_segments * nm);
    auto mean_planck = [&](const S& t, S* dst) {
      for (std::size_t g = 0; g < b.num_segments; ++g)
        for (int m = 0; m < nm; ++m) node_b[g * nm + m] = PlanckT(b.segment_nodes[g * nm + m], t);
      for (std::size_t q = 0; q < nq; ++q) {
        const double* row = &b.planck_map[q * nm];
        const S* nb = &node_b[b.segment[q] * nm];
        S v = S(0.0);
        for (int m = 0; m < nm; ++m) v += row[m] * nb[m];
        dst[q] = v;
      }
    };
    std::vector<S> b_bg(nq), kappa_far(nq), kappa_near(nq), d_far(nq), d_near(nq), dl(nq, S(0.0));
    const bool rich = options_.richardson && nn >= 5 && nn % 2 == 1;
    std::vector<S> kappa_coarse, d_coarse, dl_coarse;
    if (rich) dl_coarse.assign(nq, S(0.0));
    mean_planck(t_bg_c, b_bg.data());

    auto add_species = [&](const S& coef, const TemperatureStencil& st, const S* wt, const S& fr,
                           const std::vector<double>& sig, const std::vector<double>& lsig,
                           const std::vector<int>& active, const std::vector<char>& positive,
                           S* kappa) {
      for (int q : active) {
        S v;
        if (positive[q]) {
          S l = S(0.0);
          for (int a = 0; a < st.count; ++a) l += wt[a] * lsig[(st.first + a) * nq + q];
          v = exp(l);
        } else {
          v = InterpolateInTemperature<S>(
              st, wt, fr, [&](std::size_t k) { return sig[k * nq + q]; },
              [&](std::size_t k) { return lsig[k * nq + q]; });
        }
        kappa[q] += coef * v;
      }
    };
    auto fill_node = [&](std::size_t k, S* kappa, S* d) {
      const S& t = path.temperature_K[k];
      const S n_tot = NumberDensityCm3(path.pressure_Pa, t) * 100.0;
      std::fill(kappa, kappa + nq, S(0.0));
      for (std::size_t s = 0; s < ns; ++s) {
        const S x = path.fraction[k * ns + s];
        if (!(x > 0.0)) continue;
        const S nx0 = n_tot * x;
        if (fine_n_ > 0 && !b.fine_air[s].empty()) {
          const double tv = ValueOfScalar(t);
          const double pos = (tv - fine_t0_) / fine_dt_;
          if (pos >= 0.0 && pos <= static_cast<double>(fine_n_ - 1)) {
            std::size_t k0 = static_cast<std::size_t>(pos);
            if (k0 >= fine_n_ - 1) k0 = fine_n_ - 2;
            const S w1 = (t - (fine_t0_ + k0 * fine_dt_)) / fine_dt_;
            const S w0 = 1.0 - w1;
            const double* a0 = &b.fine_air[s][k0 * nq];
            const double* a1 = a0 + nq;
            const S ca = has_self_[s] ? nx0 * (1.0 - x) : nx0;
            for (int q : b.active[s]) kappa[q] += ca * (w0 * a0[q] + w1 * a1[q]);
            if (has_self_[s]) {
              const double* s0 = &b.fine_self[s][k0 * nq];
              const double* s1 = s0 + nq;
              const S cs = nx0 * x;
              for (int q : b.active[s]) kappa[q] += cs * (w0 * s0[q] + w1 * s1[q]);
            }
            continue;
          }
        }
        // Temperature stencil with derivative-carrying weights.
        const TemperatureStencil st =
            MakeTemperatureStencil(table_temperatures_[s], ValueOfScalar(t));
        S wt[4];
        const S dt = t - ValueOfScalar(t);
        for (int a = 0; a < st.count; ++a) wt[a] = st.weight[a] + st.dweight[a] * dt;
        const S fr = st.frac + st.dfrac * dt;
        const S nx = n_tot * x;
        add_species(has_self_[s] ? nx * (1.0 - x) : nx, st, wt, fr, b.sigma_air[s],
                    b.log_sigma_air[s], b.active[s], b.positive_air[s], kappa);
        if (has_self_[s])
          add_species(nx * x, st, wt, fr, b.sigma_self[s], b.log_sigma_self[s], b.active[s],
                      b.positive_self[s], kappa);
      }
      mean_planck(t, d);
      for (std::size_t q = 0; q < nq; ++q) d[q] -= b_bg[q];
    };
    const std::size_t half = symmetric ? nn / 2 + 1 : 0;
    std::vector<S> saved_k(half * nq), saved_d(half * nq);
    auto node = [&](std::size_t k, S* kappa, S* d) {
      if (symmetric && k >= half) {
        const std::size_t m = nn - 1 - k;
        std::copy(&saved_k[m * nq], &saved_k[m * nq] + nq, kappa);
        std::copy(&saved_d[m * nq], &saved_d[m * nq] + nq, d);
        return;
      }
      fill_node(k, kappa, d);
      if (symmetric) {
        std::copy(kappa, kappa + nq, &saved_k[k * nq]);
        std::copy(d, d + nq, &saved_d[k * nq]);
      }
    };
    node(0, kappa_far.data(), d_far.data());
    if (rich) {
      kappa_coarse = kappa_far;
      d_coarse = d_far;
    }
    for (std::size_t k = 0; k + 1 < nn; ++k) {
      node(k + 1, kappa_near.data(), d_near.data());
      const S ds = path.position_m[k + 1] - path.position_m[k];
      for (std::size_t q = 0; q < nq; ++q)
        dl[q] = MarchLayer(dl[q], kappa_far[q], kappa_near[q], d_far[q], d_near[q], ds);
      if (rich && (k + 1) % 2 == 0) {
        const S ds2 = path.position_m[k + 1] - path.position_m[k - 1];
        for (std::size_t q = 0; q < nq; ++q)
          dl_coarse[q] =
              MarchLayer(dl_coarse[q], kappa_coarse[q], kappa_near[q], d_coarse[q], d_near[q], ds2);
        kappa_coarse = kappa_near;
        d_coarse = d_near;
      }
      std::swap(kappa_far, kappa_near);
      std::swap(d_far, d_near);
    }
    if (rich)
      for (std::size_t q = 0; q < nq; ++q) dl[q] = (4.0 * dl[q] - dl_coarse[q]) * (1.0 / 3.0);
    S sum = S(0.0);
    for (std::size_t q = 0; q < nq; ++q) sum += b.weight[q] * dl[q];
    if (per_bin) *per_bin = std::move(dl);
    return sum;
  }
}

}  // namespace qogi
