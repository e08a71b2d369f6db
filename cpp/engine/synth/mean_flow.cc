#include "engine/synth/mean_flow.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "engine/util/check.h"

namespace qogi::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kStationDoubles = sizeof(Station) / sizeof(double);
static_assert(sizeof(Station) % sizeof(double) == 0, "Station must hold only doubles");
// Largest change of the structure age psi and of s (in widths sigma_c) over
// one half of a pair of stations.
constexpr double kMaxDpsi = 0.05;
constexpr double kMaxDsSigma = 0.15;
// Linear-density factor a cluster of puffs may reach (see sigma_puff below).
constexpr double kClusterDensity = 2.0;
// Length over which entrainment switches on after the laminar column [exit
// diameters].
constexpr double kEntrainmentOnset = 1.5;
// The mean centreline partial density stays below this fraction of the pure
// gas's density.
constexpr double kPureMargin = 0.995;
// RMS turbulent velocity of a plume relative to its top-hat excess velocity
// (axial intensity ~0.25-0.3 of the Gaussian centreline velocity 2 (V - W_a);
// Papanicolaou & List 1988, Wang & Law 2002).
constexpr double kPlumeTurbulence = 0.3;

// Integral-model state: mixture mass flux, momentum flux (horizontal along
// the wind, vertical), axis position (horizontal along the wind, height).
struct OdeState {
  double mass_flux, p_h, p_z, h, z;
};

struct Top {
  double t_h, t_z, v, y, rho, b, excess, ambient_axial, temperature;
};

}  // namespace

Station LerpStation(const Station& a, const Station& b, double u) {
  double da[kStationDoubles], db[kStationDoubles], out[kStationDoubles];
  std::memcpy(da, &a, sizeof(Station));
  std::memcpy(db, &b, sizeof(Station));
  for (int i = 0; i < kStationDoubles; ++i) out[i] = da[i] + u * (db[i] - da[i]);
  Station st;
  std::memcpy(&st, out, sizeof(Station));
  return st;
}

namespace {

double SmoothStep(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * (3 - 2 * u);
}

}  // namespace

double MeanFlow::PuffSpeed(const Station& st, double r2) {
  const double phi = st.development;
  double profile = 1 - phi;
  if (phi > 0)
    profile += phi * st.profile_k *
               (st.profile_eps +
                (1 - st.profile_eps) * 2 * st.profile_beta * std::exp(-r2 / st.profile_b2));
  return st.ambient_axial_m_s + st.excess_m_s * profile;
}

namespace {

// The integral model's right-hand side and the top-hat variables of a state
// (the equations at the top of mean_flow.h).
struct AxisModel {
  const PlumeModelOptions& opt;
  const MixingModel& mixing;
  double q, d, v0, l_lam, rho_a, u_wind, ri_p, onset;

  Top TopHat(const OdeState& st) const {
    Top o;
    const double pm = std::hypot(st.p_h, st.p_z);
    o.t_h = st.p_h / pm;
    o.t_z = st.p_z / pm;
    o.v = pm / st.mass_flux;
    o.y = std::min(1.0, q / st.mass_flux);
    o.temperature = mixing.TemperatureAtMassFraction(o.y);
    o.rho = mixing.DensityAtMassFraction(o.y);
    o.b = std::sqrt(st.mass_flux / (kPi * o.rho * o.v));
    o.ambient_axial = std::max(0.0, u_wind * o.t_h);
    o.excess = o.v - u_wind * o.t_h;
    return o;
  }

  OdeState Rhs(double s_here, const OdeState& st) const {
    const Top o = TopHat(st);
    const double on = SmoothStep((s_here - l_lam) / (onset * d));
    const double dv = o.excess;
    const double ri = kGravity * std::abs(rho_a - o.rho) * o.b / (rho_a * std::max(dv * dv, 1e-30));
    const double alpha =
        opt.alpha_jet + (opt.alpha_plume - opt.alpha_jet) * std::min(1.0, ri / ri_p);
    const double e = on * 2 * kPi * o.b *
                     (alpha * std::sqrt(o.rho * rho_a) * std::abs(dv) +
                      opt.beta_crossflow * rho_a * u_wind * std::abs(o.t_z));
    OdeState dd;
    dd.mass_flux = e;
    dd.p_h = e * u_wind;
    dd.p_z = kPi * o.b * o.b * kGravity * (rho_a - o.rho);
    dd.h = o.t_h;
    dd.z = o.t_z;
    return dd;
  }
};

OdeState Axpy(const OdeState& a, double k, const OdeState& b) {
  return OdeState{a.mass_flux + k * b.mass_flux, a.p_h + k * b.p_h, a.p_z + k * b.p_z,
                  a.h + k * b.h, a.z + k * b.z};
}

// A point of the marched axis.
struct Fine {
  double s, pos[3], t[3];
  Top top;
};

// Distance of p outside the box [lo, hi] (0 inside).
double Outside(const double p[3], const std::array<double, 3>& lo,
               const std::array<double, 3>& hi) {
  double s2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double e = std::max({lo[k] - p[k], 0.0, p[k] - hi[k]});
    s2 += e * e;
  }
  return std::sqrt(s2);
}

// Step 1: the integral model marched (RK4) from the exit until the axis is
// stop_distance_m (plus the plume's reach) outside the box, storing every
// step; *s_view_end: where the axis first leaves the box (-1: never).
std::vector<Fine> MarchAxis(const AxisModel& m, const double ew[3], double x0, double z0,
                            const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                            double stop_distance_m, double* s_view_end_out) {
  const double q_ = m.q, d_ = m.d, v0_ = m.v0, u_wind = m.u_wind;
  auto top = [&](const OdeState& st) { return m.TopHat(st); };
  auto rhs = [&](double s_here, const OdeState& st) { return m.Rhs(s_here, st); };
  auto axpy = Axpy;
  auto outside = [&](const double p[3]) { return Outside(p, lo, hi); };
  double box_size = 0;
  for (int k = 0; k < 3; ++k) box_size = std::max(box_size, hi[k] - lo[k]);

  // --- integrate the ODE (RK4), storing every step ---------------------------
  std::vector<Fine> fine;
  OdeState st{q_, q_ * v0_, 0.0, 0.0, z0};
  st.p_z = st.p_h;  // vertical exit
  st.p_h = 0.0;
  double s = 0;
  double s_view_end = -1;  // where the axis first leaves the box
  const double s_cap = 100.0 * std::max(box_size, 10 * d_);
  for (std::size_t steps = 0;; ++steps) {
    // A state gone non-finite (a release no plume model can carry) would
    // never reach the box's edge or the cap: stop with an error instead.
    if (!std::isfinite(s) || !std::isfinite(st.z) || !std::isfinite(st.h) || steps > 2000000)
      throw std::invalid_argument(
          "the plume model did not converge for this release (exit "
          "diameter " +
          FormatNumber(d_) +
          " m): its state became "
          "non-finite or it took more than 2e6 steps");
    Fine f;
    f.s = s;
    f.top = top(st);
    for (int k = 0; k < 3; ++k) {
      f.pos[k] = (k == 2 ? st.z : (k == 0 ? x0 : 0.0) + st.h * ew[k]);
      f.t[k] = f.top.t_h * ew[k] + (k == 2 ? f.top.t_z : 0.0);
    }
    fine.push_back(f);
    if (f.top.v < 1e-3 * v0_ || (u_wind == 0 && f.top.t_z < 0.5))
      throw std::invalid_argument(
          "the plume stalls " + FormatNumber(s) +
          " m from the exit (a release heavier than the ambient air in still air "
          "forms a fountain, which the plume model does not cover); heat the gas, "
          "add wind or change the composition");
    // Puff centres stray up to ~2.5 b from the axis and reach 6 widths beyond.
    const double out = outside(f.pos);
    if (out > 0 && s_view_end < 0) s_view_end = s;
    if (out > stop_distance_m + 4 * f.top.b || s > s_cap) break;
    const double ds = d_ / 40.0 * std::max(1.0, s / (10 * d_));
    const OdeState k1 = rhs(s, st);
    const OdeState k2 = rhs(s + ds / 2, axpy(st, ds / 2, k1));
    const OdeState k3 = rhs(s + ds / 2, axpy(st, ds / 2, k2));
    const OdeState k4 = rhs(s + ds, axpy(st, ds, k3));
    st = axpy(st, ds / 6, k1);
    st = axpy(st, ds / 3, k2);
    st = axpy(st, ds / 3, k3);
    st = axpy(st, ds / 6, k4);
    s += ds;
  }

  *s_view_end_out = s_view_end;
  return fine;
}

// The profile parameters the similarity step needs besides the options.
struct ProfileInputs {
  double q, rho_e, l_lam, l_dev, c_psi;
  double ep[3];  // n2: horizontal, across the wind
};

// Step 2: the similarity profiles (widths, speeds, puff sizes, turbulence)
// at each marched point, and the structure age psi and travel time
// integrated along s.
std::vector<Station> SimilarityProfiles(const std::vector<Fine>& fine, const Release& release,
                                        const PlumeModelOptions& opt, const ProfileInputs& in) {
  const double q_ = in.q, rho_e = in.rho_e, l_lam_ = in.l_lam, l_dev_ = in.l_dev, c_psi_ = in.c_psi;
  const double* ep = in.ep;
  const double lambda = opt.concentration_width_ratio;
  const double f_inf = opt.puff_size_fraction;
  const double eps = opt.edge_speed_fraction;
  const double tau = release.release_turbulence;
  const double sigma_a = release.AmbientRmsVelocity();
  const double l_a = std::max(1e-6, sigma_a * release.ambient_time_scale_s);
  auto profiles = [&](const Fine& f) {
    Station o{};
    o.s = f.s;
    for (int k = 0; k < 3; ++k) {
      o.pos[k] = f.pos[k];
      o.tangent[k] = f.t[k];
      o.n2[k] = ep[k];
    }
    // n1 = n2 x tangent
    o.n1[0] = ep[1] * f.t[2] - ep[2] * f.t[1];
    o.n1[1] = ep[2] * f.t[0] - ep[0] * f.t[2];
    o.n1[2] = ep[0] * f.t[1] - ep[1] * f.t[0];
    const Top& t = f.top;
    o.radius_m = t.b;
    o.velocity_m_s = t.v;
    o.excess_m_s = std::max(0.0, t.excess);
    o.ambient_axial_m_s = t.ambient_axial;
    o.mass_fraction = t.y;
    o.temperature_K = t.temperature;
    o.density = t.rho;
    const double phi = l_dev_ > 0 ? SmoothStep((f.s - l_lam_) / l_dev_) : 1.0;
    o.development = phi;
    const double kappa = (1 - phi) / std::sqrt(2.0) + phi * lambda / 2;
    o.sigma_c = kappa * t.b;
    // Mean-speed weights for the concentration-weighted speed W_m below.
    auto mean_speed = [&](double sc) {
      const double bg2q = t.b * t.b / 4;
      return std::max(0.0, t.ambient_axial) +
             std::max(0.0, t.excess) * ((1 - phi) + phi * 2 * bg2q / (bg2q + sc * sc));
    };
    // The Gaussian profile's centreline Q / (2 pi sigma_c^2 W_m) may not exceed
    // the pure gas's density (it would while the top-hat Y is still near 1 and
    // the profile turns Gaussian): widen sigma_c where needed, keeping a margin
    // of 1 - kPureMargin for the puffs' fluctuations.
    for (int it = 0; it < 20; ++it) {
      const double floor_sc =
          std::sqrt(q_ / (2 * kPi * mean_speed(o.sigma_c) * kPureMargin * rho_e));
      if (o.sigma_c >= floor_sc * (1 - 1e-12)) break;
      o.sigma_c = floor_sc;
    }
    // Puffs shrink (and structures form) only as fast as the gas is diluted: a
    // cluster of puffs holding a whole cross-section's gas at twice the mean
    // linear density must stay below the pure gas's density, so
    // (sigma_puff / sigma_c)^2 >= 2 rho_c / rho_exit.
    const double rho_c =
        q_ / (2 * kPi * o.sigma_c * o.sigma_c *
              (o.ambient_axial_m_s +
               o.excess_m_s * ((1 - phi) + phi * 2 * (t.b * t.b / 4) /
                                               (t.b * t.b / 4 + o.sigma_c * o.sigma_c))));
    const double frac = std::clamp(
        std::max(1 - phi * tau * (1 - f_inf), std::sqrt(kClusterDensity * rho_c / rho_e)), 0.0,
        1.0);
    // Offsets start smoothly where the puffs first become smaller than the
    // plume: g = 1 - f^2 -> g smoothstep(g / 0.3)^2 keeps the offset scale's
    // first and second derivatives finite there.
    const double g_raw = 1 - frac * frac;
    const double onset = SmoothStep(g_raw / 0.3);
    o.sigma_puff = o.sigma_c * std::sqrt(1 - g_raw * onset * onset);
    const double bg2 = t.b * t.b / 2;
    const double sc2 = o.sigma_c * o.sigma_c;
    const double sk2 = o.sigma_puff * o.sigma_puff;
    // Concentration-weighted mean of the Gaussian excess-velocity profile.
    const double mean_gauss = 2 * (bg2 / 2) / (bg2 / 2 + sc2);
    o.mass_weighted_speed = o.ambient_axial_m_s + o.excess_m_s * ((1 - phi) + phi * mean_gauss);
    o.profile_b2 = bg2 + 2 * sk2;
    o.profile_beta = bg2 / o.profile_b2;
    o.profile_eps = eps;
    o.profile_k = mean_gauss / (eps + (1 - eps) * mean_gauss);
    const double s2 = std::max(0.0, sc2 - sk2);
    double vf = 0;
    if (s2 > 0) {
      // Flux-weighted offsets: the concentration-space offsets N(0, s2) times
      // the puff speed, a two-Gaussian mixture matched by its second moment.
      const double a1 = o.ambient_axial_m_s + o.excess_m_s * ((1 - phi) + phi * o.profile_k * eps);
      const double a2 = phi * o.excess_m_s * o.profile_k * (1 - eps) * 2 * o.profile_beta *
                        o.profile_b2 / (o.profile_b2 + 2 * s2);
      const double v2 = 1.0 / (1.0 / s2 + 2.0 / o.profile_b2);
      vf = (a1 + a2) > 0 ? (a1 * s2 + a2 * v2) / (a1 + a2) : s2;
    }
    o.offset_scale = std::sqrt(vf);
    o.turbulence = phi * SmoothStep((1 - rho_c / rho_e) / 0.5);
    o.centre_partial_density = q_ / (2 * kPi * sc2 * o.mass_weighted_speed);
    // Internal turbulent velocity: the plume's own (a fraction of its excess
    // velocity) and the ambient eddies no larger than the plume (Kolmogorov
    // scaling sigma_a (sigma_c / L_a)^(1/3), L_a = sigma_a T_a). psi counts
    // eddy turnovers sigma_c / u_int, in units of structure_persistence.
    const double u_amb = sigma_a > 0 ? sigma_a * std::cbrt(std::min(1.0, o.sigma_c / l_a)) : 0.0;
    const double u_own = kPlumeTurbulence * o.excess_m_s;
    o.internal_turbulence_m_s =
        std::max(std::sqrt(u_own * u_own + u_amb * u_amb), 1e-3 * o.mass_weighted_speed);
    o.ds_dpsi = c_psi_ * o.sigma_c * o.mass_weighted_speed / o.internal_turbulence_m_s;
    o.axial_turbulence =
        opt.axial_turbulence * tau * o.turbulence *
        std::min(1.0, o.internal_turbulence_m_s / (kPlumeTurbulence * o.mass_weighted_speed));
    return o;
  };
  std::vector<Station> fs(fine.size());
  for (std::size_t i = 0; i < fine.size(); ++i) fs[i] = profiles(fine[i]);
  fs[0].psi = 0;
  fs[0].time_s = 0;
  for (std::size_t i = 1; i < fs.size(); ++i) {
    const double ds = fs[i].s - fs[i - 1].s;
    fs[i].psi = fs[i - 1].psi + ds / 2 * (1 / fs[i].ds_dpsi + 1 / fs[i - 1].ds_dpsi);
    fs[i].time_s = fs[i - 1].time_s +
                   ds / 2 * (1 / fs[i].mass_weighted_speed + 1 / fs[i - 1].mass_weighted_speed);
  }
  // The quiet laminar column's speed wave: ramped in over the first exit
  // diameter, gone where the flow has developed or the release is turbulent.
  const double wave = opt.column_wave_amplitude * (1 - release.release_turbulence);
  for (Station& st : fs) {
    st.wave_amplitude = wave * (1 - st.development) * SmoothStep(st.s / release.exit_diameter_m);
    st.wave_time_s = st.time_s / opt.column_wave_phase_speed;
  }

  return fs;
}

// Step 3: stations in pairs along s (a station and the midpoint to the
// next), the pipe segment in front of the exit; *exit_station: the index of
// the exit's station.
std::vector<Station> PlaceStations(const std::vector<Station>& fs, int* exit_station) {
  std::vector<Station> stations_;
  const Station exit = fs.front();
  const double s_birth = -3.0 * exit.sigma_c;
  auto at_s_fine = [&](double s_here) {
    if (s_here < 0) {
      Station o = exit;
      o.s = s_here;
      o.psi = s_here / exit.ds_dpsi;
      o.time_s = s_here / exit.mass_weighted_speed;
      for (int k = 0; k < 3; ++k) o.pos[k] = exit.pos[k] + s_here * exit.tangent[k];
      return o;
    }
    auto it = std::upper_bound(fs.begin(), fs.end(), s_here,
                               [](double v, const Station& a) { return v < a.s; });
    if (it == fs.end()) return fs.back();
    if (it == fs.begin()) return fs.front();
    const Station& b = *it;
    const Station& a = *(it - 1);
    Station o = LerpStation(a, b, (s_here - a.s) / (b.s - a.s));
    o.s = s_here;
    return o;
  };
  auto pair_step = [&](const Station& a) {
    return std::min(2 * kMaxDpsi * a.ds_dpsi, 2 * kMaxDsSigma * a.sigma_c);
  };
  {
    const int n_pipe = std::max(1, static_cast<int>(std::ceil(-s_birth / pair_step(exit))));
    const double h = -s_birth / n_pipe;
    for (int p = 0; p < n_pipe; ++p) {
      stations_.push_back(at_s_fine(s_birth + p * h));
      stations_.push_back(at_s_fine(s_birth + (p + 0.5) * h));
    }
    *exit_station = static_cast<int>(stations_.size());
    const double s_end = fs.back().s;
    double s_here = 0;
    for (;;) {
      const Station a = at_s_fine(s_here);
      stations_.push_back(a);
      if (s_here >= s_end) break;
      double h2 = pair_step(a);
      // A zero or non-finite step (a width or axis-speed scale of zero)
      // would never reach the end.
      if (!(h2 > 1e-9 * std::max(1.0, s_end)) || !std::isfinite(h2) || stations_.size() > 4000000)
        throw std::invalid_argument(
            "the plume model cannot place its puff stations for this "
            "release (a zero-width or stalled plume at s = " +
            FormatNumber(s_here) + " m)");
      if (s_here + h2 > s_end - 0.25 * h2) h2 = s_end - s_here;
      stations_.push_back(at_s_fine(s_here + 0.5 * h2));
      s_here = s_here + h2 >= s_end ? s_end : s_here + h2;
    }
  }
  if (stations_.size() < 9)
    throw std::invalid_argument(
        "the view is too small for the plume model: enlarge "
        "the view or the distance");

  return stations_;
}

// Step 4: puff widths that reproduce the centreline density near the exit.
void CorrectPuffWidths(std::vector<Station>* stations, double q_, double rho_e) {
  std::vector<Station>& stations_ = *stations;
  // Where all puffs travel on the axis (no cross-stream offsets: near the
  // exit), the puff field's centreline density is the convolution along it
  //   rho_sm(s) = sum_i (Q / W_i) ds_i N3(X(s) - X(s_i); sigma_i),
  // which departs by a few per cent from the integral model's rho_c(s) where
  // the speed and width change quickly (the laminar column's acceleration
  // and the onset of entrainment), enough to exceed the pure gas's density.
  // A fixed-point correction of the widths there removes that:
  //   sigma <- sigma sqrt(rho_sm / rho_c).
  {
    const int ns = static_cast<int>(stations_.size());
    std::vector<double> sig(ns), lam(ns), target(ns);
    for (int j = 0; j < ns; ++j) {
      sig[j] = stations_[j].sigma_puff;
      const double ds = stations_[std::min(j + 1, ns - 1)].s - stations_[std::max(j - 1, 0)].s;
      lam[j] = q_ / MeanFlow::PuffSpeed(stations_[j], 0.0) * 0.5 * ds;
      target[j] = stations_[j].centre_partial_density;
    }
    for (int iter = 0; iter < 16; ++iter) {
      std::vector<double> next = sig;
      for (int j = 0; j < ns; ++j) {
        const Station& a = stations_[j];
        if (a.s < 0 || a.offset_scale > 0) continue;
        double rho = 0;
        for (int i = 0; i < ns; ++i) {
          if (std::abs(a.s - stations_[i].s) > 8 * sig[i]) continue;
          // Distance between the axis points (a bending axis overlaps itself).
          double d2 = 0;
          for (int k = 0; k < 3; ++k) {
            const double e = a.pos[k] - stations_[i].pos[k];
            d2 += e * e;
          }
          rho += lam[i] * std::exp(-0.5 * d2 / (sig[i] * sig[i])) /
                 std::pow(2 * kPi * sig[i] * sig[i], 1.5);
        }
        // Only where the gas is nearly pure (elsewhere a few per cent do not
        // matter), under-relaxed and bounded: the deconvolution is
        // ill-conditioned where the speed jumps (a jet bending over).
        const double w = SmoothStep((target[j] / rho_e - 0.6) / 0.2);
        const double factor = std::clamp(std::sqrt(rho / target[j]), 0.8, 1.25);
        next[j] = sig[j] * (1 + 0.5 * w * (factor - 1));
      }
      sig.swap(next);
    }
    for (int j = 0; j < ns; ++j) {
      Station& a = stations_[j];
      if (a.s < 0 || a.offset_scale > 0) continue;
      a.sigma_c = a.sigma_puff = sig[j];
    }
  }
}

// Step 5: the structure scale bands (log-spaced time scales over the view)
// and each station's normalised weights on them.
int AssignScaleBands(std::vector<Station>* stations, const PlumeModelOptions& opt, double l_lam_,
                     double l_dev_, double s_view_end, double s_last,
                     std::array<double, kMaxBands>* band_time) {
  std::vector<Station>& stations_ = *stations;
  std::array<double, kMaxBands>& band_time_ = *band_time;
  int num_bands_ = 1;
  const double c_tau = opt.structure_length;
  double t_min = 1e300, t_max = 0;
  if (s_view_end < 0) s_view_end = s_last;
  for (const Station& a : stations_) {
    if (a.s < l_lam_ || a.s > std::max(s_view_end, l_lam_ + l_dev_)) continue;
    const double tt = c_tau * a.sigma_c / a.mass_weighted_speed;
    t_min = std::min(t_min, tt);
    t_max = std::max(t_max, tt);
  }
  if (!(t_max > 0))
    t_min = t_max = c_tau * stations_.back().sigma_c / stations_.back().mass_weighted_speed;
  num_bands_ = std::clamp(1 + static_cast<int>(std::ceil(std::log2(t_max / t_min))), 1, kMaxBands);
  const double ratio = num_bands_ > 1 ? std::pow(t_max / t_min, 1.0 / (num_bands_ - 1)) : 2.0;
  const double log_ratio = std::log(std::max(ratio, 1.0 + 1e-9));
  for (int b = 0; b < num_bands_; ++b) band_time_[b] = t_min * std::pow(ratio, b);
  for (Station& a : stations_) {
    const double tt = c_tau * std::max(a.sigma_c, 1e-12) / a.mass_weighted_speed;
    double norm = 0;
    for (int b = 0; b < num_bands_; ++b) {
      const double l = std::log(tt / band_time_[b]) / log_ratio;
      a.band_w[b] = std::exp(-0.5 * l * l);
      norm += a.band_w[b] * a.band_w[b];
    }
    norm = std::sqrt(norm);
    for (int b = 0; b < num_bands_; ++b) a.band_w[b] /= norm;
  }

  return num_bands_;
}

// Step 6: the band weights' derivatives along s (central differences).
void BandWeightSlopes(std::vector<Station>* stations, int num_bands_) {
  std::vector<Station>& stations_ = *stations;
  const int n = static_cast<int>(stations_.size());
  for (int j = 0; j < n; ++j) {
    const int a = std::max(0, j - 1), b = std::min(n - 1, j + 1);
    const Station &sa = stations_[a], &sb = stations_[b];
    const double h = sb.s - sa.s;
    Station& o = stations_[j];
    for (int k = 0; k < num_bands_; ++k) o.band_dw_ds[k] = (sb.band_w[k] - sa.band_w[k]) / h;
  }
}

}  // namespace

MeanFlow::MeanFlow(const Release& release, const PlumeModelOptions& opt, const MixingModel& mixing,
                   const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                   double stop_distance_m) {
  release.Check();
  opt.Check();
  q_ = release.MassRateKgS();
  d_ = release.exit_diameter_m;
  const double area = kPi * d_ * d_ / 4;
  const double rho_e = mixing.exit_density();
  const double rho_a = mixing.ambient_density();
  v0_ = q_ / (rho_e * area);
  const double quiet = kQuietLaminarDiameters * (1 - release.release_turbulence);
  l_lam_ = (opt.laminar_length_diameters >= 0
                ? opt.laminar_length_diameters
                : (release.ExitReynoldsNumber() < 2000 ? 1.0 + quiet : 0.0)) *
           d_;
  l_dev_ = opt.development_length_diameters * d_;
  c_psi_ = opt.structure_persistence;
  const double u_wind = release.wind_speed_m_s;
  const double theta = release.wind_direction_deg * kPi / 180.0;
  const double ew[3] = {std::cos(theta), std::sin(theta), 0.0};
  const double x0 = release.exit_x_m, z0 = release.stack_height_m;
  // The laminar column above a low-Reynolds-number exit does not entrain
  // turbulently; entrainment switches on over kEntrainmentOnset diameters
  // after it (half a diameter above a turbulent exit).
  const double onset = l_lam_ > 0 ? kEntrainmentOnset : 0.5;
  const AxisModel axis{opt,  mixing, q_, d_, v0_, l_lam_, rho_a, u_wind, 0.8 * opt.alpha_plume,
                       onset};

  double s_view_end = -1;
  const std::vector<Fine> fine = MarchAxis(axis, ew, x0, z0, lo, hi, stop_distance_m, &s_view_end);
  const ProfileInputs in{q_,     rho_e,  l_lam_,
                         l_dev_, c_psi_, {-std::sin(theta), std::cos(theta), 0.0}};
  const std::vector<Station> fs = SimilarityProfiles(fine, release, opt, in);
  stations_ = PlaceStations(fs, &exit_station_);
  CorrectPuffWidths(&stations_, q_, rho_e);
  num_bands_ =
      AssignScaleBands(&stations_, opt, l_lam_, l_dev_, s_view_end, fs.back().s, &band_time_);
  BandWeightSlopes(&stations_, num_bands_);
}

Station MeanFlow::AtS(double s) const {
  auto it = std::upper_bound(stations_.begin(), stations_.end(), s,
                             [](double v, const Station& a) { return v < a.s; });
  if (it == stations_.end()) return stations_.back();
  if (it == stations_.begin()) return stations_.front();
  const Station& b = *it;
  const Station& a = *(it - 1);
  return LerpStation(a, b, (s - a.s) / (b.s - a.s));
}

}  // namespace qogi::synth
