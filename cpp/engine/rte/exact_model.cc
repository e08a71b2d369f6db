#include "engine/rte/exact_model.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "engine/optics/planck.h"
#include "engine/rte/march.h"
#include "engine/util/check.h"

namespace qogi {

void ExactModelOptions::Check() const {
  Require(num_nodes >= 3 && num_nodes <= 100000,
          "num_nodes must be within [3, 100000]; got " + std::to_string(num_nodes));
  CheckInRange(z_max, 3.0, 12.0, "z_max", "sigma");
  ResolveThreads(num_threads);
}

void AtmosphericPath::Check() const {
  CheckNonNegative(distance_m, "atmosphere distance_m", "m");
  CheckInRange(temperature_K, 180.0, 340.0, "atmosphere temperature_K", "K");
  CheckInRange(relative_humidity, 0.0, 1.0, "atmosphere relative_humidity");
  CheckInRange(co2_ppm, 0.0, 1e5, "atmosphere co2_ppm", "ppm");
  CheckInRange(ch4_ppm, 0.0, 1e5, "atmosphere ch4_ppm", "ppm");
}

double SaturationVaporPressure(double temperature_K) {
  const double t = temperature_K - 273.15;  // Buck (1996), over water
  return 611.21 * std::exp((18.678 - t / 234.5) * (t / (257.14 + t)));
}

void CheckModelTables(const std::vector<AbsorberTable>& tables, double* t_min, double* t_max) {
  Require(!tables.empty(), "a forward model needs at least one absorber table");
  std::set<std::string> names;
  *t_min = 0;
  *t_max = 1e30;
  for (const auto& t : tables) {
    t.Check();
    Require(names.insert(t.species).second, "species '" + t.species + "' has two tables");
    Require(std::abs(t.pressure_Pa - tables[0].pressure_Pa) <= 1e-6 * tables[0].pressure_Pa,
            "all tables must be at the same pressure; '" + t.species + "' is at " +
                FormatNumber(t.pressure_Pa) + " Pa, '" + tables[0].species + "' at " +
                FormatNumber(tables[0].pressure_Pa) + " Pa");
    *t_min = std::max(*t_min, t.temperatures_K.front());
    *t_max = std::min(*t_max, t.temperatures_K.back());
  }
  Require(*t_min < *t_max, "the tables' temperature ranges do not overlap");
}

ChannelGrid MakeChannelGrid(const SpectralResponse& channel,
                            const std::vector<AbsorberTable>& tables) {
  ChannelGrid g;
  double dnu = tables[0].dnu_cm1, lo = 1e30, hi = -1e30;
  for (const auto& t : tables) {
    dnu = std::min(dnu, t.dnu_cm1);
    lo = std::min(lo, t.nu0_cm1);
    hi = std::max(hi, t.nu_max_cm1());
  }
  const double ref = tables[0].nu0_cm1;
  lo = std::max(lo, channel.min_nu_cm1());
  hi = std::min(hi, channel.max_nu_cm1());
  g.index.resize(tables.size());
  g.frac.resize(tables.size());
  g.dnu_cm1 = dnu;
  if (lo > hi) return g;
  const long i0 = static_cast<long>(std::ceil((lo - ref) / dnu - 1e-9));
  const long i1 = static_cast<long>(std::floor((hi - ref) / dnu + 1e-9));
  for (long i = i0; i <= i1; ++i) {
    const double nu = ref + i * dnu;
    const double r = channel.Evaluate(nu);
    if (r <= 0) continue;
    bool any = false;
    std::vector<long> idx(tables.size(), -1);
    std::vector<double> fr(tables.size(), 0.0);
    for (std::size_t s = 0; s < tables.size(); ++s) {
      const auto& t = tables[s];
      const double p = (nu - t.nu0_cm1) / t.dnu_cm1;
      if (p < -1e-9 || p > (t.n_nu - 1) + 1e-9) continue;
      long j = static_cast<long>(std::floor(p + 1e-9));
      j = std::min<long>(std::max<long>(j, 0), static_cast<long>(t.n_nu) - 2);
      idx[s] = j;
      fr[s] = std::min(1.0, std::max(0.0, p - j));
      any = true;
    }
    if (!any) continue;
    g.nu_cm1.push_back(nu);
    g.grid_index.push_back(i);
    g.weight.push_back(r * dnu);
    for (std::size_t s = 0; s < tables.size(); ++s) {
      g.index[s].push_back(idx[s]);
      g.frac[s].push_back(fr[s]);
    }
  }
  return g;
}

void PlanckOnGrid(const ChannelGrid& g, std::size_t begin, std::size_t end, double t, double* out) {
  // exp(c2 nu / T) along runs of adjacent grid points by a multiplicative
  // recurrence (relative rounding error ~1e-12 over 1e5 steps), exp elsewhere.
  const double a = constants::kC2 / t;
  const double step = std::exp(a * g.dnu_cm1);
  double e = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const double nu = g.nu_cm1[i];
    if (i > begin && g.grid_index[i] == g.grid_index[i - 1] + 1 && (i - begin) % 512 != 0)
      e *= step;
    else
      e = std::exp(a * nu);
    out[i - begin] = std::isfinite(e) ? constants::kC1 * nu * nu * nu / (e - 1.0) : 0.0;
  }
}

ExactModel::ExactModel(std::vector<SpectralResponse> channels, std::vector<AbsorberTable> tables,
                       ExactModelOptions options)
    : channels_(std::move(channels)), tables_(std::move(tables)), options_(options) {
  options_.Check();
  Require(!channels_.empty(), "a forward model needs at least one channel");
  CheckModelTables(tables_, &t_min_, &t_max_);
  for (const auto& ch : channels_) grids_.push_back(MakeChannelGrid(ch, tables_));
  for (const auto& t : tables_) {
    log_air_.push_back(LogValues(t.sigma_air));
    log_self_.push_back(LogValues(t.sigma_self));
  }
}

std::vector<std::string> ExactModel::species() const {
  std::vector<std::string> out;
  for (const auto& t : tables_) out.push_back(t.species);
  return out;
}

std::vector<double> ExactModel::molar_masses() const {
  std::vector<double> out;
  for (const auto& t : tables_) out.push_back(t.molar_mass());
  return out;
}

void ExactModel::CheckPathAgainstTables(const Path& path) const {
  CheckPath(path);
  Require(path.num_species == tables_.size(), "the path has " + std::to_string(path.num_species) +
                                                  " species; the model has " +
                                                  std::to_string(tables_.size()));
  Require(std::abs(path.pressure_Pa - tables_[0].pressure_Pa) <= 1e-6 * tables_[0].pressure_Pa,
          "path pressure " + FormatNumber(path.pressure_Pa) +
              " Pa differs from the tables' pressure " + FormatNumber(tables_[0].pressure_Pa) +
              " Pa; build tables at the scene's pressure");
  for (double t : path.temperature_K)
    if (t < t_min_ - 1e-9 || t > t_max_ + 1e-9)
      throw std::invalid_argument("path temperature " + FormatNumber(t) +
                                  " K is outside the cross-section tables' range [" +
                                  FormatNumber(t_min_) + ", " + FormatNumber(t_max_) +
                                  "] K; extend the tables' temperature grid");
}

Path ExactModel::GaussianPath(const GaussianPlume& plume) const {
  plume.Check();
  Require(plume.peak_fractions.size() == tables_.size(),
          "peak_fractions has " + std::to_string(plume.peak_fractions.size()) +
              " values; the model has " + std::to_string(tables_.size()) + " species");
  Path path = SampleGaussianPlume<double>(plume.peak_fractions.data(), tables_.size(),
                                          plume.peak_temperature_K, plume.ambient_temperature_K,
                                          plume.sigma_m, plume.pressure_Pa, options_.num_nodes,
                                          options_.z_max);
  CheckPathAgainstTables(path);
  return path;
}

double ExactModel::ContrastSum(std::size_t c, const Path& path, double t_bg, std::size_t begin,
                               std::size_t end, const std::vector<double>* atm_t,
                               std::vector<double>* spectral_out) const {
  const ChannelGrid& g = grids_[c];
  const std::size_t n = end - begin;
  const std::size_t ns = tables_.size();
  std::vector<double> k_far(n), k_near(n), d_far(n), d_near(n), dl(n, 0.0), b_bg(n);
  PlanckOnGrid(g, begin, end, t_bg, b_bg.data());

  auto fill_node = [&](std::size_t k, double* kappa, double* d) {
    const double t = path.temperature_K[k];
    const double n_tot = NumberDensityCm3(path.pressure_Pa, t) * 100.0;  // per cm3 x cm/m
    std::fill(kappa, kappa + n, 0.0);
    for (std::size_t s = 0; s < ns; ++s) {
      const double x = path.fraction[k * ns + s];
      if (x <= 0) continue;
      const AbsorberTable& tab = tables_[s];
      const TemperatureStencil st = MakeTemperatureStencil(tab.temperatures_K, t);
      const double nx = n_tot * x;
      const std::vector<long>& idx = g.index[s];
      const std::vector<double>& fr = g.frac[s];
      for (std::size_t i = 0; i < n; ++i) {
        const long j = idx[begin + i];
        if (j < 0) continue;
        const double w = fr[begin + i];
        auto sigma = [&](const std::vector<float>& v, const std::vector<double>& lv) {
          const double lo = SigmaAt(v, lv, tab.n_nu, st, j);
          return w > 0 ? lo + w * (SigmaAt(v, lv, tab.n_nu, st, j + 1) - lo) : lo;
        };
        const double sa = sigma(tab.sigma_air, log_air_[s]);
        const double sig =
            tab.has_self() ? (1 - x) * sa + x * sigma(tab.sigma_self, log_self_[s]) : sa;
        kappa[i] += nx * sig;
      }
    }
    PlanckOnGrid(g, begin, end, t, d);
    for (std::size_t i = 0; i < n; ++i) d[i] -= b_bg[i];
  };

  const std::size_t nn = path.size();
  const bool rich = options_.richardson && nn >= 5 && nn % 2 == 1;
  // A symmetric path (a Gaussian plume) has the same node state at k and
  // nn-1-k: compute the first half once and reuse it.
  bool symmetric = true;
  for (std::size_t k = 0; k < nn / 2 && symmetric; ++k) {
    symmetric = path.temperature_K[k] == path.temperature_K[nn - 1 - k];
    for (std::size_t s = 0; s < ns && symmetric; ++s)
      symmetric = path.fraction[k * ns + s] == path.fraction[(nn - 1 - k) * ns + s];
  }
  const std::size_t half = symmetric ? nn / 2 + 1 : 0;
  std::vector<double> saved_k(half * n), saved_d(half * n);
  auto node = [&](std::size_t k, double* kappa, double* d) {
    if (symmetric && k >= half) {
      const std::size_t m = nn - 1 - k;
      std::copy(&saved_k[m * n], &saved_k[m * n] + n, kappa);
      std::copy(&saved_d[m * n], &saved_d[m * n] + n, d);
      return;
    }
    fill_node(k, kappa, d);
    if (symmetric) {
      std::copy(kappa, kappa + n, &saved_k[k * n]);
      std::copy(d, d + n, &saved_d[k * n]);
    }
  };
  std::vector<double> k_coarse, d_coarse, dl_coarse;
  node(0, k_far.data(), d_far.data());
  if (rich) {
    k_coarse = k_far;
    d_coarse = d_far;
    dl_coarse.assign(n, 0.0);
  }
  for (std::size_t k = 0; k + 1 < nn; ++k) {
    node(k + 1, k_near.data(), d_near.data());
    MarchLayer(n, k_far.data(), k_near.data(), d_far.data(), d_near.data(),
               path.position_m[k + 1] - path.position_m[k], dl.data());
    if (rich && (k + 1) % 2 == 0) {
      MarchLayer(n, k_coarse.data(), k_near.data(), d_coarse.data(), d_near.data(),
                 path.position_m[k + 1] - path.position_m[k - 1], dl_coarse.data());
      k_coarse = k_near;
      d_coarse = d_near;
    }
    std::swap(k_far, k_near);
    std::swap(d_far, d_near);
  }
  if (rich)
    for (std::size_t i = 0; i < n; ++i) dl[i] = (4.0 * dl[i] - dl_coarse[i]) / 3.0;
  double sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    double v = dl[i];
    if (atm_t) {
      const double ta = (*atm_t)[begin + i];
      v = v * ta;
    }
    if (spectral_out) (*spectral_out)[begin + i] = v;
    sum += g.weight[begin + i] * v;
  }
  return sum;
}

std::vector<double> ExactModel::BandRadiance(const GaussianPlume& plume,
                                             const std::vector<double>& t_bg,
                                             const AtmosphericPath& atmosphere,
                                             const RunControl* control) const {
  return BandRadiance(GaussianPath(plume), t_bg, atmosphere, control);
}

std::vector<double> ExactModel::BandRadiance(const Path& path, const std::vector<double>& t_bg_in,
                                             const AtmosphericPath& atmosphere,
                                             const RunControl* control) const {
  CheckPathAgainstTables(path);
  atmosphere.Check();
  const std::vector<double> t_bg = BackgroundTemperaturesPerChannel(t_bg_in, channels_.size());
  std::vector<double> out(channels_.size());
  for (std::size_t c = 0; c < channels_.size(); ++c) {
    const ChannelGrid& g = grids_[c];
    const std::size_t n = g.nu_cm1.size();
    // Atmospheric transmittance on the grid.
    std::vector<double> atm_t;
    double atm_term = 0;
    if (atmosphere.distance_m > 0) {
      atm_t.assign(n, 1.0);
      const double ta = atmosphere.temperature_K;
      Require(ta >= t_min_ && ta <= t_max_, "atmosphere temperature outside the tables' range");
      const double n_air = NumberDensityCm3(path.pressure_Pa, ta) * 100.0;
      for (std::size_t s = 0; s < tables_.size(); ++s) {
        double x = 0;
        if (tables_[s].species == "H2O")
          x = atmosphere.relative_humidity * SaturationVaporPressure(ta) / path.pressure_Pa;
        else if (tables_[s].species == "CO2")
          x = atmosphere.co2_ppm * 1e-6;
        else if (tables_[s].species == "CH4")
          x = atmosphere.ch4_ppm * 1e-6;
        if (x <= 0) continue;
        const AbsorberTable& tab = tables_[s];
        const TemperatureStencil st = MakeTemperatureStencil(tab.temperatures_K, ta);
        for (std::size_t i = 0; i < n; ++i) {
          const long j = g.index[s][i];
          if (j < 0) continue;
          const double w = g.frac[s][i];
          const double lo = SigmaAt(tab.sigma_air, log_air_[s], tab.n_nu, st, j);
          const double sa =
              w > 0 ? lo + w * (SigmaAt(tab.sigma_air, log_air_[s], tab.n_nu, st, j + 1) - lo) : lo;
          atm_t[i] *= std::exp(-n_air * x * sa * atmosphere.distance_m);
        }
      }
      for (std::size_t i = 0; i < n; ++i)
        atm_term += g.weight[i] *
                    (PlanckUnchecked(g.nu_cm1[i], ta) - PlanckUnchecked(g.nu_cm1[i], t_bg[c])) *
                    (1 - atm_t[i]);
    }
    const std::size_t chunk = 2048;
    const std::size_t num_chunks = (n + chunk - 1) / chunk;
    std::vector<double> partial(num_chunks, 0.0);
    ParallelFor(
        num_chunks, 1,
        [&](std::size_t b, std::size_t e) {
          for (std::size_t q = b; q < e; ++q)
            partial[q] = ContrastSum(c, path, t_bg[c], q * chunk, std::min(n, (q + 1) * chunk),
                                     atm_t.empty() ? nullptr : &atm_t, nullptr);
        },
        options_.num_threads, control);
    double contrast = atm_term;
    for (double p : partial) contrast += p;
    out[c] = channels_[c].BandRadiance(t_bg[c]) + contrast;
  }
  return out;
}

void ExactModel::SpectralContrast(std::size_t channel, const Path& path, double t_bg,
                                  std::vector<double>* nu_cm1,
                                  std::vector<double>* contrast) const {
  Require(channel < channels_.size(), "channel index " + std::to_string(channel) +
                                          " out of range [0, " + std::to_string(channels_.size()) +
                                          ")");
  CheckPathAgainstTables(path);
  CheckInRange(t_bg, 100.0, 2000.0, "background_temperature_K", "K");
  const ChannelGrid& g = grids_[channel];
  *nu_cm1 = g.nu_cm1;
  contrast->assign(g.nu_cm1.size(), 0.0);
  ContrastSum(channel, path, t_bg, 0, g.nu_cm1.size(), nullptr, contrast);
}

}  // namespace qogi
