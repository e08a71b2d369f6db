#include "engine/rte/binned_model.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "engine/optics/planck.h"
#include "engine/rte/exact_model.h"
#include "engine/util/check.h"

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
  for (std::size_t c = 0; c < channels_.size(); ++c) BuildChannel(c, tables);
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
    if (it == bin_of_key.end()) it = bin_of_key.emplace(key, static_cast<int>(bin_of_key.size())).first;
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
    for (std::size_t k = 0; k < node_b.size(); ++k) node_b[k] = PlanckUnchecked(b.segment_nodes[k], temp);
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

void BinnedModel::CheckPath(const Path& path) const {
  qogi::CheckPath(path);
  Require(path.num_species == species_.size(),
          "the path has " + std::to_string(path.num_species) + " species; the model has " +
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
  Require(t_bg_in.size() == 1 || t_bg_in.size() == channels_.size(),
          "background_temperature_K needs 1 value or one per channel (" +
              std::to_string(channels_.size()) + "); got " + std::to_string(t_bg_in.size()));
  std::vector<double> t_bg(channels_.size(), t_bg_in[0]);
  for (std::size_t c = 0; c < t_bg.size(); ++c) {
    if (t_bg_in.size() > 1) t_bg[c] = t_bg_in[c];
    CheckInRange(t_bg[c], 100.0, 2000.0, "background_temperature_K", "K");
  }
  std::vector<double> out(channels_.size());
  Contrast<double>(path, t_bg.data(), out.data());
  for (std::size_t c = 0; c < out.size(); ++c) out[c] += channels_[c].BandRadiance(t_bg[c]);
  return out;
}

}  // namespace qogi
