#include "engine/synth/plume.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "engine/synth/random.h"
#include "engine/util/check.h"

namespace qogi::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Puffs farther than this many widths outside the box are dropped.
constexpr double kRemoveSigma = 6.0;
constexpr int kMeanderModes = 16;
constexpr int kComponents = 3;  // xi1, xi2 (cross-stream), zeta (axial)
// Correlation length of the label field per component (in label units, the
// labels being standard normal): cross-stream structures split a release
// instant into a few eddies; axial bunching spans the whole section (puffing).
constexpr double kLabelScale[kComponents] = {1.0, 1.0, 2.0};

// Random-stream identifiers.
enum : std::uint64_t { kStreamModes = 1, kStreamLabels = 2, kStreamMeander = 3, kStreamWave = 4 };

// Random Fourier modes of the structure fields.
struct Modes {
  int bands = 1, per_band = 1, total = 0;
  double amp = 1;  // sqrt(2 / per_band): unit variance per band
  std::vector<double> kappa, k1, k2, omega, theta;
  // exp(i omega (psi_{j+1} - psi_j)) for station interval j, [j * total + i].
  std::vector<double> rot_re, rot_im;
  int Index(int c, int b, int m) const { return (c * bands + b) * per_band + m; }
};

// Spatially uniform ambient velocity fluctuation u'(t), Gaussian correlation.
struct Meander {
  double sigma[3] = {0, 0, 0};
  double omega[3][kMeanderModes] = {}, phase[3][kMeanderModes] = {};
  void Velocity(double t, double out[3]) const {
    const double a = std::sqrt(2.0 / kMeanderModes);
    for (int c = 0; c < 3; ++c) {
      double v = 0;
      if (sigma[c] > 0)
        for (int j = 0; j < kMeanderModes; ++j) v += std::cos(omega[c][j] * t + phase[c][j]);
      out[c] = sigma[c] * a * v;
    }
  }
  // Integral of u' from t0 to t1 (stable for small omega).
  void Displacement(double t0, double t1, double out[3]) const {
    const double a = std::sqrt(2.0 / kMeanderModes);
    const double dt = t1 - t0;
    for (int c = 0; c < 3; ++c) {
      double d = 0;
      if (sigma[c] > 0)
        for (int j = 0; j < kMeanderModes; ++j) {
          const double w = omega[c][j];
          const double half = 0.5 * w * dt;
          const double sinc = std::abs(half) < 1e-8 ? 1.0 : std::sin(half) / half;
          d += std::cos(0.5 * w * (t0 + t1) + phase[c][j]) * dt * sinc;
        }
      out[c] = sigma[c] * a * d;
    }
  }
};

struct NodeValue {
  double t = 0;            // arrival time [s]
  double g = 0;            // dt/ds [s/m]
  double xi[kComponents] = {0, 0, 0};
  double dxi[kComponents] = {0, 0, 0};  // d xi / d s [1/m]
};

struct Track {
  std::uint64_t id = 0;
  double tau = 0;          // release time [s]
  int node = 0;            // station index of nv[0]; nv[1], nv[2] follow
  NodeValue nv[3];
  double t_exit = std::numeric_limits<double>::quiet_NaN();  // time at psi = 0
  bool alive = false;
};

double Hermite(double y0, double d0, double y1, double d1, double u, double h) {
  const double u2 = u * u, u3 = u2 * u;
  return (2 * u3 - 3 * u2 + 1) * y0 + (u3 - 2 * u2 + u) * h * d0 + (-2 * u3 + 3 * u2) * y1 +
         (u3 - u2) * h * d1;
}
// d/du of Hermite.
double HermiteDu(double y0, double d0, double y1, double d1, double u, double h) {
  const double u2 = u * u;
  return (6 * u2 - 6 * u) * y0 + (3 * u2 - 4 * u + 1) * h * d0 + (-6 * u2 + 6 * u) * y1 +
         (3 * u2 - 2 * u) * h * d1;
}

class Engine {
 public:
  // wave_omega, wave_phase: angular frequency [rad/s] and phase [rad] of the
  // laminar column's speed wave (Station::wave_amplitude).
  Engine(const MeanFlow& mf, const Modes& modes, const Meander& meander, const Box& box,
         double wave_omega, double wave_phase)
      : st_(mf.stations()),
        modes_(modes),
        meander_(meander),
        box_(box),
        exit_node_(mf.exit_station()),
        wave_omega_(wave_omega),
        wave_phase_(wave_phase) {}

  // Initialises a track released at tau with labels zeta, phasors in re/im.
  void Init(Track& tr, double* re, double* im, std::uint64_t id, double tau,
            const double zeta[2]) const {
    tr.id = id;
    tr.tau = tau;
    tr.node = 0;
    tr.alive = true;
    tr.t_exit = std::numeric_limits<double>::quiet_NaN();
    const double psi0 = st_[0].psi;
    for (int i = 0; i < modes_.total; ++i) {
      const double ph = modes_.kappa[i] * tau + modes_.k1[i] * zeta[0] + modes_.k2[i] * zeta[1] +
                        modes_.theta[i] + modes_.omega[i] * psi0;
      re[i] = std::cos(ph);
      im[i] = std::sin(ph);
    }
    Eval(0, re, im, tr.nv[0]);
    tr.nv[0].t = tau;
    if (exit_node_ == 0) tr.t_exit = tau;
    Pair(tr, re, im);
  }

  // Advances until the frame time t lies in [nv[0].t, nv[2].t); returns false
  // when the track ran off the end of the table.
  bool AdvanceTo(Track& tr, double* re, double* im, double t) const {
    while (tr.nv[2].t <= t) {
      if (tr.node + 4 >= static_cast<int>(st_.size())) return false;
      tr.nv[0] = tr.nv[2];
      tr.node += 2;
      Pair(tr, re, im);
    }
    return true;
  }

  PuffState State(const Track& tr, double t, double mass) const {
    const int k = t < tr.nv[1].t ? 0 : 1;
    const NodeValue& a = tr.nv[k];
    const NodeValue& b = tr.nv[k + 1];
    const int j = tr.node + k;
    const double h = st_[j + 1].s - st_[j].s;
    // Solve t(u) = t on the cubic Hermite of t(psi) (monotone): Newton with a
    // bisection safeguard.
    double lo = 0, hi = 1;
    double u = std::clamp((t - a.t) / (b.t - a.t), 0.0, 1.0);
    for (int it = 0; it < 50; ++it) {
      const double f = Hermite(a.t, a.g, b.t, b.g, u, h) - t;
      if (f > 0)
        hi = u;
      else
        lo = u;
      const double df = HermiteDu(a.t, a.g, b.t, b.g, u, h);
      double next = df > 0 ? u - f / df : 0.5 * (lo + hi);
      if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
      if (std::abs(next - u) < 1e-14) {
        u = next;
        break;
      }
      u = next;
    }
    const Station& sa = st_[j];
    const Station& sb = st_[j + 1];
    const Station s = LerpStation(sa, sb, u);
    double xi[kComponents], dxi[kComponents];
    for (int c = 0; c < kComponents; ++c) {
      xi[c] = Hermite(a.xi[c], a.dxi[c], b.xi[c], b.dxi[c], u, h);
      dxi[c] = HermiteDu(a.xi[c], a.dxi[c], b.xi[c], b.dxi[c], u, h) / h;
    }
    // The trajectory is P(s) = pos(s) + offset(s) (xi1(s) n1(s) + xi2(s) n2(s))
    // with pos, offset, n1, n2 linear and xi cubic (Hermite) on the interval,
    // and s(t) the inverse of the Hermite t(s). The velocity reported is the
    // exact derivative of that trajectory, so the fluxes computed from it move
    // exactly the mass the positions move.
    const double speed = h / HermiteDu(a.t, a.g, b.t, b.g, u, h);  // ds/dt
    const double off_ds = (sb.offset_scale - sa.offset_scale) / h;
    double pos[3], vel[3];
    for (int c = 0; c < 3; ++c) {
      const double dir = xi[0] * s.n1[c] + xi[1] * s.n2[c];
      pos[c] = s.pos[c] + s.offset_scale * dir;
      const double dp =
          (sb.pos[c] - sa.pos[c]) / h + off_ds * dir +
          s.offset_scale * (dxi[0] * s.n1[c] + dxi[1] * s.n2[c] +
                            xi[0] * (sb.n1[c] - sa.n1[c]) / h + xi[1] * (sb.n2[c] - sa.n2[c]) / h);
      vel[c] = dp * speed;
    }
    if (s.psi > 0 && std::isfinite(tr.t_exit) && s.turbulence > 0) {
      // The ambient fluctuation displaces the gas in proportion to the local
      // turbulence strength phi_t (0 in the unmixed core near the exit):
      // d = phi_t(psi) D(t), D = integral of u' since the exit, so the
      // velocity gains phi_t u' + (d phi_t/dt) D.
      double d[3], v[3];
      meander_.Displacement(tr.t_exit, t, d);
      meander_.Velocity(t, v);
      const double dphi_dt = (sb.turbulence - sa.turbulence) / h * speed;
      for (int c = 0; c < 3; ++c) {
        pos[c] += s.turbulence * d[c];
        vel[c] += s.turbulence * v[c] + dphi_dt * d[c];
      }
    }
    PuffState p;
    p.x = static_cast<float>(pos[0]);
    p.y = static_cast<float>(pos[1]);
    p.z = static_cast<float>(pos[2]);
    p.u = static_cast<float>(vel[0]);
    p.v = static_cast<float>(vel[1]);
    p.w = static_cast<float>(vel[2]);
    p.sigma = static_cast<float>(s.sigma_puff);
    p.sigma_rate = static_cast<float>((sb.sigma_puff - sa.sigma_puff) / h * speed);
    p.mass = static_cast<float>(mass);
    p.id = static_cast<std::uint32_t>(tr.id);
    return p;
  }

  bool Outside(const PuffState& p) const {
    const double r = kRemoveSigma * p.sigma;
    const double c[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k)
      if (c[k] < box_.lo[k] - r || c[k] > box_.hi[k] + r) return true;
    return false;
  }

 private:
  double Speed(const Station& s, const double xi[kComponents]) const {
    const double r2 = s.offset_scale * s.offset_scale * (xi[0] * xi[0] + xi[1] * xi[1]);
    return MeanFlow::PuffSpeed(s, r2) * (1 + s.axial_turbulence * 3 * std::tanh(xi[2] / 3));
  }

  // Node values at station j from the phasors (time not set).
  void Eval(int j, const double* re, const double* im, NodeValue& out) const {
    const Station& s = st_[j];
    const int nb = modes_.bands, pb = modes_.per_band;
    for (int c = 0; c < kComponents; ++c) {
      double xi = 0, dxi = 0;
      for (int b = 0; b < nb; ++b) {
        double sr = 0, sd = 0;
        const int base = modes_.Index(c, b, 0);
        for (int m = 0; m < pb; ++m) {
          sr += re[base + m];
          sd -= modes_.omega[base + m] * im[base + m];
        }
        xi += s.band_w[b] * sr;
        dxi += s.band_dw_ds[b] * sr + s.band_w[b] * sd / s.ds_dpsi;
      }
      out.xi[c] = modes_.amp * xi;
      out.dxi[c] = modes_.amp * dxi;
    }
    out.g = 1.0 / Speed(s, out.xi);
  }

  // Advances the phasors from station j to j + 1.
  void Rotate(int j, double* re, double* im) const {
    const double* rr = &modes_.rot_re[static_cast<std::size_t>(j) * modes_.total];
    const double* ri = &modes_.rot_im[static_cast<std::size_t>(j) * modes_.total];
    for (int i = 0; i < modes_.total; ++i) {
      const double r = re[i] * rr[i] - im[i] * ri[i];
      im[i] = re[i] * ri[i] + im[i] * rr[i];
      re[i] = r;
    }
  }

  // Computes nv[1], nv[2] from nv[0] (phasors at nv[0] in, at nv[2] out).
  // Simpson's rule over the pair (the middle station is its midpoint in s).
  void Pair(Track& tr, double* re, double* im) const {
    const double h = st_[tr.node + 2].s - st_[tr.node].s;
    Rotate(tr.node, re, im);
    Eval(tr.node + 1, re, im, tr.nv[1]);
    Rotate(tr.node + 1, re, im);
    Eval(tr.node + 2, re, im, tr.nv[2]);
    const double g0 = tr.nv[0].g;
    // The column's speed wave depends on the time a node is reached: each
    // node's dt/ds from the time predicted with the previous ones.
    WaveAt(tr.node + 1, tr.nv[0].t + h / 2 * g0, tr.nv[1]);
    const double g1 = tr.nv[1].g;
    WaveAt(tr.node + 2, tr.nv[0].t + h / 6 * (g0 + 4 * g1 + tr.nv[2].g), tr.nv[2]);
    const double g2 = tr.nv[2].g;
    tr.nv[1].t = tr.nv[0].t + h / 24 * (5 * g0 + 8 * g1 - g2);
    tr.nv[2].t = tr.nv[0].t + h / 6 * (g0 + 4 * g1 + g2);
    if (tr.node + 1 == exit_node_) tr.t_exit = tr.nv[1].t;
    if (tr.node + 2 == exit_node_) tr.t_exit = tr.nv[2].t;
  }

  // Divides node j's dt/ds by the column wave's speed factor at time t.
  void WaveAt(int j, double t, NodeValue& nv) const {
    const double a = st_[j].wave_amplitude;
    if (a > 0) nv.g /= 1 + a * std::sin(wave_omega_ * (st_[j].wave_time_s - t) + wave_phase_);
  }

  const std::vector<Station>& st_;
  const Modes& modes_;
  const Meander& meander_;
  const Box& box_;
  int exit_node_;
  double wave_omega_, wave_phase_;
};

}  // namespace

PlumeSimulation::~PlumeSimulation() = default;
PlumeSimulation::PlumeSimulation(PlumeSimulation&&) noexcept = default;

const std::vector<PuffState>& PlumeSimulation::puffs(int frame) const {
  if (frame < 0 || frame >= num_frames())
    throw std::out_of_range("frame must be within [0, " + std::to_string(num_frames() - 1) +
                            "]; got " + std::to_string(frame));
  return frames_[frame];
}

PlumeSimulation::PlumeSimulation(const Release& release, const View& view, double duration_s,
                                 double frame_rate_hz, const PlumeModelOptions& options,
                                 int num_threads, const RunControl* control)
    : release_(release), view_(view), options_(options), frame_rate_hz_(frame_rate_hz) {
  release_.Check();
  view_.Check();
  options_.Check();
  CheckInRange(frame_rate_hz, 1e-3, 1e6, "frame_rate_hz", "Hz");
  CheckPositive(duration_s, "duration_s", "s");
  const double n_frames_d = std::round(duration_s * frame_rate_hz);
  if (!(n_frames_d >= 1 && n_frames_d <= 1e5))
    throw std::invalid_argument("duration_s * frame_rate_hz must give 1 to 100000 frames; got " +
                                FormatNumber(n_frames_d));
  const int n_frames = static_cast<int>(n_frames_d);
  const int threads = ResolveThreads(num_threads);

  mixing_ = std::make_unique<MixingModel>(release_.ReleasedGas(), release_.exit_temperature_K,
                                          GasMixture::DryAir(), release_.ambient_temperature_K,
                                          release_.pressure_Pa);

  // --- the mean flow, integrated well past the view ----------------------------
  auto window = [&](double y, std::array<double, 3>& lo, std::array<double, 3>& hi) {
    lo[0] = view_.PixelX(-0.5, y);
    hi[0] = view_.PixelX(view_.width_px - 0.5, y);
    lo[2] = view_.PixelZ(view_.height_px - 0.5, y);
    hi[2] = view_.PixelZ(-0.5, y);
  };
  std::array<double, 3> lo{}, hi{};
  window(0.0, lo, hi);
  const double size = std::max(hi[0] - lo[0], hi[2] - lo[2]);
  // Depths considered: from 0.9 D in front of the axis plane to y_cap behind
  // it (a plume blown along the line of sight stays inside a perspective
  // view's widening frustum; beyond y_cap it is left out).
  const double y_near = -0.9 * view_.distance_m;
  const double y_cap = std::max(4 * size, 2 * view_.distance_m);
  window(y_cap, lo, hi);
  lo[1] = y_near;
  hi[1] = y_cap;
  // The table runs `size` beyond this region, so puffs leave the box below
  // well before they reach its end.
  mean_flow_ = std::make_unique<MeanFlow>(release_, options_, *mixing_, lo, hi, size);
  const MeanFlow& mf = *mean_flow_;
  const std::vector<Station>& st = mf.stations();

  // --- the box: the view's frustum over the plume's depth ----------------------
  const double sigma_h = release_.AmbientRmsVelocity();
  double y_lo = st.front().pos[1], y_hi = st.front().pos[1];
  for (const Station& s : st) {
    const double meander = std::min(size, 3 * sigma_h * std::max(0.0, s.time_s));
    const double reach = 5 * s.sigma_c + meander;
    std::array<double, 3> wl{}, wh{};
    window(std::clamp(s.pos[1], y_near, y_cap), wl, wh);
    if (s.pos[0] < wl[0] - reach || s.pos[0] > wh[0] + reach || s.pos[2] < wl[2] - reach ||
        s.pos[2] > wh[2] + reach)
      continue;
    y_lo = std::min(y_lo, s.pos[1] - reach);
    y_hi = std::max(y_hi, s.pos[1] + reach);
  }
  y_lo = std::max(y_lo, y_near);
  y_hi = std::min(y_hi, y_cap);
  window(std::max(y_hi, 0.0), box_.lo, box_.hi);
  box_.lo[1] = y_lo;
  box_.hi[1] = y_hi;

  // --- puff rate and spin-up -----------------------------------------------------
  const Station exit = mf.AtS(0.0);
  const Station dev = mf.AtS(mf.laminar_length_m() + mf.development_length_m());
  if (options_.puff_rate_per_s > 0) {
    puff_rate_ = options_.puff_rate_per_s;
  } else {
    const double k_exit = 4 * exit.mass_weighted_speed / exit.sigma_c;
    const double k_dev = 3 * dev.mass_weighted_speed / dev.sigma_puff;
    puff_rate_ = std::clamp(std::ceil(std::max(k_exit, k_dev)), 100.0, 2e4);
  }
  double t_leave = st.back().time_s;
  for (const Station& s : st) {
    if (s.s <= 0) continue;
    bool out = false;
    for (int k = 0; k < 3; ++k) out = out || s.pos[k] < box_.lo[k] || s.pos[k] > box_.hi[k];
    if (out) {
      t_leave = s.time_s;
      break;
    }
  }
  spin_up_ = options_.spin_up_s >= 0 ? options_.spin_up_s : std::min(600.0, 2 * t_leave + 0.5);

  // --- random modes ---------------------------------------------------------------
  const std::uint64_t seed = options_.seed;
  Modes modes;
  modes.bands = mf.num_bands();
  modes.per_band = options_.modes_per_band;
  modes.total = kComponents * modes.bands * modes.per_band;
  modes.amp = std::sqrt(2.0 / modes.per_band);
  for (auto* v : {&modes.kappa, &modes.k1, &modes.k2, &modes.omega, &modes.theta})
    v->resize(modes.total);
  for (int c = 0; c < kComponents; ++c)
    for (int b = 0; b < modes.bands; ++b)
      for (int m = 0; m < modes.per_band; ++m) {
        const int i = modes.Index(c, b, m);
        const std::uint64_t base = static_cast<std::uint64_t>(i) * 8;
        modes.kappa[i] = Normal(seed, kStreamModes, base + 0) / mf.band_time_s(b);
        modes.k1[i] = Normal(seed, kStreamModes, base + 1) / kLabelScale[c];
        modes.k2[i] = Normal(seed, kStreamModes, base + 2) / kLabelScale[c];
        modes.omega[i] = Normal(seed, kStreamModes, base + 3);
        modes.theta[i] = 2 * kPi * Uniform(seed, kStreamModes, base + 4);
      }
  {
    const std::size_t n_int = st.size() - 1;
    modes.rot_re.resize(n_int * modes.total);
    modes.rot_im.resize(n_int * modes.total);
    for (std::size_t j = 0; j < n_int; ++j) {
      const double dpsi = st[j + 1].psi - st[j].psi;
      for (int i = 0; i < modes.total; ++i) {
        modes.rot_re[j * modes.total + i] = std::cos(modes.omega[i] * dpsi);
        modes.rot_im[j * modes.total + i] = std::sin(modes.omega[i] * dpsi);
      }
    }
  }
  Meander meander;
  {
    const double t_gauss = release_.ambient_time_scale_s / std::sqrt(kPi / 2);
    meander.sigma[0] = meander.sigma[1] = sigma_h;
    meander.sigma[2] = 0.5 * sigma_h;
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < kMeanderModes; ++j) {
        const std::uint64_t idx = static_cast<std::uint64_t>(c * kMeanderModes + j);
        meander.omega[c][j] = Normal(seed, kStreamMeander, 2 * idx) / t_gauss;
        meander.phase[c][j] = 2 * kPi * Uniform(seed, kStreamMeander, 2 * idx + 1);
      }
  }

  // --- run ---------------------------------------------------------------------------
  // The quiet column's wave: the puffing frequency 1.5 / sqrt(D [m]) Hz of
  // buoyant plumes (Cetegen & Ahmed 1993) within +-10 %, a random phase.
  const double wave_f = 1.5 / std::sqrt(release_.exit_diameter_m) *
                        (1 + 0.1 * (2 * Uniform(seed, kStreamWave, 0) - 1));
  const Engine engine(mf, modes, meander, box_, 2 * kPi * wave_f,
                      2 * kPi * Uniform(seed, kStreamWave, 1));
  const double mass = mf.mass_rate_kg_s() / puff_rate_;
  const double t_start = -spin_up_;
  std::vector<Track> tracks;
  std::vector<double> re, im;
  std::vector<int> free_slots;
  std::uint64_t next_id = 0;
  frames_.resize(n_frames);
  std::vector<PuffState> states;
  std::vector<char> keep;

  for (int n = 0; n < n_frames; ++n) {
    const double t = frame_time(n);
    // Release the puffs due by t.
    for (;;) {
      const double tau = t_start + (static_cast<double>(next_id) + 0.5) / puff_rate_;
      if (tau > t) break;
      int slot;
      if (!free_slots.empty()) {
        slot = free_slots.back();
        free_slots.pop_back();
      } else {
        slot = static_cast<int>(tracks.size());
        tracks.emplace_back();
        re.resize(re.size() + modes.total);
        im.resize(im.size() + modes.total);
      }
      const double zeta[2] = {Normal(seed, kStreamLabels, 2 * next_id),
                              Normal(seed, kStreamLabels, 2 * next_id + 1)};
      engine.Init(tracks[slot], &re[slot * modes.total], &im[slot * modes.total], next_id, tau,
                  zeta);
      ++next_id;
    }
    states.assign(tracks.size(), PuffState{});
    keep.assign(tracks.size(), 0);
    std::vector<char> lost(tracks.size(), 0);
    ParallelFor(
        tracks.size(), 16,
        [&](std::size_t b, std::size_t e) {
          for (std::size_t i = b; i < e; ++i) {
            Track& tr = tracks[i];
            if (!tr.alive) continue;
            double* pr = &re[i * modes.total];
            double* pi = &im[i * modes.total];
            if (!engine.AdvanceTo(tr, pr, pi, t)) {
              tr.alive = false;
              // Its last known state decides whether that loses visible gas.
              const PuffState last = engine.State(tr, tr.nv[2].t, mass);
              lost[i] = engine.Outside(last) ? 0 : 1;
              continue;
            }
            states[i] = engine.State(tr, t, mass);
            if (engine.Outside(states[i])) {
              tr.alive = false;
              continue;
            }
            keep[i] = 1;
          }
        },
        threads);
    std::vector<PuffState>& out = frames_[n];
    out.clear();
    std::uint64_t live = 0;
    for (std::size_t i = 0; i < tracks.size(); ++i) {
      stats_.puffs_lost_inside += lost[i];
      if (keep[i]) {
        out.push_back(states[i]);
        ++live;
      } else if (tracks[i].id != std::numeric_limits<std::uint64_t>::max() && !tracks[i].alive) {
        tracks[i].id = std::numeric_limits<std::uint64_t>::max();  // mark slot free
        free_slots.push_back(static_cast<int>(i));
      }
    }
    // Free slots are reused in a fixed order, keeping runs reproducible.
    std::sort(free_slots.begin(), free_slots.end(), std::greater<int>());
    stats_.max_live_puffs = std::max(stats_.max_live_puffs, live);
    if (control) {
      if (control->cancelled && control->cancelled()) throw Cancelled();
      if (control->progress) control->progress(static_cast<double>(n + 1) / n_frames);
    }
  }
  stats_.puffs_emitted = next_id;
}

}  // namespace qogi::synth
