// The one-unknown Newton path (one free fraction, T_peak and sigma known):
// Newton on a cached curve of the table's contrast.
#include "engine/inversion/inversion.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "engine/inversion/bounded_lm_internal.h"
#include "engine/inversion/full_model.h"
#include "engine/inversion/inversion_internal.h"
#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {

using namespace inversion_detail;  // NOLINT: the module's own internals

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
      t.RawValues(c, s, lu, std::exp(lu) / sg, tp,
                  &ws->curve_nodes[static_cast<std::size_t>(i) * r1]);
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
      if ((f > 0) == (fa > 0))
        la = lu;
      else
        lb = lu;
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

}  // namespace qogi
