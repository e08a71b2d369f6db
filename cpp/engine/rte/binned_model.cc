#include "engine/rte/binned_model.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "engine/optics/planck.h"
#include "engine/rte/exact_model.h"
#include "engine/util/check.h"
#include "engine/util/parallel.h"

namespace qogi {

void BinnedModelOptions::Check() const {
  CheckInRange(bin_ratio, 1.01, 100.0, "bin_ratio");
  Require(!key_temperatures_K.empty() && key_temperatures_K.size() <= 6,
          "key_temperatures_K needs 1 to 6 temperatures; got " +
              std::to_string(key_temperatures_K.size()));
  for (double t : key_temperatures_K) CheckInRange(t, 100.0, 3000.0, "key_temperatures_K", "K");
  CheckInRange(floor_fraction, 0.0, 1e-2, "floor_fraction");
  Require(chebyshev_nodes >= 4 && chebyshev_nodes <= 32,
          "chebyshev_nodes must be within [4, 32]; got " + std::to_string(chebyshev_nodes));
  CheckInRange(segment_width_cm1, 10.0, 10000.0, "segment_width_cm1", "cm-1");
  Require(num_nodes >= 3 && num_nodes <= 10001,
          "num_nodes must be within [3, 10001]; got " + std::to_string(num_nodes));
  CheckInRange(z_max, 2.0, 12.0, "z_max", "sigma");
}

namespace {

// Cross-section of table `t` at grid point (index j, fraction w) and
// temperature-grid index `it`.
inline double TableValue(const std::vector<float>& v, const AbsorberTable& t, std::size_t it,
                         long j, double w) {
  const float* row = &v[it * t.n_nu + j];
  return (1 - w) * row[0] + w * row[1];
}

}  // namespace

BinnedModel::BinnedModel(std::vector<SpectralResponse> channels, std::vector<AbsorberTable> tables,
                         BinnedModelOptions options)
    : channels_(std::move(channels)), options_(std::move(options)) {
  options_.Check();
  Require(!channels_.empty(), "a forward model needs at least one channel");
  CheckModelTables(tables, &t_min_, &t_max_);
  for (double t : options_.key_temperatures_K)
    Require(t >= t_min_ && t <= t_max_,
            "key temperature " + FormatNumber(t) + " K is outside the tables' range [" +
                FormatNumber(t_min_) + ", " + FormatNumber(t_max_) + "] K");
  pressure_Pa_ = tables[0].pressure_Pa;
  for (const auto& t : tables) {
    species_.push_back(t.species);
    molar_masses_.push_back(t.molar_mass());
    table_temperatures_.push_back(t.temperatures_K);
    has_self_.push_back(t.has_self());
  }
  bins_.resize(channels_.size());
  // Channels are independent (each writes its own bins_[c]).
  ParallelFor(channels_.size(), 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t c = b; c < e; ++c) BuildChannel(c, tables);
  });
}

void BinnedModel::BuildChannel(std::size_t c, const std::vector<AbsorberTable>& tables) {
  const ChannelGrid g = MakeChannelGrid(channels_[c], tables);
  const std::size_t np = g.nu_cm1.size();
  const std::size_t ns = tables.size();
  Bins& b = bins_[c];
  if (np == 0) return;

  // Values at the key temperatures (linear interpolation between table rows
  // is enough for binning decisions).
  const std::size_t nk = options_.key_temperatures_K.size();
  std::vector<double> smax(ns, 0.0);
  for (std::size_t s = 0; s < ns; ++s)
    for (float v : tables[s].sigma_air) smax[s] = std::max<double>(smax[s], v);
  std::vector<std::vector<double>> log_air, log_self;
  for (const auto& t : tables) {
    log_air.push_back(LogValues(t.sigma_air));
    log_self.push_back(LogValues(t.sigma_self));
  }
  auto key_value = [&](bool self, std::size_t s, std::size_t i, double temp) {
    const AbsorberTable& t = tables[s];
    const long j = g.index[s][i];
    if (j < 0) return 0.0;
    const TemperatureStencil st = MakeTemperatureStencil(t.temperatures_K, temp);
    const std::vector<float>& v = self ? t.sigma_self : t.sigma_air;
    const std::vector<double>& lv = self ? log_self[s] : log_air[s];
    const double lo = SigmaAt(v, lv, t.n_nu, st, j);
    const double w = g.frac[s][i];
    return w > 0 ? lo + w * (SigmaAt(v, lv, t.n_nu, st, j + 1) - lo) : lo;
  };
  const double log_ratio = std::log(options_.bin_ratio);
  auto level = [&](double v, double floor_v) -> int {
    if (!(v > floor_v)) return -1000000;
    return static_cast<int>(std::floor(std::log(v) / log_ratio));
  };

  // Segments for the Chebyshev Planck interpolation.
  const double lo = g.nu_cm1.front(), hi = g.nu_cm1.back();
  b.num_segments = std::max<std::size_t>(
      1, static_cast<std::size_t>(std::ceil((hi - lo) / options_.segment_width_cm1 - 1e-9)));
  const double seg_w = (hi - lo) / b.num_segments;
  auto segment_of = [&](double nu) {
    std::size_t sg = seg_w > 0 ? static_cast<std::size_t>((nu - lo) / seg_w) : 0;
    return std::min(sg, b.num_segments - 1);
  };

  std::map<std::vector<int>, int> bin_of_key;
  std::vector<int> bin_of_point(np, -1);
  std::vector<int> key;
  for (std::size_t i = 0; i < np; ++i) {
    key.clear();
    key.push_back(static_cast<int>(segment_of(g.nu_cm1[i])));
    bool absorbs = false;
    for (std::size_t s = 0; s < ns; ++s) {
      const double floor_v = options_.floor_fraction * smax[s];
      for (std::size_t k = 0; k < nk; ++k) {
        const int l = level(key_value(false, s, i, options_.key_temperatures_K[k]), floor_v);
        absorbs = absorbs || l > -1000000;
        key.push_back(l);
      }
      if (tables[s].has_self() && options_.self_key)
        key.push_back(level(key_value(true, s, i, options_.key_temperatures_K[0]), floor_v));
    }
    if (!absorbs) continue;  // transparent at every key temperature: zero contrast
    auto it = bin_of_key.find(key);
    if (it == bin_of_key.end())
      it = bin_of_key.emplace(key, static_cast<int>(bin_of_key.size())).first;
    bin_of_point[i] = it->second;
  }
  const std::size_t nq = bin_of_key.size();
  b.weight.assign(nq, 0.0);
  b.segment.assign(nq, 0);
  b.sigma_air.assign(ns, {});
  b.sigma_self.assign(ns, {});
  for (std::size_t s = 0; s < ns; ++s) {
    b.sigma_air[s].assign(tables[s].temperatures_K.size() * nq, 0.0);
    if (tables[s].has_self()) b.sigma_self[s].assign(tables[s].temperatures_K.size() * nq, 0.0);
  }
  const int nm = options_.chebyshev_nodes;
  b.segment_nodes.resize(b.num_segments * nm);
  for (std::size_t sg = 0; sg < b.num_segments; ++sg) {
    const double a = lo + sg * seg_w, e = (sg + 1 == b.num_segments) ? hi : a + seg_w;
    for (int m = 0; m < nm; ++m)
      b.segment_nodes[sg * nm + m] =
          0.5 * (a + e) + 0.5 * (e - a) * std::cos(constants::kPi * (m + 0.5) / nm);
  }
  b.planck_map.assign(nq * nm, 0.0);
  // Barycentric weights of Chebyshev points of the first kind.
  std::vector<double> bw(nm);
  for (int m = 0; m < nm; ++m)
    bw[m] = ((m % 2) ? -1.0 : 1.0) * std::sin(constants::kPi * (m + 0.5) / nm);
  std::vector<double> ell(nm);
  auto lagrange = [&](std::size_t sg, double nu) {
    const double* x = &b.segment_nodes[sg * nm];
    for (int m = 0; m < nm; ++m)
      if (nu == x[m]) {
        std::fill(ell.begin(), ell.end(), 0.0);
        ell[m] = 1.0;
        return;
      }
    double den = 0;
    for (int m = 0; m < nm; ++m) den += bw[m] / (nu - x[m]);
    for (int m = 0; m < nm; ++m) ell[m] = bw[m] / (nu - x[m]) / den;
  };

  for (std::size_t i = 0; i < np; ++i) {
    const int q = bin_of_point[i];
    if (q < 0) continue;
    const double w = g.weight[i];
    b.weight[q] += w;
    const std::size_t sg = segment_of(g.nu_cm1[i]);
    b.segment[q] = static_cast<int>(sg);
    lagrange(sg, g.nu_cm1[i]);
    for (int m = 0; m < nm; ++m) b.planck_map[q * nm + m] += w * ell[m];
    for (std::size_t s = 0; s < ns; ++s) {
      const long j = g.index[s][i];
      if (j < 0) continue;
      const AbsorberTable& t = tables[s];
      for (std::size_t it = 0; it < t.temperatures_K.size(); ++it) {
        b.sigma_air[s][it * nq + q] += w * TableValue(t.sigma_air, t, it, j, g.frac[s][i]);
        if (t.has_self())
          b.sigma_self[s][it * nq + q] += w * TableValue(t.sigma_self, t, it, j, g.frac[s][i]);
      }
    }
  }
  for (std::size_t q = 0; q < nq; ++q) {
    const double inv = 1.0 / b.weight[q];
    for (int m = 0; m < nm; ++m) b.planck_map[q * nm + m] *= inv;
    for (std::size_t s = 0; s < ns; ++s) {
      for (std::size_t it = 0; it < tables[s].temperatures_K.size(); ++it) {
        b.sigma_air[s][it * nq + q] *= inv;
        if (tables[s].has_self()) b.sigma_self[s][it * nq + q] *= inv;
      }
    }
  }
  b.log_sigma_air.resize(ns);
  b.log_sigma_self.resize(ns);
  b.active.assign(ns, {});
  b.positive_air.assign(ns, std::vector<char>(nq, 0));
  b.positive_self.assign(ns, std::vector<char>(nq, 0));
  for (std::size_t s = 0; s < ns; ++s) {
    for (double v : b.sigma_air[s]) b.log_sigma_air[s].push_back(v > 0 ? std::log(v) : -1e300);
    for (double v : b.sigma_self[s]) b.log_sigma_self[s].push_back(v > 0 ? std::log(v) : -1e300);
    const std::size_t nt = tables[s].temperatures_K.size();
    for (std::size_t q = 0; q < nq; ++q) {
      bool any = false, all_air = true, all_self = tables[s].has_self();
      for (std::size_t it = 0; it < nt; ++it) {
        const double va = b.sigma_air[s][it * nq + q];
        any = any || va > 0;
        all_air = all_air && va > 0;
        if (tables[s].has_self()) {
          const double vs = b.sigma_self[s][it * nq + q];
          any = any || vs > 0;
          all_self = all_self && vs > 0;
        }
      }
      if (any) b.active[s].push_back(static_cast<int>(q));
      b.positive_air[s][q] = all_air;
      b.positive_self[s][q] = all_self;
    }
  }
  // Measure the Planck interpolation error on the grid points.
  for (double temp : {200.0, 300.0, 600.0}) {
    std::vector<double> node_b(b.num_segments * nm);
    for (std::size_t k = 0; k < node_b.size(); ++k)
      node_b[k] = PlanckUnchecked(b.segment_nodes[k], temp);
    for (std::size_t i = 0; i < np; i += 7) {
      const std::size_t sg = segment_of(g.nu_cm1[i]);
      lagrange(sg, g.nu_cm1[i]);
      double v = 0;
      for (int m = 0; m < nm; ++m) v += ell[m] * node_b[sg * nm + m];
      const double exact = PlanckUnchecked(g.nu_cm1[i], temp);
      planck_error_ = std::max(planck_error_, std::abs(v - exact) / exact);
    }
  }
}

void BinnedModel::BinContrasts(const Path& path, std::size_t channel, double t_bg,
                               std::vector<double>* out) const {
  Require(channel < bins_.size(), "channel index out of range");
  CheckPath(path);
  CheckInRange(t_bg, 100.0, 2000.0, "background_temperature_K", "K");
  ChannelContrast<double>(path, false, channel, t_bg, out);
}

BinnedModel BinnedModel::Subset(const std::vector<std::vector<int>>& keep,
                                const std::vector<std::vector<double>>& weights) const {
  Require(keep.size() == bins_.size() && weights.size() == bins_.size(),
          "Subset needs one list of bins and weights per channel (" + std::to_string(bins_.size()) +
              ")");
  BinnedModel out = *this;
  const std::size_t ns = species_.size();
  const int nm = options_.chebyshev_nodes;
  for (std::size_t c = 0; c < bins_.size(); ++c) {
    const Bins& b = bins_[c];
    const std::size_t nq = b.weight.size();
    Require(keep[c].size() == weights[c].size(), "Subset: bins and weights differ in length");
    Bins n;
    n.num_segments = b.num_segments;
    n.segment_nodes = b.segment_nodes;
    const std::size_t k = keep[c].size();
    for (std::size_t i = 0; i < k; ++i) {
      const int q = keep[c][i];
      Require(q >= 0 && static_cast<std::size_t>(q) < nq, "Subset: bin index out of range");
      CheckNonNegative(weights[c][i], "Subset weight", "cm-1");
      n.weight.push_back(weights[c][i]);
      n.segment.push_back(b.segment[q]);
      for (int m = 0; m < nm; ++m) n.planck_map.push_back(b.planck_map[q * nm + m]);
    }
    auto pick = [&](const std::vector<double>& v, std::size_t nt) {
      std::vector<double> o(nt * k);
      for (std::size_t it = 0; it < nt; ++it)
        for (std::size_t i = 0; i < k; ++i) o[it * k + i] = v[it * nq + keep[c][i]];
      return o;
    };
    n.sigma_air.resize(ns);
    n.sigma_self.resize(ns);
    n.log_sigma_air.resize(ns);
    n.log_sigma_self.resize(ns);
    n.active.assign(ns, {});
    n.positive_air.assign(ns, std::vector<char>(k, 0));
    n.positive_self.assign(ns, std::vector<char>(k, 0));
    n.fine_air.assign(ns, {});
    n.fine_self.assign(ns, {});
    for (std::size_t s = 0; s < ns; ++s) {
      const std::size_t nt = table_temperatures_[s].size();
      n.sigma_air[s] = pick(b.sigma_air[s], nt);
      n.log_sigma_air[s] = pick(b.log_sigma_air[s], nt);
      if (has_self_[s]) {
        n.sigma_self[s] = pick(b.sigma_self[s], nt);
        n.log_sigma_self[s] = pick(b.log_sigma_self[s], nt);
      }
      std::vector<char> active(nq, 0);
      for (int q : b.active[s]) active[q] = 1;
      for (std::size_t i = 0; i < k; ++i) {
        const int q = keep[c][i];
        if (active[q]) n.active[s].push_back(static_cast<int>(i));
        n.positive_air[s][i] = b.positive_air[s][q];
        n.positive_self[s][i] = b.positive_self[s][q];
      }
    }
    out.bins_[c] = std::move(n);
  }
  out.fine_n_ = 0;
  return out;
}

void BinnedModel::UseFineTemperatureGrid(double t_lo, double t_hi, double step) {
  CheckPositive(step, "step_K", "K");
  Require(t_lo >= t_min_ - 1e-9 && t_hi <= t_max_ + 1e-9 && t_hi > t_lo,
          "fine temperature grid [" + FormatNumber(t_lo) + ", " + FormatNumber(t_hi) +
              "] K must lie inside the tables' range [" + FormatNumber(t_min_) + ", " +
              FormatNumber(t_max_) + "] K");
  const std::size_t n = static_cast<std::size_t>(std::ceil((t_hi - t_lo) / step)) + 1;
  Require(n >= 2 && n <= 100000, "fine temperature grid needs 2 to 100000 points");
  fine_t0_ = t_lo;
  fine_dt_ = step;
  fine_n_ = n;
  const std::size_t ns = species_.size();
  const int nm = options_.chebyshev_nodes;
  for (Bins& b : bins_) {
    const std::size_t nq = b.weight.size();
    // Bin-mean Planck on the grid too, when the table stays small (renderers
    // use few bins); others keep the Chebyshev evaluation.
    b.fine_planck.clear();
    if (n * nq <= 4000000) {
      b.fine_planck.assign(n * nq, 0.0);
      std::vector<double> node_b(b.num_segments * nm);
      for (std::size_t k = 0; k < n; ++k) {
        const double t = t_lo + k * step;
        for (std::size_t i = 0; i < node_b.size(); ++i)
          node_b[i] = PlanckUnchecked(b.segment_nodes[i], t);
        for (std::size_t q = 0; q < nq; ++q) {
          double v = 0;
          for (int m = 0; m < nm; ++m)
            v += b.planck_map[q * nm + m] * node_b[b.segment[q] * nm + m];
          b.fine_planck[k * nq + q] = v;
        }
      }
    }
    b.fine_air.assign(ns, {});
    b.fine_self.assign(ns, {});
    for (std::size_t s = 0; s < ns; ++s) {
      b.fine_air[s].assign(n * nq, 0.0);
      if (has_self_[s]) b.fine_self[s].assign(n * nq, 0.0);
      for (std::size_t k = 0; k < n; ++k) {
        const double t = std::min(t_lo + k * step, t_max_);
        const TemperatureStencil st = MakeTemperatureStencil(table_temperatures_[s], t);
        double w[4];
        for (int a = 0; a < st.count; ++a) w[a] = st.weight[a];
        for (std::size_t q = 0; q < nq; ++q) {
          auto interp = [&](const std::vector<double>& v, const std::vector<double>& lv) {
            return InterpolateInTemperature<double>(
                st, w, st.frac, [&](std::size_t i) { return v[i * nq + q]; },
                [&](std::size_t i) { return lv[i * nq + q]; });
          };
          b.fine_air[s][k * nq + q] = interp(b.sigma_air[s], b.log_sigma_air[s]);
          if (has_self_[s])
            b.fine_self[s][k * nq + q] = interp(b.sigma_self[s], b.log_sigma_self[s]);
        }
      }
    }
  }
}

namespace {

// One layer of the march (march.h) given the nodes' half-layer transmittances
// e = exp(-kappa ds / 2): t = e_far e_near, so each node costs one exp.
inline void RenderLayer(std::size_t nq, const double* kf, const double* kn, const double* ef,
                        const double* en, const double* df, const double* dn, double ds,
                        double* dl) {
  for (std::size_t q = 0; q < nq; ++q) {
    const double tau = 0.5 * (kf[q] + kn[q]) * ds;
    const double t = ef[q] * en[q];
    const double f = tau < 1e-4 ? 1.0 - tau * (0.5 - tau * (1.0 / 6.0)) : (1.0 - t) / tau;
    const double tt = 1.0 - tau * f;
    const double dd = df[q] - dn[q];
    dl[q] =
        dl[q] * tt + dn[q] * (tau * f) + dd * (f - tt) + 0.25 * dd * (kf[q] - kn[q]) * ds * (f * f);
  }
}

}  // namespace

void BinnedModel::RenderRays(std::size_t r0, std::size_t r1, const std::int64_t* offset,
                             const float* step_m, const float* temperature,
                             const std::vector<const float*>& fractions, double t_amb,
                             const double* t_bg, std::size_t bg_stride, float* out) const {
  const std::size_t ns = species_.size();
  const std::size_t nc = channels_.size();
  Require(fine_n_ > 0, "RenderRays needs UseFineTemperatureGrid first");
  for (const Bins& b : bins_)
    Require(!b.fine_planck.empty() || b.weight.empty(),
            "RenderRays needs a model small enough to tabulate Planck per bin (use Subset)");
  const double t_hi = fine_t0_ + fine_dt_ * (fine_n_ - 1);
  auto position = [&](double t, std::size_t* k0, double* w1) {
    if (!(t >= fine_t0_ - 1e-9 && t <= t_hi + 1e-9))
      throw std::invalid_argument("temperature " + FormatNumber(t) +
                                  " K is outside the renderer's fine grid [" +
                                  FormatNumber(fine_t0_) + ", " + FormatNumber(t_hi) + "] K");
    double p = (t - fine_t0_) / fine_dt_;
    p = std::min(std::max(p, 0.0), static_cast<double>(fine_n_ - 1));
    std::size_t k = static_cast<std::size_t>(p);
    if (k >= fine_n_ - 1) k = fine_n_ - 2;
    *k0 = k;
    *w1 = p - static_cast<double>(k);
  };
  // Per node (shared by all channels): fine-grid index and weight, and the
  // air- and self-broadened number densities per species [1/cm3 x cm/m].
  std::vector<std::size_t> nk;
  std::vector<double> nw, na, nsf;
  std::vector<double> kf, kn, ef, en, df, dn, dl, kc, ec, dc, dlc, bbg;
  for (std::size_t r = r0; r < r1; ++r) {
    const std::int64_t s0 = offset[r], s1 = offset[r + 1];
    float* o = out + r * nc;
    if (s1 <= s0) {
      for (std::size_t c = 0; c < nc; ++c) o[c] = 0.f;
      continue;
    }
    // Nodes: ambient, the samples, ambient, padded to an odd count.
    const std::size_t gas = static_cast<std::size_t>(s1 - s0);
    std::size_t n = gas + 2;
    if (n % 2 == 0) ++n;
    const double ds = step_m[r];
    const bool rich = options_.richardson && n >= 5;
    nk.resize(n);
    nw.resize(n);
    na.assign(n * ns, 0.0);
    nsf.assign(n * ns, 0.0);
    for (std::size_t k = 0; k < n; ++k) {
      const bool is_gas = k >= 1 && k <= gas;
      const double t = is_gas ? temperature[s0 + static_cast<std::int64_t>(k) - 1] : t_amb;
      position(t, &nk[k], &nw[k]);
      if (!is_gas) continue;
      const double n_tot = NumberDensityCm3(pressure_Pa_, t) * 100.0;
      for (std::size_t s = 0; s < ns; ++s) {
        const double xs =
            std::min(1.0, std::max(0.0, static_cast<double>(
                                            fractions[s][s0 + static_cast<std::int64_t>(k) - 1])));
        na[k * ns + s] = has_self_[s] ? n_tot * xs * (1.0 - xs) : n_tot * xs;
        nsf[k * ns + s] = has_self_[s] ? n_tot * xs * xs : 0.0;
      }
    }
    for (std::size_t c = 0; c < nc; ++c) {
      const Bins& b = bins_[c];
      const std::size_t nq = b.weight.size();
      if (nq == 0) {
        o[c] = 0.f;
        continue;
      }
      kf.assign(nq, 0.0);
      kn.assign(nq, 0.0);
      ef.assign(nq, 1.0);
      en.assign(nq, 1.0);
      df.assign(nq, 0.0);
      dn.assign(nq, 0.0);
      dl.assign(nq, 0.0);
      bbg.assign(nq, 0.0);
      if (rich) {
        kc.assign(nq, 0.0);
        ec.assign(nq, 1.0);
        dc.assign(nq, 0.0);
        dlc.assign(nq, 0.0);
      }
      std::size_t kb;
      double wb;
      position(t_bg[r * bg_stride + c], &kb, &wb);
      for (std::size_t q = 0; q < nq; ++q)
        bbg[q] = (1 - wb) * b.fine_planck[kb * nq + q] + wb * b.fine_planck[(kb + 1) * nq + q];
      auto fill = [&](std::size_t k, std::vector<double>& kap, std::vector<double>& e,
                      std::vector<double>& d) {
        const std::size_t k0 = nk[k];
        const double w1 = nw[k], w0 = 1.0 - w1;
        const double* p0 = &b.fine_planck[k0 * nq];
        const double* p1 = p0 + nq;
        for (std::size_t q = 0; q < nq; ++q) {
          kap[q] = 0.0;
          d[q] = w0 * p0[q] + w1 * p1[q] - bbg[q];
        }
        for (std::size_t s = 0; s < ns; ++s) {
          const double ca = na[k * ns + s], cs = nsf[k * ns + s];
          if (ca == 0.0 && cs == 0.0) continue;
          const double* a0 = &b.fine_air[s][k0 * nq];
          const double* a1 = a0 + nq;
          for (int q : b.active[s]) kap[q] += ca * (w0 * a0[q] + w1 * a1[q]);
          if (cs != 0.0) {
            const double* e0 = &b.fine_self[s][k0 * nq];
            const double* e1 = e0 + nq;
            for (int q : b.active[s]) kap[q] += cs * (w0 * e0[q] + w1 * e1[q]);
          }
        }
        for (std::size_t q = 0; q < nq; ++q)
          e[q] = kap[q] > 0.0 ? std::exp(-0.5 * kap[q] * ds) : 1.0;
      };
      fill(0, kf, ef, df);
      if (rich) {
        kc = kf;
        ec = ef;
        dc = df;
      }
      for (std::size_t k = 0; k + 1 < n; ++k) {
        fill(k + 1, kn, en, dn);
        RenderLayer(nq, kf.data(), kn.data(), ef.data(), en.data(), df.data(), dn.data(), ds,
                    dl.data());
        if (rich && (k + 1) % 2 == 0) {
          // Coarse layer over 2 ds: its half-layer transmittances are e^2.
          for (std::size_t q = 0; q < nq; ++q) {
            ec[q] *= ec[q];
            const double enq = en[q] * en[q];
            const double tau = (kc[q] + kn[q]) * ds;
            const double t = ec[q] * enq;
            const double f = tau < 1e-4 ? 1.0 - tau * (0.5 - tau * (1.0 / 6.0)) : (1.0 - t) / tau;
            const double tt = 1.0 - tau * f;
            const double dd = dc[q] - dn[q];
            dlc[q] = dlc[q] * tt + dn[q] * (tau * f) + dd * (f - tt) +
                     0.25 * dd * (kc[q] - kn[q]) * 2.0 * ds * (f * f);
          }
          kc = kn;
          ec = en;
          dc = dn;
        }
        std::swap(kf, kn);
        std::swap(ef, en);
        std::swap(df, dn);
      }
      double sum = 0;
      for (std::size_t q = 0; q < nq; ++q)
        sum += b.weight[q] * (rich ? (4.0 * dl[q] - dlc[q]) / 3.0 : dl[q]);
      o[c] = static_cast<float>(sum);
    }
  }
}

void BinnedModel::CheckPath(const Path& path) const {
  qogi::CheckPath(path);
  Require(path.num_species == species_.size(), "the path has " + std::to_string(path.num_species) +
                                                   " species; the model has " +
                                                   std::to_string(species_.size()));
  Require(std::abs(path.pressure_Pa - pressure_Pa_) <= 1e-6 * pressure_Pa_,
          "path pressure " + FormatNumber(path.pressure_Pa) +
              " Pa differs from the tables' pressure " + FormatNumber(pressure_Pa_) +
              " Pa; build the model at the scene's pressure");
  for (double t : path.temperature_K)
    if (t < t_min_ - 1e-9 || t > t_max_ + 1e-9)
      throw std::invalid_argument("path temperature " + FormatNumber(t) +
                                  " K is outside the cross-section tables' range [" +
                                  FormatNumber(t_min_) + ", " + FormatNumber(t_max_) + "] K");
}

std::vector<double> BinnedModel::BandRadiance(const GaussianPlume& plume,
                                              const std::vector<double>& t_bg) const {
  plume.Check();
  Require(plume.peak_fractions.size() == species_.size(),
          "peak_fractions has " + std::to_string(plume.peak_fractions.size()) +
              " values; the model has " + std::to_string(species_.size()) + " species");
  Require(std::abs(plume.pressure_Pa - pressure_Pa_) <= 1e-6 * pressure_Pa_,
          "plume pressure " + FormatNumber(plume.pressure_Pa) +
              " Pa differs from the tables' pressure " + FormatNumber(pressure_Pa_) + " Pa");
  Path path = GaussianPath<double>(plume.peak_fractions.data(), plume.peak_temperature_K,
                                   plume.ambient_temperature_K, plume.sigma_m);
  return BandRadiance(path, t_bg);
}

std::vector<double> BinnedModel::BandRadiance(const Path& path,
                                              const std::vector<double>& t_bg_in) const {
  CheckPath(path);
  const std::vector<double> t_bg = BackgroundTemperaturesPerChannel(t_bg_in, channels_.size());
  std::vector<double> out(channels_.size());
  Contrast<double>(path, t_bg.data(), out.data());
  for (std::size_t c = 0; c < out.size(); ++c) out[c] += channels_[c].BandRadiance(t_bg[c]);
  return out;
}

BinnedModel::BinView BinnedModel::bins(std::size_t c) const {
  Require(c < bins_.size(), "channel index " + std::to_string(c) +
                                " is out of range; the model has " + std::to_string(bins_.size()) +
                                " channels");
  const Bins& b = bins_[c];
  BinView v;
  v.num_bins = b.weight.size();
  v.num_segments = b.num_segments;
  v.num_chebyshev = options_.chebyshev_nodes;
  v.weight = b.weight.data();
  v.segment = b.segment.data();
  v.planck_map = b.planck_map.data();
  v.segment_nodes = b.segment_nodes.data();
  return v;
}

bool BinnedModel::BinAbsorbs(std::size_t c, std::size_t s, std::size_t q) const {
  const std::vector<int>& a = bins_[c].active[s];
  return std::binary_search(a.begin(), a.end(), static_cast<int>(q));
}

void BinnedModel::MeanPlanck(std::size_t c, double t, double* out) const {
  const Bins& b = bins_[c];
  const std::size_t nq = b.weight.size();
  const int nm = options_.chebyshev_nodes;
  std::vector<double> node_b(b.num_segments * nm);
  for (std::size_t g = 0; g < b.num_segments; ++g)
    for (int m = 0; m < nm; ++m) node_b[g * nm + m] = PlanckT(b.segment_nodes[g * nm + m], t);
  for (std::size_t q = 0; q < nq; ++q) {
    const double* row = &b.planck_map[q * nm];
    const double* nb = &node_b[b.segment[q] * nm];
    double v = 0.0;
    for (int m = 0; m < nm; ++m) v += row[m] * nb[m];
    out[q] = v;
  }
}

void BinnedModel::BinCrossSections(std::size_t c, std::size_t s, double t, double* air,
                                   double* self) const {
  const Bins& b = bins_[c];
  const std::size_t nq = b.weight.size();
  const TemperatureStencil st = MakeTemperatureStencil(table_temperatures_[s], t);
  auto fill = [&](const std::vector<double>& sig, const std::vector<double>& lsig,
                  const std::vector<char>& positive, double* out) {
    std::fill(out, out + nq, 0.0);
    for (int q : b.active[s]) {
      if (positive[q]) {
        double l = 0.0;
        for (int a = 0; a < st.count; ++a) l += st.weight[a] * lsig[(st.first + a) * nq + q];
        out[q] = std::exp(l);
      } else {
        out[q] = InterpolateInTemperature<double>(
            st, st.weight, st.frac, [&](std::size_t k) { return sig[k * nq + q]; },
            [&](std::size_t k) { return lsig[k * nq + q]; });
      }
    }
  };
  fill(b.sigma_air[s], b.log_sigma_air[s], b.positive_air[s], air);
  if (has_self_[s] && self) fill(b.sigma_self[s], b.log_sigma_self[s], b.positive_self[s], self);
}

}  // namespace qogi
