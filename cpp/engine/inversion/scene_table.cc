#include "engine/inversion/scene_table.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <string>

#include "engine/inversion/march_kernel.h"
#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {

void SceneTableOptions::Check() const {
  CheckInRange(ambient_temperature_K, 100.0, 2000.0, "ambient_temperature_K", "K");
  CheckNonNegative(min_peak_temperature_K, "min_peak_temperature_K", "K");
  CheckNonNegative(max_peak_temperature_K, "max_peak_temperature_K", "K");
  CheckInRange(temperature_step_K, 1.0, 50.0, "temperature_step_K", "K");
  CheckInRange(max_sigma_m, 1e-4, 1e3, "max_sigma_m", "m");
  Require(nodes_per_decade >= 2 && nodes_per_decade <= 40,
          "nodes_per_decade must be within [2, 40]; got " + std::to_string(nodes_per_decade));
  Require(fraction_nodes >= 4 && fraction_nodes <= 21,
          "fraction_nodes must be within [4, 21]; got " + std::to_string(fraction_nodes));
  CheckInRange(thin_optical_depth, 1e-8, 1e-3, "thin_optical_depth");
  CheckInRange(min_background_K, 50.0, 2000.0, "min_background_K", "K");
  CheckInRange(max_background_K, min_background_K + 10.0, 2000.0, "max_background_K", "K");
  CheckInRange(planck_tolerance, 1e-14, 1e-4, "planck_tolerance");
  CheckInRange(negligible_fraction, 0.0, 1e-3, "negligible_fraction");
  CheckInRange(linear_optical_depth, 1e-9, 1e-3, "linear_optical_depth");
  Require(num_nodes == 0 || (num_nodes >= 5 && num_nodes <= 10001 && num_nodes % 2 == 1),
          "num_nodes must be 0 (the model's) or odd within [5, 10001]; got " +
              std::to_string(num_nodes));
  Require(num_threads >= 0,
          "num_threads must be >= 0 (0 = all cores); got " + std::to_string(num_threads));
}

std::vector<std::string> SceneTable::SpectralOverlaps(const BinnedModel& model) {
  std::vector<std::string> out;
  for (std::size_t c = 0; c < model.num_channels(); ++c) {
    const std::size_t nq = model.num_bins(c);
    std::size_t shared = 0;
    std::vector<bool> involved(model.num_species(), false);
    for (std::size_t q = 0; q < nq; ++q) {
      int count = 0;
      for (std::size_t s = 0; s < model.num_species(); ++s) count += model.BinAbsorbs(c, s, q);
      if (count > 1) {
        ++shared;
        for (std::size_t s = 0; s < model.num_species(); ++s)
          if (model.BinAbsorbs(c, s, q)) involved[s] = true;
      }
    }
    if (shared > 0) {
      std::string names;
      for (std::size_t s = 0; s < involved.size(); ++s)
        if (involved[s]) names += (names.empty() ? "" : ", ") + model.species()[s];
      const std::string& cn = model.channels()[c].name();
      out.push_back("channel " + std::to_string(c) + (cn.empty() ? "" : " '" + cn + "'") + ": " +
                    std::to_string(shared) + " of " + std::to_string(nq) +
                    " bins where several species absorb (" + names + ")");
    }
  }
  return out;
}

namespace {

constexpr int kMaxRank = 48;

// B(nu, T) and dB/dT.
inline void PlanckWithSlope(double nu, double t, double* b, double* db) {
  const double x = constants::kC2 * nu / t;
  *b = PlanckUnchecked(nu, t);
  *db = *b * x / t / (-std::expm1(-x));
}

// Tensor-product prefilter along one axis of a row-major array with dims
// (d0, d1, d2, d3); `axis` in {0, 1, 2}; returns the array with that axis
// replaced by its coefficient count.
std::vector<double> PrefilterAxis(const std::vector<double>& in, int dims[4], int axis,
                                  const CubicSplineAxis& a) {
  int out_dims[4] = {dims[0], dims[1], dims[2], dims[3]};
  out_dims[axis] = a.num_coefficients();
  std::vector<double> out(static_cast<std::size_t>(out_dims[0]) * out_dims[1] * out_dims[2] *
                          out_dims[3]);
  auto stride = [](const int* d, int ax) {
    std::ptrdiff_t s = 1;
    for (int k = 3; k > ax; --k) s *= d[k];
    return s;
  };
  const std::ptrdiff_t si = stride(dims, axis), so = stride(out_dims, axis);
  // Iterate over all index combinations except `axis`.
  int idx[4] = {0, 0, 0, 0};
  const int other[3] = {axis == 0 ? 1 : 0, axis <= 1 ? 2 : 1, 3};
  (void)other;
  for (idx[0] = 0; idx[0] < (axis == 0 ? 1 : dims[0]); ++idx[0])
    for (idx[1] = 0; idx[1] < (axis == 1 ? 1 : dims[1]); ++idx[1])
      for (idx[2] = 0; idx[2] < (axis == 2 ? 1 : dims[2]); ++idx[2])
        for (idx[3] = 0; idx[3] < dims[3]; ++idx[3]) {
          std::ptrdiff_t oi = 0, oo = 0;
          for (int k = 0; k < 4; ++k) {
            oi += idx[k] * stride(dims, k);
            oo += idx[k] * stride(out_dims, k);
          }
          a.Prefilter(&in[oi], si, &out[oo], so);
        }
  for (int k = 0; k < 4; ++k) dims[k] = out_dims[k];
  return out;
}

}  // namespace

SceneTable::SceneTable(std::shared_ptr<const BinnedModel> model, SceneTableOptions options,
                       const RunControl* control)
    : model_(std::move(model)), options_(std::move(options)) {
  const auto t_start = std::chrono::steady_clock::now();
  Require(model_ != nullptr, "SceneTable needs a model");
  options_.Check();
  const BinnedModel& m = *model_;
  const auto overlaps = SpectralOverlaps(m);
  if (!overlaps.empty()) {
    std::string msg = "the per-scene table needs spectrally separate species, but ";
    for (std::size_t i = 0; i < overlaps.size(); ++i) msg += (i ? "; " : "") + overlaps[i];
    throw std::invalid_argument(msg + "; invert with the full binned model instead");
  }
  nc_ = m.num_channels();
  ns_ = m.num_species();
  const double tmin = m.min_temperature_K(), tmax = m.max_temperature_K();
  const double t_amb = options_.ambient_temperature_K;
  Require(t_amb >= tmin && t_amb <= tmax,
          "ambient_temperature_K " + FormatNumber(t_amb) + " K is outside the cross-section " +
              "tables' range [" + FormatNumber(tmin) + ", " + FormatNumber(tmax) + "] K");
  t_lo_ = options_.min_peak_temperature_K > 0 ? options_.min_peak_temperature_K : tmin;
  t_hi_ = options_.max_peak_temperature_K > 0 ? options_.max_peak_temperature_K : tmax;
  Require(t_lo_ >= tmin - 1e-9 && t_hi_ <= tmax + 1e-9,
          "peak temperature range [" + FormatNumber(t_lo_) + ", " + FormatNumber(t_hi_) +
              "] K must lie inside the cross-section tables' range [" + FormatNumber(tmin) + ", " +
              FormatNumber(tmax) + "] K");
  Require(t_hi_ - t_lo_ >= 3 * 1.0, "peak temperature range [" + FormatNumber(t_lo_) + ", " +
                                        FormatNumber(t_hi_) + "] K is too narrow (needs >= 3 K)");
  nt_ = std::max(
      4, static_cast<int>(std::ceil((t_hi_ - t_lo_) / options_.temperature_step_K - 1e-9)) + 1);
  h_t_ = (t_hi_ - t_lo_) / (nt_ - 1);

  bool any_self = false;
  for (std::size_t s = 0; s < ns_; ++s) any_self = any_self || m.has_self(s);
  nx_ = any_self ? options_.fraction_nodes : 1;
  h_x_ = nx_ > 1 ? 1.0 / (nx_ - 1) : 1.0;

  // Which bins belong to which species, and the largest absorption
  // coefficient per unit u (for the thin limit).
  const double z_max = m.options().z_max;
  const double n_lo = NumberDensityCm3(m.pressure_Pa(), tmin) * 100.0;  // [1/cm3] x [cm/m]
  double kmax = 0;
  std::vector<std::vector<std::size_t>> bins_of(nc_ * ns_);
  for (std::size_t c = 0; c < nc_; ++c) {
    const std::size_t nq = m.num_bins(c);
    std::vector<double> air(nq), self(nq);
    // Largest possible contrast of each bin: W_q Bbar_q at the hottest
    // temperature the table serves (gas or background).
    std::vector<double> bmax(nq);
    m.MeanPlanck(c, std::max(tmax, options_.max_background_K), bmax.data());
    const BinnedModel::BinView bvc = m.bins(c);
    const double budget = options_.negligible_fraction * m.channels()[c].BandRadiance(t_amb);
    double dropped_c = 0;
    for (std::size_t s = 0; s < ns_; ++s) {
      std::vector<std::pair<double, std::size_t>> by_size;
      for (std::size_t q = 0; q < nq; ++q)
        if (m.BinAbsorbs(c, s, q)) by_size.emplace_back(bvc.weight[q] * std::abs(bmax[q]), q);
      std::sort(by_size.begin(), by_size.end());
      for (const auto& bq : by_size) {
        if (dropped_c + bq.first <= budget) {
          dropped_c += bq.first;
          continue;
        }
        bins_of[c * ns_ + s].push_back(bq.second);
      }
      std::sort(bins_of[c * ns_ + s].begin(), bins_of[c * ns_ + s].end());
      if (bins_of[c * ns_ + s].empty()) continue;
      for (double temp = tmin; temp <= tmax + 1e-9; temp += (tmax - tmin) / 40.0) {
        m.BinCrossSections(c, s, temp, air.data(), m.has_self(s) ? self.data() : nullptr);
        for (std::size_t q : bins_of[c * ns_ + s]) {
          kmax = std::max(kmax, air[q]);
          if (m.has_self(s)) kmax = std::max(kmax, self[q]);
        }
      }
    }
    negligible_bound_ = std::max(negligible_bound_, dropped_c);
  }
  Require(kmax > 0,
          "no channel sees any absorption of the model's species; "
          "check the channels' spectral ranges against the tables");
  // Peak optical depth of a plume: u * n * sigma_abs * sqrt(2 pi).
  const double u_min = options_.thin_optical_depth / (kmax * n_lo * std::sqrt(2 * constants::kPi));
  const double u_max = options_.max_sigma_m;
  Require(u_max > 10 * u_min, "max_sigma_m is too small for the table");
  lu_lo_ = std::log(u_min);
  lu_hi_ = std::log(u_max);
  nu_ = std::max(
      4, static_cast<int>(std::ceil(std::log10(u_max / u_min) * options_.nodes_per_decade - 1e-9)) +
             1);
  h_lu_ = (lu_hi_ - lu_lo_) / (nu_ - 1);
  axis_u_ = CubicSplineAxis(nu_);
  axis_x_ = CubicSplineAxis(nx_);
  axis_t_ = CubicSplineAxis(nt_);
  axis_one_ = CubicSplineAxis(1);
  (void)z_max;

  // Tables and their Planck bases.
  index_.assign(nc_ * ns_, -1);
  const int n_bg = std::max(
      4,
      static_cast<int>(std::ceil((options_.max_background_K - options_.min_background_K) / 0.5)) +
          1);
  const double h_bg = (options_.max_background_K - options_.min_background_K) / (n_bg - 1);
  h_bg_ = h_bg;
  for (std::size_t c = 0; c < nc_; ++c) {
    const BinnedModel::BinView bv = m.bins(c);
    for (std::size_t s = 0; s < ns_; ++s) {
      const auto& bins = bins_of[c * ns_ + s];
      if (bins.empty()) continue;
      Table t;
      t.channel = c;
      t.species = s;
      t.nx = m.has_self(s) ? nx_ : 1;
      t.num_bins = bins.size();
      // Moments: Chebyshev nodes of the segments holding this species' bins.
      std::vector<int> segs;
      for (std::size_t q : bins) segs.push_back(bv.segment[q]);
      std::sort(segs.begin(), segs.end());
      segs.erase(std::unique(segs.begin(), segs.end()), segs.end());
      const int nm = bv.num_chebyshev;
      for (int g : segs)
        for (int k = 0; k < nm; ++k) t.moment_nu_cm1.push_back(bv.segment_nodes[g * nm + k]);
      const int mm = static_cast<int>(t.moment_nu_cm1.size());
      // Normalised moment vectors over the background range; SVD.
      const int n_svd = std::max(
          50, static_cast<int>((options_.max_background_K - options_.min_background_K) / 2.0));
      Eigen::MatrixXd bm(mm, n_svd);
      for (int j = 0; j < n_svd; ++j) {
        const double temp =
            options_.min_background_K +
            (options_.max_background_K - options_.min_background_K) * j / (n_svd - 1);
        for (int k = 0; k < mm; ++k) bm(k, j) = PlanckUnchecked(t.moment_nu_cm1[k], temp);
        bm.col(j) /= bm.col(j).norm();
      }
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(bm, Eigen::ComputeThinU);
      const Eigen::MatrixXd& u = svd.matrixU();
      int rank = 1;
      for (; rank <= mm; ++rank) {
        const Eigen::MatrixXd ur = u.leftCols(rank);
        const Eigen::MatrixXd resid = bm - ur * (ur.transpose() * bm);
        if (resid.colwise().norm().maxCoeff() <= options_.planck_tolerance || rank == mm) break;
      }
      Require(rank <= kMaxRank, "the background Planck basis needs rank " + std::to_string(rank) +
                                    " (> " + std::to_string(kMaxRank) + ") for planck_tolerance " +
                                    FormatNumber(options_.planck_tolerance) +
                                    "; raise planck_tolerance or narrow the background range");
      t.rank = rank;
      t.basis.resize(static_cast<std::size_t>(mm) * rank);
      for (int k = 0; k < mm; ++k)
        for (int r = 0; r < rank; ++r) t.basis[k * rank + r] = u(k, r);
      // phi_r(T) / B(nu_ref, T) as splines over the background range.
      double nsum = 0;
      for (double v : t.moment_nu_cm1) nsum += v;
      t.nu_ref_cm1 = nsum / mm;
      std::vector<double> psi(static_cast<std::size_t>(n_bg) * rank, 0.0);
      for (int j = 0; j < n_bg; ++j) {
        const double temp = options_.min_background_K + j * h_bg;
        const double bref = PlanckUnchecked(t.nu_ref_cm1, temp);
        for (int k = 0; k < mm; ++k) {
          const double b = PlanckUnchecked(t.moment_nu_cm1[k], temp) / bref;
          for (int r = 0; r < rank; ++r) psi[j * rank + r] += t.basis[k * rank + r] * b;
        }
      }
      t.psi = UniformSpline(options_.min_background_K, h_bg, n_bg, rank, psi);
      t.phi_offset = phi_size_;
      phi_size_ += rank;
      index_[c * ns_ + s] = static_cast<int>(tables_.size());
      tables_.push_back(std::move(t));
    }
  }

  // Node values, in parallel over peak temperatures.
  std::vector<std::vector<double>> values(tables_.size());
  for (std::size_t i = 0; i < tables_.size(); ++i)
    values[i].assign(static_cast<std::size_t>(nt_) * tables_[i].nx * nu_ * (tables_[i].rank + 1),
                     0.0);
  ParallelFor(
      static_cast<std::size_t>(nt_), 1,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t it = b; it < e; ++it)
          for (std::size_t i = 0; i < tables_.size(); ++i)
            BuildTable(&tables_[i], bins_of[tables_[i].channel * ns_ + tables_[i].species],
                       t_lo_ + it * h_t_, static_cast<int>(it), &values[i]);
      },
      options_.num_threads, control);

  // B-spline coefficients (u, then x, then T), and the thin-limit line.
  for (std::size_t i = 0; i < tables_.size(); ++i) {
    Table& t = tables_[i];
    std::vector<double> thin(static_cast<std::size_t>(nt_) * (t.rank + 1));
    for (int it = 0; it < nt_; ++it)
      for (int r = 0; r <= t.rank; ++r)
        thin[it * (t.rank + 1) + r] =
            values[i][(static_cast<std::size_t>(it) * t.nx * nu_) * (t.rank + 1) + r];
    t.thin = UniformSpline(t_lo_, h_t_, nt_, t.rank + 1, thin);
    int dims[4] = {nt_, t.nx, nu_, t.rank + 1};
    std::vector<double> a = PrefilterAxis(values[i], dims, 2, axis_u_);
    a = PrefilterAxis(a, dims, 1, t.nx > 1 ? axis_x_ : axis_one_);
    t.coef = PrefilterAxis(a, dims, 0, axis_t_);
  }
  build_seconds_ =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
}

void SceneTable::BuildTable(Table* t, const std::vector<std::size_t>& bins, double t_peak, int it,
                            std::vector<double>* values) const {
  const BinnedModel& m = *model_;
  const std::size_t c = t->channel, s = t->species;
  const BinnedModel::BinView bv = m.bins(c);
  const std::size_t nq_all = bv.num_bins, nb = bins.size();
  const int nn = options_.num_nodes > 0 ? options_.num_nodes : m.options().num_nodes;
  const double z_max = m.options().z_max;
  const double dz = 2 * z_max / (nn - 1);
  const bool rich = m.options().richardson && nn >= 5 && nn % 2 == 1;
  const double t_amb = options_.ambient_temperature_K;
  const bool self = m.has_self(s);
  const int nm = bv.num_chebyshev;
  const int rank = t->rank;

  // Per node: n g, the bins' cross-sections and mean Planck functions.
  std::vector<double> ng(nn), g(nn);
  std::vector<double> air(static_cast<std::size_t>(nn) * nb), slf(self ? air.size() : 0),
      bbar(air.size());
  std::vector<double> air_all(nq_all), self_all(nq_all), b_all(nq_all);
  for (int k = 0; k < nn; ++k) {
    const double z = -z_max + k * dz;
    g[k] = std::exp(-0.5 * z * z);
    const double temp = t_amb + (t_peak - t_amb) * g[k];
    ng[k] = NumberDensityCm3(m.pressure_Pa(), temp) * 100.0 * g[k];
    m.BinCrossSections(c, s, temp, air_all.data(), self ? self_all.data() : nullptr);
    m.MeanPlanck(c, temp, b_all.data());
    for (std::size_t j = 0; j < nb; ++j) {
      air[k * nb + j] = air_all[bins[j]];
      if (self) slf[k * nb + j] = self_all[bins[j]];
      bbar[k * nb + j] = b_all[bins[j]];
    }
  }
  // Projection of each bin's absorptance onto the Planck basis:
  // P[j * R + r] = W_q sum_m M_qm U_{moment(q, m), r}.
  std::vector<int> seg_pos(bv.num_segments, -1);
  {
    int pos = 0;
    std::vector<int> segs;
    for (std::size_t q : bins) segs.push_back(bv.segment[q]);
    std::sort(segs.begin(), segs.end());
    segs.erase(std::unique(segs.begin(), segs.end()), segs.end());
    for (int sg : segs) seg_pos[sg] = pos++;
  }
  std::vector<double> proj(nb * rank, 0.0), weight(nb);
  for (std::size_t j = 0; j < nb; ++j) {
    const std::size_t q = bins[j];
    weight[j] = bv.weight[q];
    const int base = seg_pos[bv.segment[q]] * nm;
    for (int k = 0; k < nm; ++k) {
      const double mq = bv.planck_map[q * nm + k] * bv.weight[q];
      for (int r = 0; r < rank; ++r) proj[j * rank + r] += mq * t->basis[(base + k) * rank + r];
    }
  }

  // Bins in decreasing order of absorption (air, and self when present), so
  // that at each u the bins still optically thin form a suffix.
  {
    std::vector<double> strength(nb, 0.0);
    for (int k = 0; k < nn; ++k)
      for (std::size_t j = 0; j < nb; ++j)
        strength[j] += ng[k] * std::max(air[k * nb + j], self ? slf[k * nb + j] : 0.0);
    std::vector<std::size_t> order(nb);
    for (std::size_t j = 0; j < nb; ++j) order[j] = j;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return strength[a] > strength[b]; });
    auto permute = [&](std::vector<double>* v, std::size_t width) {
      if (v->empty()) return;
      std::vector<double> out(v->size());
      const std::size_t rows = v->size() / (nb * width);
      for (std::size_t row = 0; row < rows; ++row)
        for (std::size_t j = 0; j < nb; ++j)
          for (std::size_t w = 0; w < width; ++w)
            out[(row * nb + j) * width + w] = (*v)[(row * nb + order[j]) * width + w];
      v->swap(out);
    };
    permute(&air, 1);
    permute(&slf, 1);
    permute(&bbar, 1);
    permute(&weight, 1);
    permute(&proj, rank);
  }

  // The march of march.h for D = Bbar(T(s)) (emission E) and D = 1
  // (absorptance), which share each layer's optical depth (march_kernel.h).
  std::vector<double> phi_tp(rank), dphi_tp(rank);
  Phi(*t, t_peak, phi_tp.data(), dphi_tp.data());
  std::vector<double> kap(static_cast<std::size_t>(nn) * nb), tau_hat(nb);
  std::vector<double> dle(nb), dla(nb), dlec(nb), dlac(nb);
  const std::size_t block = 128;  // bins whose node data stay in cache while every u is marched
  // March bins [j0, j0 + m) at u; Richardson-combined results into dle, dla.
  // The path is symmetric about its middle node (odd nn): only its first
  // half is marched, the mirrored half's contribution accumulated alongside
  // (MarchLayerPairSymmetric); with Richardson the coarse grid's layers must
  // end on the middle node too.
  const bool symmetric = nn % 2 == 1 && (!rich || ((nn - 1) / 2) % 2 == 0);
  const int layers = symmetric ? (nn - 1) / 2 : nn - 1;
  std::vector<double> pf(nb), ebf(nb), abf(nb), pc(nb), ebc(nb), abc(nb);
  auto march = [&](std::size_t j0, std::size_t m, double u) {
    std::fill(dle.begin(), dle.begin() + m, 0.0);
    std::fill(dla.begin(), dla.begin() + m, 0.0);
    std::fill(dlec.begin(), dlec.begin() + m, 0.0);
    std::fill(dlac.begin(), dlac.begin() + m, 0.0);
    if (symmetric) {
      std::fill(pf.begin(), pf.begin() + m, 1.0);
      std::fill(pc.begin(), pc.begin() + m, 1.0);
      std::fill(ebf.begin(), ebf.begin() + m, 0.0);
      std::fill(abf.begin(), abf.begin() + m, 0.0);
      std::fill(ebc.begin(), ebc.begin() + m, 0.0);
      std::fill(abc.begin(), abc.begin() + m, 0.0);
    }
    for (int k = 0; k < layers; ++k) {
      if (symmetric)
        MarchLayerPairSymmetric(m, &kap[k * nb + j0], &kap[(k + 1) * nb + j0], &bbar[k * nb + j0],
                                &bbar[(k + 1) * nb + j0], u, dz, dle.data(), dla.data(), pf.data(),
                                ebf.data(), abf.data());
      else
        MarchLayerPair(m, &kap[k * nb + j0], &kap[(k + 1) * nb + j0], &bbar[k * nb + j0],
                       &bbar[(k + 1) * nb + j0], u, dz, dle.data(), dla.data());
      if (rich && (k + 1) % 2 == 0) {
        if (symmetric)
          MarchLayerPairSymmetric(m, &kap[(k - 1) * nb + j0], &kap[(k + 1) * nb + j0],
                                  &bbar[(k - 1) * nb + j0], &bbar[(k + 1) * nb + j0], u, 2 * dz,
                                  dlec.data(), dlac.data(), pc.data(), ebc.data(), abc.data());
        else
          MarchLayerPair(m, &kap[(k - 1) * nb + j0], &kap[(k + 1) * nb + j0],
                         &bbar[(k - 1) * nb + j0], &bbar[(k + 1) * nb + j0], u, 2 * dz, dlec.data(),
                         dlac.data());
      }
    }
    if (symmetric)
      for (std::size_t j = 0; j < m; ++j) {
        dle[j] = dle[j] * pf[j] + ebf[j];
        dla[j] = dla[j] * pf[j] + abf[j];
        dlec[j] = dlec[j] * pc[j] + ebc[j];
        dlac[j] = dlac[j] * pc[j] + abc[j];
      }
    if (rich)
      for (std::size_t j = 0; j < m; ++j) {
        dle[j] = (4.0 * dle[j] - dlec[j]) * (1.0 / 3.0);
        dla[j] = (4.0 * dla[j] - dlac[j]) * (1.0 / 3.0);
      }
  };
  // A bin whose whole-path optical depth stays below this is linear in u to
  // within half of it (relative): it is not marched but scaled from its slope.
  const double kLinear = options_.linear_optical_depth;
  const int nx = t->nx;
  const int r1 = rank + 1;
  std::vector<double> suffix((nb + 1) * r1);
  for (int ix = 0; ix < nx; ++ix) {
    const double x = nx > 1 ? ix * h_x_ : 0.0;
    // Absorption coefficient per unit u and per unit of z (kappa ds = u kap dz).
    for (int k = 0; k < nn; ++k)
      for (std::size_t j = 0; j < nb; ++j) {
        const std::size_t i = k * nb + j;
        kap[i] = self ? ng[k] * ((1.0 - x * g[k]) * air[i] + x * g[k] * slf[i]) : ng[k] * air[i];
      }
    double tau_max = 0;
    for (std::size_t j = 0; j < nb; ++j) {
      double tt = 0;
      for (int k = 0; k + 1 < nn; ++k) tt += 0.5 * (kap[k * nb + j] + kap[(k + 1) * nb + j]) * dz;
      tau_hat[j] = tt;
      tau_max = std::max(tau_max, tt);
    }
    // Optically thin slopes of every bin (a march at a u where even the
    // strongest bin has optical depth 1e-12), summed from each bin to the end.
    const double u0 = tau_max > 0 ? 1e-12 / tau_max : 1.0;
    std::fill(suffix.begin(), suffix.end(), 0.0);
    for (std::size_t j0 = 0; j0 < nb; j0 += block) {
      const std::size_t m = std::min(block, nb - j0);
      march(j0, m, u0);
      for (std::size_t j = 0; j < m; ++j) {
        double* row = &suffix[(j0 + j) * r1];
        row[0] = weight[j0 + j] * dle[j] / u0;
        for (int r = 0; r < rank; ++r) row[1 + r] = proj[(j0 + j) * rank + r] * dla[j] / u0;
      }
    }
    for (std::size_t j = nb; j-- > 0;)
      for (int r = 0; r < r1; ++r) suffix[j * r1 + r] += suffix[(j + 1) * r1 + r];
    // Per u: bins [0, cut) are marched, the rest scaled from their slopes.
    std::vector<std::size_t> cut(nu_);
    for (int iu = 0; iu < nu_; ++iu) {
      const double u = std::exp(lu_lo_ + iu * h_lu_);
      std::size_t cc = 0;
      for (std::size_t j = 0; j < nb; ++j)
        if (u * tau_hat[j] > kLinear) cc = j + 1;
      cut[iu] = cc;
    }
    double* line = &(*values)[(static_cast<std::size_t>(it) * nx + ix) * nu_ * r1];
    for (int iu = 0; iu < nu_; ++iu) {
      const double u = std::exp(lu_lo_ + iu * h_lu_);
      for (int r = 0; r < r1; ++r) line[iu * r1 + r] = u * suffix[cut[iu] * r1 + r];
    }
    for (std::size_t j0 = 0; j0 < nb; j0 += block) {
      for (int iu = 0; iu < nu_; ++iu) {
        if (cut[iu] <= j0) continue;
        const std::size_t m = std::min(block, cut[iu] - j0);
        const double u = std::exp(lu_lo_ + iu * h_lu_);
        march(j0, m, u);
        double* out = line + static_cast<std::size_t>(iu) * r1;
        for (std::size_t j = 0; j < m; ++j) {
          out[0] += weight[j0 + j] * dle[j];
          for (int r = 0; r < rank; ++r) out[1 + r] += proj[(j0 + j) * rank + r] * dla[j];
        }
      }
    }
    for (int iu = 0; iu < nu_; ++iu) {
      const double u = std::exp(lu_lo_ + iu * h_lu_);
      double* out = line + static_cast<std::size_t>(iu) * r1;
      // Emission relative to a background at T_peak.
      for (int r = 0; r < rank; ++r) out[0] -= phi_tp[r] * out[1 + r];
      for (int r = 0; r < r1; ++r) out[r] /= u;
    }
  }
}

void SceneTable::Export(std::size_t c, std::size_t s, std::vector<double>* coef,
                        std::vector<double>* psi, double* nu_ref) const {
  const int i = index_[c * ns_ + s];
  Require(i >= 0,
          "species " + std::to_string(s) + " does not absorb in channel " + std::to_string(c));
  *coef = tables_[i].coef;
  *psi = tables_[i].psi.coefficients();
  *nu_ref = tables_[i].nu_ref_cm1;
}

std::size_t SceneTable::num_tabulated_bins() const {
  std::size_t n = 0;
  for (const Table& t : tables_) n += t.num_bins;
  return n;
}

int SceneTable::fraction_axis(std::size_t s) const {
  for (const Table& t : tables_)
    if (t.species == s) return t.nx;
  return 1;
}

int SceneTable::basis_rank(std::size_t c, std::size_t s) const {
  const int i = index_[c * ns_ + s];
  return i < 0 ? 0 : tables_[i].rank;
}

std::size_t SceneTable::phi_offset(std::size_t c, std::size_t s) const {
  const int i = index_[c * ns_ + s];
  return i < 0 ? 0 : tables_[i].phi_offset;
}

double SceneTable::memory_bytes() const {
  double b = 0;
  for (const Table& t : tables_) b += 8.0 * (t.coef.size() + t.basis.size());
  return b;
}

void SceneTable::Background(const double* t_bg, double* phi) const {
  for (const Table& t : tables_) {
    const double tb = t_bg[t.channel];
    t.psi.Evaluate(tb, phi + t.phi_offset);
    const double bref = PlanckUnchecked(t.nu_ref_cm1, tb);
    for (int r = 0; r < t.rank; ++r) phi[t.phi_offset + r] *= bref;
  }
}

void SceneTable::Phi(const Table& t, double temp, double* phi, double* dphi) const {
  double bref, dbref;
  PlanckWithSlope(t.nu_ref_cm1, temp, &bref, &dbref);
  t.psi.Evaluate(temp, phi, dphi);
  for (int r = 0; r < t.rank; ++r) {
    dphi[r] = dphi[r] * bref + phi[r] * dbref;
    phi[r] *= bref;
  }
}

namespace {

// The tensor-product sums of Accumulate over the (up to) 4 x 4 x 4
// coefficient vectors of one table around a point: with v = c_0 + sum_r
// dphi_r c_r and w = sum_r dphi_dt_r c_r (WithT),
//   out = {sum wt wx wu v, sum wt wx dwu v, sum wt dwx wu v, sum dwt wx wu v,
//          sum wt wx wu w}.
// R1 (the vectors' length, rank + 1) is a compile-time constant for the
// common ranks, so that the dot products unroll; 0 = r1 at run time.
template <int R1, bool WithT>
void SumCell(const double* base, std::size_t a_stride, std::size_t b_stride, int r1_runtime,
             const SplineWeights& wu, const SplineWeights& wx, const SplineWeights& wt,
             const double* dphi, const double* dphi_dt, double* out) {
  const int r1 = R1 > 0 ? R1 : r1_runtime;
  double v0 = 0, vu = 0, vx = 0, vt = 0, w0 = 0;
  for (int a = 0; a < wt.count; ++a) {
    double a0 = 0, au = 0, ax = 0, aw = 0;
    for (int b = 0; b < wx.count; ++b) {
      const double* row = base + a * a_stride + b * b_stride;
      double b0 = 0, bu = 0, bw = 0;
      for (int k = 0; k < wu.count; ++k) {
        const double* cv = row + k * r1;
        double v = cv[0], w = 0;
        for (int r = 1; r < r1; ++r) {
          v += dphi[r - 1] * cv[r];
          if (WithT) w += dphi_dt[r - 1] * cv[r];
        }
        b0 += wu.w[k] * v;
        bu += wu.dw[k] * v;
        if (WithT) bw += wu.w[k] * w;
      }
      a0 += wx.w[b] * b0;
      au += wx.w[b] * bu;
      ax += wx.dw[b] * b0;
      if (WithT) aw += wx.w[b] * bw;
    }
    v0 += wt.w[a] * a0;
    vu += wt.w[a] * au;
    vx += wt.w[a] * ax;
    vt += wt.dw[a] * a0;
    if (WithT) w0 += wt.w[a] * aw;
  }
  out[0] = v0;
  out[1] = vu;
  out[2] = vx;
  out[3] = vt;
  out[4] = w0;
}

template <bool WithT>
void SumCellAnyRank(const double* base, std::size_t a_stride, std::size_t b_stride, int r1,
                    const SplineWeights& wu, const SplineWeights& wx, const SplineWeights& wt,
                    const double* dphi, const double* dphi_dt, double* out) {
  switch (r1) {
#define QOGI_SUM_CELL_CASE(n) \
  case n: return SumCell<n, WithT>(base, a_stride, b_stride, n, wu, wx, wt, dphi, dphi_dt, out);
    QOGI_SUM_CELL_CASE(2)
    QOGI_SUM_CELL_CASE(3)
    QOGI_SUM_CELL_CASE(4)
    QOGI_SUM_CELL_CASE(5)
    QOGI_SUM_CELL_CASE(6)
    QOGI_SUM_CELL_CASE(7)
    QOGI_SUM_CELL_CASE(8)
    QOGI_SUM_CELL_CASE(9)
    QOGI_SUM_CELL_CASE(10)
    QOGI_SUM_CELL_CASE(11)
    QOGI_SUM_CELL_CASE(12)
#undef QOGI_SUM_CELL_CASE
    default: return SumCell<0, WithT>(base, a_stride, b_stride, r1, wu, wx, wt, dphi, dphi_dt, out);
  }
}

}  // namespace

void SceneTable::Accumulate(const Table& t, const SplineWeights& wu, const SplineWeights& wx,
                            const SplineWeights& wt, double tp, const double* phi_bg, double* g,
                            double* g_lu, double* g_x, double* g_t, const double* phi_tp,
                            const double* dphi_tp) const {
  const int r1 = t.rank + 1;
  const int nxc = t.nx > 1 ? nx_ + 2 : 1;
  const int nuc = nu_ + 2;
  double dphi[kMaxRank], dphi_dt[kMaxRank];
  if (phi_tp) {
    std::copy(phi_tp, phi_tp + t.rank, dphi);
    std::copy(dphi_tp, dphi_tp + t.rank, dphi_dt);
  } else {
    Phi(t, tp, dphi, dphi_dt);
  }
  const double* pb = phi_bg + t.phi_offset;
  for (int r = 0; r < t.rank; ++r) dphi[r] -= pb[r];
  // g = Etilde + sum_r (phi_r(T_peak) - phi_r(T_bg)) A_r/u, and the sum
  // sum_r dphi_r/dT A_r/u for the T_peak derivative.
  const std::size_t b_stride = static_cast<std::size_t>(nuc) * r1;
  const std::size_t a_stride = nxc * b_stride;
  const double* base =
      &t.coef[((static_cast<std::size_t>(wt.first) * nxc + wx.first) * nuc + wu.first) * r1];
  double sums[5];
  if (g_t)
    SumCellAnyRank<true>(base, a_stride, b_stride, r1, wu, wx, wt, dphi, dphi_dt, sums);
  else
    SumCellAnyRank<false>(base, a_stride, b_stride, r1, wu, wx, wt, dphi, dphi_dt, sums);
  *g = sums[0];
  if (!g_t) return;
  *g_lu = sums[1] / h_lu_;
  *g_x = t.nx > 1 ? sums[2] / h_x_ : 0.0;
  *g_t = sums[3] / h_t_ + sums[4];
}

void SceneTable::SpeciesContrast(std::size_t c, std::size_t s, double u, double x, double tp,
                                 const double* phi, double* value, double* d_du, double* d_dx,
                                 double* d_dt) const {
  const int i = index_[c * ns_ + s];
  if (i < 0) {
    *value = *d_du = *d_dx = *d_dt = 0;
    return;
  }
  const Table& t = tables_[i];
  const bool thin = !(u > std::exp(lu_lo_));
  const double lu = thin ? lu_lo_ : std::log(u);
  const SplineWeights wu =
      axis_u_.Weights((lu - lu_lo_) / h_lu_, Extrapolation::kHold, Extrapolation::kLinear);
  const SplineWeights wx = t.nx > 1 ? axis_x_.Weights(x / h_x_) : axis_one_.Weights(0);
  const SplineWeights wt = axis_t_.Weights((tp - t_lo_) / h_t_);
  double g, g_lu, g_x, g_t;
  Accumulate(t, wu, wx, wt, tp, phi, &g, &g_lu, &g_x, &g_t);
  *value = u * g;
  *d_du = thin ? g : g + g_lu;
  *d_dx = u * g_x;
  *d_dt = u * g_t;
}

double SceneTable::ThinSlope(std::size_t c, std::size_t s, double tp, const double* phi) const {
  const int i = index_[c * ns_ + s];
  if (i < 0) return 0.0;
  const Table& t = tables_[i];
  double raw[kMaxRank + 1], ptp[kMaxRank], dptp[kMaxRank];
  t.thin.Evaluate(tp, raw);
  Phi(t, tp, ptp, dptp);
  double g = raw[0];
  const double* pb = phi + t.phi_offset;
  for (int r = 0; r < t.rank; ++r) g += (ptp[r] - pb[r]) * raw[1 + r];
  return g;
}

int SceneTable::RawValues(std::size_t c, std::size_t s, double lu, double x, double tp,
                          double* out) const {
  const int i = index_[c * ns_ + s];
  if (i < 0) return 0;
  const Table& t = tables_[i];
  const int r1 = t.rank + 1;
  const int nxc = t.nx > 1 ? nx_ + 2 : 1;
  const int nuc = nu_ + 2;
  const SplineWeights wu =
      axis_u_.Weights((lu - lu_lo_) / h_lu_, Extrapolation::kHold, Extrapolation::kLinear);
  const SplineWeights wx = t.nx > 1 ? axis_x_.Weights(x / h_x_) : axis_one_.Weights(0);
  const SplineWeights wt = axis_t_.Weights((tp - t_lo_) / h_t_);
  for (int r = 0; r < r1; ++r) out[r] = 0;
  for (int a = 0; a < wt.count; ++a)
    for (int b = 0; b < wx.count; ++b) {
      const double* row =
          &t.coef[((static_cast<std::size_t>(wt.first + a) * nxc + wx.first + b) * nuc + wu.first) *
                  r1];
      const double wab = wt.w[a] * wx.w[b];
      for (int k = 0; k < wu.count; ++k) {
        const double w = wab * wu.w[k];
        for (int r = 0; r < r1; ++r) out[r] += w * row[k * r1 + r];
      }
    }
  // Back from emission relative to T_peak to E / u.
  double ptp[kMaxRank], dptp[kMaxRank];
  Phi(t, tp, ptp, dptp);
  for (int r = 0; r < t.rank; ++r) out[0] += ptp[r] * out[1 + r];
  return r1;
}

SceneTable::Slice SceneTable::MakeSlice(double tp) const {
  Slice sl;
  sl.peak_temperature_K = tp;
  const SplineWeights wt = axis_t_.Weights((tp - t_lo_) / h_t_);
  const int nuc = nu_ + 2;
  std::size_t size = 0;
  for (const Table& t : tables_) {
    sl.offset.push_back(size);
    size += static_cast<std::size_t>(t.nx > 1 ? nx_ + 2 : 1) * nuc * (t.rank + 1);
  }
  sl.coef.assign(size, 0.0);
  sl.phi.assign(tables_.size() * kMaxRank, 0.0);
  for (std::size_t i = 0; i < tables_.size(); ++i) {
    const Table& t = tables_[i];
    const std::size_t block = static_cast<std::size_t>(t.nx > 1 ? nx_ + 2 : 1) * nuc * (t.rank + 1);
    double* out = &sl.coef[sl.offset[i]];
    for (int a = 0; a < wt.count; ++a) {
      const double* in = &t.coef[static_cast<std::size_t>(wt.first + a) * block];
      for (std::size_t k = 0; k < block; ++k) out[k] += wt.w[a] * in[k];
    }
    double dphi[kMaxRank];
    Phi(t, tp, &sl.phi[i * kMaxRank], dphi);
  }
  return sl;
}

template <class F>
void SceneTable::ForEachTable(const double* x, double sigma, F&& f) const {
  const double u_lo = std::exp(lu_lo_);
  for (std::size_t s = 0; s < ns_; ++s) {
    const double u = x[s] * sigma;
    const bool thin = !(u > u_lo);
    const double lu = thin ? lu_lo_ : std::log(u);
    const SplineWeights wu =
        axis_u_.Weights((lu - lu_lo_) / h_lu_, Extrapolation::kHold, Extrapolation::kLinear);
    SplineWeights wx;
    bool wx_ready = false;
    for (std::size_t c = 0; c < nc_; ++c) {
      const int i = index_[c * ns_ + s];
      if (i < 0) continue;
      const Table& t = tables_[i];
      if (!wx_ready) {
        wx = t.nx > 1 ? axis_x_.Weights(x[s] / h_x_) : axis_one_.Weights(0);
        wx_ready = true;
      }
      f(s, c, static_cast<std::size_t>(i), t, u, thin, wu, wx);
    }
  }
}

void SceneTable::SliceContrast(const Slice& sl, const double* x, double sigma, const double* phi,
                               double* contrast, double* d_dx) const {
  SplineWeights one;  // the slice has no T_peak axis
  one.count = 1;
  one.w[0] = 1.0;
  for (std::size_t c = 0; c < nc_; ++c) contrast[c] = 0;
  if (d_dx)
    for (std::size_t k = 0; k < nc_ * ns_; ++k) d_dx[k] = 0;
  const int nuc = nu_ + 2;
  ForEachTable(
      x, sigma,
      [&](std::size_t s, std::size_t c, std::size_t i, const Table& t, double u, bool thin,
          const SplineWeights& wu, const SplineWeights& wx) {
        const int r1 = t.rank + 1;
        double dphi[kMaxRank];
        const double* pt = &sl.phi[i * kMaxRank];
        const double* pb = phi + t.phi_offset;
        for (int r = 0; r < t.rank; ++r) dphi[r] = pt[r] - pb[r];
        const double* base =
            &sl.coef[sl.offset[i] + (static_cast<std::size_t>(wx.first) * nuc + wu.first) * r1];
        double sums[5];
        SumCellAnyRank<false>(base, 0, static_cast<std::size_t>(nuc) * r1, r1, wu, wx, one, dphi,
                              nullptr, sums);
        const double g = sums[0], g_u = sums[1], g_x = sums[2];
        contrast[c] += u * g;
        if (d_dx) {
          const double d_du = thin ? g : g + g_u / h_lu_;
          d_dx[c * ns_ + s] += d_du * sigma + (t.nx > 1 ? u * g_x / h_x_ : 0.0);
        }
      });
}

void SceneTable::Contrast(const double* x, double tp, double sigma, const double* phi,
                          double* contrast, double* jac) const {
  ContrastAt(x, axis_t_.Weights((tp - t_lo_) / h_t_), tp, nullptr, sigma, phi, contrast, jac);
}

void SceneTable::MakePeakTerms(double tp, PeakTerms* terms) const {
  terms->peak_temperature_K = tp;
  terms->wt = axis_t_.Weights((tp - t_lo_) / h_t_);
  terms->phi.resize(tables_.size() * kMaxRank);
  terms->dphi.resize(tables_.size() * kMaxRank);
  for (std::size_t i = 0; i < tables_.size(); ++i)
    Phi(tables_[i], tp, &terms->phi[i * kMaxRank], &terms->dphi[i * kMaxRank]);
}

void SceneTable::Contrast(const double* x, const PeakTerms& terms, double sigma, const double* phi,
                          double* contrast, double* jac) const {
  ContrastAt(x, terms.wt, terms.peak_temperature_K, &terms, sigma, phi, contrast, jac);
}

void SceneTable::ContrastAt(const double* x, const SplineWeights& wt, double tp,
                            const PeakTerms* terms, double sigma, const double* phi,
                            double* contrast, double* jac) const {
  const std::size_t np = ns_ + 2;
  for (std::size_t c = 0; c < nc_; ++c) contrast[c] = 0;
  if (jac)
    for (std::size_t k = 0; k < nc_ * np; ++k) jac[k] = 0;
  ForEachTable(x, sigma,
               [&](std::size_t s, std::size_t c, std::size_t i, const Table& t, double u, bool thin,
                   const SplineWeights& wu, const SplineWeights& wx) {
                 double g, g_lu, g_x, g_t;
                 const double* pt = terms ? &terms->phi[i * kMaxRank] : nullptr;
                 const double* dpt = terms ? &terms->dphi[i * kMaxRank] : nullptr;
                 Accumulate(t, wu, wx, wt, tp, phi, &g, &g_lu, &g_x, jac ? &g_t : nullptr, pt, dpt);
                 contrast[c] += u * g;
                 if (jac) {
                   const double d_du = thin ? g : g + g_lu;
                   double* row = jac + c * np;
                   row[s] += d_du * sigma + u * g_x;
                   row[ns_] += u * g_t;
                   row[ns_ + 1] += d_du * x[s];
                 }
               });
}

TableErrorReport MeasureTableError(const SceneTable& table, int num_samples, unsigned seed,
                                   double floor_fraction, bool check_jacobian) {
  const BinnedModel& m = table.model();
  const std::size_t nc = m.num_channels(), ns = m.num_species();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  TableErrorReport rep;
  double sum2 = 0;
  int count = 0;
  const double t_amb = table.ambient_temperature_K();
  std::vector<double> phi(table.background_size()), tab(nc), ref(nc), jac(nc * (ns + 2));
  const auto& opt = table.options();
  for (int n = 0; n < num_samples; ++n) {
    const double lu0 = std::log(table.min_column_proxy_m() * 0.5);
    const double lu1 = std::log(table.max_column_proxy_m());
    std::vector<double> x(ns);
    double sigma = 0;
    // One random species-mix; sigma from the first species' u and x.
    const double x0 = 0.02 + 0.96 * u01(rng);
    const double u0 = std::exp(lu0 + (lu1 - lu0) * u01(rng));
    sigma = std::min(u0 / x0, opt.max_sigma_m);
    double rest = 1.0;
    for (std::size_t s = 0; s < ns; ++s) {
      x[s] = (s == 0 ? std::min(u0 / sigma, 1.0) : u01(rng)) * rest;
      rest -= x[s];
    }
    const double tp = table.min_peak_temperature_K() +
                      (table.max_peak_temperature_K() - table.min_peak_temperature_K()) * u01(rng);
    std::vector<double> tbg(nc);
    for (std::size_t c = 0; c < nc; ++c)
      tbg[c] = std::min(std::max(tp - 40.0 + 50.0 * u01(rng), opt.min_background_K + 1),
                        opt.max_background_K - 1);
    table.Background(tbg.data(), phi.data());
    table.Contrast(x.data(), tp, sigma, phi.data(), tab.data(),
                   check_jacobian ? jac.data() : nullptr);
    const Path path = m.GaussianPath<double>(x.data(), tp, t_amb, sigma);
    m.Contrast<double>(path, tbg.data(), ref.data());
    for (std::size_t c = 0; c < nc; ++c) {
      const double floor = floor_fraction * m.channels()[c].BandRadianceDerivative(tbg[c]);
      const double err = std::abs(tab[c] - ref[c]) / std::max(std::abs(ref[c]), floor);
      rep.max_relative_error = std::max(rep.max_relative_error, err);
      sum2 += err * err;
      ++count;
    }
    if (check_jacobian) {
      // Central differences of the binned model in each parameter.
      std::vector<double> p(ns + 2);
      for (std::size_t s = 0; s < ns; ++s) p[s] = x[s];
      p[ns] = tp;
      p[ns + 1] = sigma;
      for (std::size_t k = 0; k < ns + 2; ++k) {
        const double h = k < ns ? 1e-4 * std::max(x[k], 1e-3) : (k == ns ? 0.05 : 1e-4 * sigma);
        std::vector<double> lo = p, hi = p;
        lo[k] -= h;
        hi[k] += h;
        if (k < ns && lo[k] < 0) lo[k] = 0;
        std::vector<double> rl(nc), rh(nc);
        const Path pl = m.GaussianPath<double>(lo.data(), lo[ns], t_amb, lo[ns + 1]);
        const Path ph = m.GaussianPath<double>(hi.data(), hi[ns], t_amb, hi[ns + 1]);
        m.Contrast<double>(pl, tbg.data(), rl.data());
        m.Contrast<double>(ph, tbg.data(), rh.data());
        // Derivative error as the contrast error over a typical parameter
        // change (the fraction itself, 10 K, sigma itself), relative to the contrast.
        const double typical = k < ns ? x[k] : (k == ns ? 10.0 : sigma);
        for (std::size_t c = 0; c < nc; ++c) {
          const double fd = (rh[c] - rl[c]) / (hi[k] - lo[k]);
          const double scale = std::max(
              std::abs(ref[c]), floor_fraction * m.channels()[c].BandRadianceDerivative(tbg[c]));
          const double err = std::abs(jac[c * (ns + 2) + k] - fd) * typical / scale;
          rep.max_jacobian_error = std::max(rep.max_jacobian_error, err);
        }
      }
    }
  }
  rep.num_samples = num_samples;
  rep.rms_relative_error = count ? std::sqrt(sum2 / count) : 0.0;
  return rep;
}

RadiometricTable BackgroundBandTable(const SpectralResponse& channel, double lo, double hi,
                                     int num_threads) {
  const double du = (1.0 / 150.0 - 1.0 / 700.0) / 511.0;
  const int nodes = std::max(64, static_cast<int>(std::ceil((1.0 / lo - 1.0 / hi) / du)) + 1);
  return RadiometricTable(channel, lo, hi, nodes, num_threads);
}

}  // namespace qogi
