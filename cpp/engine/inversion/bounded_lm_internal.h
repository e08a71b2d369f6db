// Internal to engine/inversion (not installed): the small bounded
// Levenberg-Marquardt solver of the per-pixel inversion (BoundedLm) and its
// variable projection over T_peak (ProfileLm), with the solver coordinates
// and the residual rows of a pixel's priors.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

#include "engine/inversion/inversion_internal.h"

namespace qogi {
namespace inversion_detail {

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
inline double SolveScaled(const double* a, const double* b, int n, double extra, double* x) {
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
inline double PredictedDecrease(const double* g, const double* h, std::size_t np, const int* set,
                                int n) {
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
  double stop = 1e-5;  // iterate on while it would lower chi2 by more than this (<= tolerance)
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
        const double step =
            h[release * np + release] > 0 ? -g[release] / h[release * np + release] : 0.0;
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
      if (act[a] != static_cast<int>(ns) && std::abs(dv[a]) * alpha > 5.0)
        alpha = 5.0 / std::abs(dv[a]);
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
      trial[p] =
          std::min(std::max(ToTheta(p, ns, ToParam(p, ns, theta[p]) + alpha * dv[a]), px.lower[p]),
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
    if (at_bound ||
        (!crosses && (dec_t < set.stop || (set.stop_when_slow && dec_t < set.tolerance)))) {
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
inline std::size_t NumRows(const Inverter::Pixel& px) {
  std::size_t n = px.nc;
  for (std::size_t p = 0; p < px.np; ++p)
    if (px.est[p] && px.prior_sigma[p] > 0) ++n;
  return n;
}

// The 99 % quantile of chi2 (with priors) for the pixel's degrees of freedom
// (residual rows minus estimated parameters, at least 1), by the
// Wilson-Hilferty approximation (within 1 % for one degree of freedom).
inline double FitThreshold(const Inverter::Pixel& px) {
  int ne = 0;
  for (std::size_t p = 0; p < px.np; ++p) ne += px.est[p] ? 1 : 0;
  const double k = std::max(1.0, static_cast<double>(NumRows(px)) - ne);
  const double c = 2.0 / (9.0 * k);
  const double q = 1.0 - c + 2.3263 * std::sqrt(c);
  return k * q * q * q;
}

// Fills the prior rows (from row nc on) of the residuals and their derivatives.
inline void PriorRows(const Inverter::Pixel& px, const double* theta, double* r, double* jac) {
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

}  // namespace inversion_detail
}  // namespace qogi
