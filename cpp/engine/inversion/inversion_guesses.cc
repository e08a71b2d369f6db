// Starting points of the per-pixel solve: the optically thin non-negative
// least squares, the coarse table lookup, the chi2 profile over T_peak, and
// the full model's guess.
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

namespace {

// Small non-negative least squares min ||A u - b|| (A: m x k, k <= 6) by active sets.
void SmallNnls(const Eigen::MatrixXd& a, const Eigen::VectorXd& b, Eigen::VectorXd* u) {
  const int k = static_cast<int>(a.cols());
  std::vector<bool> on(k, true);
  u->setZero(k);
  for (int iter = 0; iter <= k; ++iter) {
    std::vector<int> idx;
    for (int j = 0; j < k; ++j)
      if (on[j]) idx.push_back(j);
    if (idx.empty()) return;
    Eigen::MatrixXd as(a.rows(), idx.size());
    for (std::size_t j = 0; j < idx.size(); ++j) as.col(j) = a.col(idx[j]);
    Eigen::MatrixXd n = as.transpose() * as;
    n.diagonal().array() += 1e-12 * (n.diagonal().maxCoeff() + 1e-300);
    const Eigen::VectorXd sol = n.ldlt().solve(as.transpose() * b);
    int worst = -1;
    double wv = 0;
    for (std::size_t j = 0; j < idx.size(); ++j)
      if (!(sol[j] >= 0) && (worst < 0 || sol[j] < wv)) {
        worst = static_cast<int>(j);
        wv = sol[j];
      }
    if (worst < 0) {
      u->setZero(k);
      for (std::size_t j = 0; j < idx.size(); ++j) (*u)[idx[j]] = sol[j];
      return;
    }
    on[idx[worst]] = false;
  }
}

}  // namespace

void Inverter::ThinGuess(const Pixel& px, double tc, double* th) const {
  const std::size_t nc = px.nc, ns = px.ns;
  const SceneTable& t = *table_;
  const double sigma = th[ns + 1];
  std::vector<int> free_s;
  for (std::size_t s = 0; s < ns; ++s)
    if (px.est[s]) free_s.push_back(static_cast<int>(s));
  th[ns] = tc;
  for (int s : free_s) th[s] = 0.0;
  px.ApplyTies(th);
  if (free_s.empty()) return;
  double con[kMaxChannels];
  t.Contrast(th, tc, sigma, px.phi, con, nullptr);  // the fixed species
  Eigen::MatrixXd a(nc, free_s.size());
  Eigen::VectorXd b(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    b[c] = (px.y[c] - con[c]) / px.noise[c];
    for (std::size_t j = 0; j < free_s.size(); ++j) {
      double slope = t.ThinSlope(c, free_s[j], tc, px.phi);
      for (std::size_t s2 = 0; s2 < ns; ++s2)  // tied species follow (u_s2 = ratio u)
        if (px.tie_ref[s2] == free_s[j]) slope += px.tie_ratio[s2] * t.ThinSlope(c, s2, tc, px.phi);
      a(c, j) = slope / px.noise[c];
    }
  }
  Eigen::VectorXd u;
  SmallNnls(a, b, &u);
  for (std::size_t j = 0; j < free_s.size(); ++j) {
    const int s = free_s[j];
    th[s] = std::min(std::max(u[j] / sigma, px.lower[s]), px.upper[s]);
  }
  px.ApplyTies(th);
}

void Inverter::TableGuess(const Pixel& px, std::vector<GuessCandidate>* out, Workspace*) const {
  const std::size_t nc = px.nc, ns = px.ns, np = px.np;
  const SceneTable& t = *table_;
  std::vector<double> cands;
  cands.push_back(px.nominal[ns]);
  if (px.est[ns]) {
    const int n = options_.temperature_candidates;
    for (int k = 0; k < n; ++k)
      cands.push_back(n == 1 ? 0.5 * (px.lower[ns] + px.upper[ns])
                             : px.lower[ns] + (px.upper[ns] - px.lower[ns]) * k / (n - 1));
  }
  std::uint8_t fractions = 0;
  for (std::size_t s = 0; s < ns; ++s)
    if (px.est[s]) fractions |= static_cast<std::uint8_t>(1u << s);
  const std::size_t nr = NumRows(px);
  auto eval = [&](const double* th, double* r, double* jac) {
    double con[kMaxChannels];
    t.Contrast(th, th[ns], th[ns + 1], px.phi, con, jac);
    px.FoldJacobian(jac, nc);
    for (std::size_t c = 0; c < nc; ++c) {
      r[c] = (con[c] - px.y[c]) / px.noise[c];
      for (std::size_t p = 0; p < np; ++p) jac[c * np + p] /= px.noise[c];
    }
    PriorRows(px, th, r, jac);
    return std::all_of(r, r + nr, [](double v) { return std::isfinite(v); });
  };
  std::vector<GuessCandidate>& all = *out;
  all.clear();
  for (double tc : cands) {
    GuessCandidate k;
    for (std::size_t p = 0; p < np; ++p) k.th[p] = px.nominal[p];
    ThinGuess(px, tc, k.th);
    double r[kMaxRows], jac[kMaxRows * kMaxParams];
    if (!eval(k.th, r, jac)) continue;
    k.cost = 0;
    for (std::size_t i = 0; i < nr; ++i) k.cost += r[i] * r[i];
    // The thin limit underestimates optically thick columns: with several
    // candidates (a coarse profile of chi2 over T_peak) refine the fractions
    // of each by a few iterations with the temperature held.
    if (cands.size() > 1 && fractions && options_.guess_iterations > 0) {
      GuessCandidate refined = k;
      LmSettings set;
      set.estimate = fractions;
      set.max_iterations = options_.guess_iterations;
      set.tolerance = set.stop = options_.tolerance_chi2;
      std::uint8_t held = 0;
      int it = 0;
      BoundedLm(px, set, nr, eval, refined.th, &held, r, jac, &refined.cost, &it);
      if (refined.cost < k.cost) k = refined;
    }
    all.push_back(k);
  }
  std::sort(all.begin(), all.end(),
            [](const GuessCandidate& a, const GuessCandidate& b) { return a.cost < b.cost; });
}

void Inverter::ProfileGuess(const Pixel& px, std::vector<GuessCandidate>* out, int* iterations,
                            Workspace* ws) const {
  const std::size_t nc = px.nc, ns = px.ns, np = px.np, m = slices_.size();
  const SceneTable& t = *table_;
  std::uint8_t fractions = 0;
  for (std::size_t s = 0; s < ns; ++s)
    if (px.est[s]) fractions |= static_cast<std::uint8_t>(1u << s);
  const std::size_t nr = NumRows(px);
  const double sigma = px.nominal[ns + 1];
  const SceneTable::Slice* slice = nullptr;
  auto eval = [&](const double* th, double* r, double* jac) {
    double con[kMaxChannels], d_dx[kMaxChannels * kMaxParams];
    t.SliceContrast(*slice, th, sigma, px.phi, con, d_dx);
    for (std::size_t c = 0; c < nc; ++c) {
      r[c] = (con[c] - px.y[c]) / px.noise[c];
      double* row = jac + c * np;
      for (std::size_t s = 0; s < ns; ++s) row[s] = d_dx[c * ns + s] / px.noise[c];
      row[ns] = row[ns + 1] = 0.0;
    }
    px.FoldJacobian(jac, nc);
    PriorRows(px, th, r, jac);
    return std::all_of(r, r + nr, [](double v) { return std::isfinite(v); });
  };
  ws->profile_cost.resize(m);
  ws->profile_theta.resize(m);
  double th[kMaxParams];
  for (std::size_t p = 0; p < np; ++p) th[p] = px.nominal[p];
  // From the hottest temperature down: there the optically thin guess is
  // close, and continuing from it towards colder (thicker) solutions follows
  // the branch on which the contrast grows with the column. (Starting cold
  // would follow the self-absorbed branch beyond the contrast's maximum,
  // where the plume's cooler edges hide its hot core.)
  ThinGuess(px, slices_[m - 1].peak_temperature_K, th);
  LmSettings set;
  set.estimate = fractions;
  set.max_iterations = 20;
  // A profile locates minima; the full solve polishes them. Its costs must
  // be accurate well below the tolerance: on flat profiles (a weakly
  // determined temperature) their errors would make spurious local minima.
  set.tolerance = set.stop = std::max(0.3 * options_.tolerance_chi2, 3e-3);
  std::uint8_t held = 0;
  double r[kMaxRows], jac[kMaxRows * kMaxParams];
  for (std::size_t jj = 0; jj < m; ++jj) {
    // Continuation: the fractions of the neighbouring temperature.
    const std::size_t j = m - 1 - jj;
    slice = &slices_[j];
    th[ns] = slice->peak_temperature_K;
    // ... extrapolated (in log) along the last two temperatures, where the
    // fraction is off its bounds at both.
    if (jj >= 2) {
      const auto& p1 = ws->profile_theta[j + 1];
      const auto& p2 = ws->profile_theta[j + 2];
      const double w = (th[ns] - p1[ns]) / (p1[ns] - p2[ns]);
      for (std::size_t s = 0; s < ns; ++s) {
        if (!px.est[s] || (held >> s & 1)) continue;
        if (!(p1[s] > px.lower[s] && p2[s] > px.lower[s] && p1[s] < px.upper[s] &&
              p2[s] < px.upper[s]))
          continue;
        const double l1 = std::log(p1[s] + kLogEps), l2 = std::log(p2[s] + kLogEps);
        const double dl = std::min(std::max(w * (l1 - l2), -1.0), 1.0);
        th[s] = std::min(std::max(std::exp(l1 + dl) - kLogEps, px.lower[s]), px.upper[s]);
      }
    }
    px.ApplyTies(th);
    double cost = std::numeric_limits<double>::infinity();
    if (fractions) {
      BoundedLm(px, set, nr, eval, th, &held, r, jac, &cost, iterations);
    } else if (eval(th, r, jac)) {
      cost = 0;
      for (std::size_t i = 0; i < nr; ++i) cost += r[i] * r[i];
    }
    ws->profile_cost[j] = std::isfinite(cost) ? cost : std::numeric_limits<double>::max();
    std::copy(th, th + np, ws->profile_theta[j].begin());
  }
  // Local minima, each refined by the parabola through it and its neighbours.
  const std::vector<double>& f = ws->profile_cost;
  std::vector<GuessCandidate>& all = *out;
  all.clear();
  ws->profile_predicted.clear();
  for (std::size_t j = 0; j < m; ++j) {
    if (j > 0 && f[j] > f[j - 1]) continue;
    if (j + 1 < m && f[j] >= f[j + 1]) continue;
    GuessCandidate k;
    std::copy(ws->profile_theta[j].begin(), ws->profile_theta[j].end(), k.th);
    k.cost = f[j];
    double predicted =
        f[j];  // the parabola's minimum (a poor guess on steep profiles: only a filter)
    if (j > 0 && j + 1 < m) {
      const double a = slices_[j - 1].peak_temperature_K, b = slices_[j].peak_temperature_K,
                   c = slices_[j + 1].peak_temperature_K;
      const double fa = f[j - 1], fb = f[j], fc = f[j + 1];
      const double num = (b - a) * (b - a) * (fb - fc) - (b - c) * (b - c) * (fb - fa);
      const double den = (b - a) * (fb - fc) - (b - c) * (fb - fa);
      if (den < 0) {  // convex
        const double tm = std::min(std::max(b - 0.5 * num / den, a), c);
        // The parabola's value at tm (Lagrange form).
        const double pm = fa * (tm - b) * (tm - c) / ((a - b) * (a - c)) +
                          fb * (tm - a) * (tm - c) / ((b - a) * (b - c)) +
                          fc * (tm - a) * (tm - b) / ((c - a) * (c - b));
        predicted = std::max(std::min(fb, pm), 0.0);
        // Half the parabola's second derivative: the profile's curvature for
        // ProfileLm, unless a fraction reaches a bound between the nodes
        // (which kinks the profile).
        auto on_bound = [&](std::size_t node) {
          unsigned mask = 0;
          for (std::size_t s = 0; s < ns; ++s) {
            const double v = ws->profile_theta[node][s];
            if (px.est[s] && (v <= px.lower[s] || v >= px.upper[s])) mask |= 1u << s;
          }
          return mask;
        };
        if (on_bound(j - 1) == on_bound(j) && on_bound(j) == on_bound(j + 1))
          k.curvature =
              fa / ((a - b) * (a - c)) + fb / ((b - a) * (b - c)) + fc / ((c - a) * (c - b));
        // Fractions interpolated (in log) towards the neighbour on tm's side.
        const std::size_t o = tm < b ? j - 1 : j + 1;
        const double w = (tm - b) / (slices_[o].peak_temperature_K - b);
        for (std::size_t s = 0; s < ns; ++s) {
          if (!px.est[s]) continue;
          const double l0 = std::log(k.th[s] + kLogEps),
                       l1 = std::log(ws->profile_theta[o][s] + kLogEps);
          k.th[s] =
              std::min(std::max(std::exp(l0 + w * (l1 - l0)) - kLogEps, px.lower[s]), px.upper[s]);
        }
        k.th[ns] = tm;
        px.ApplyTies(k.th);
      }
    }
    all.push_back(k);
    ws->profile_predicted.push_back(predicted);
  }
  // The nodes beside the best minimum start solves too: a second minimum
  // closer than the node spacing (a well-determined temperature) shows no
  // local minimum of its own on the nodes.
  std::size_t jb = 0;
  for (std::size_t j = 1; j < m; ++j)
    if (f[j] < f[jb]) jb = j;
  double best_curvature = 0;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (all[i].cost == f[jb]) best_curvature = all[i].curvature;
  for (std::size_t j : {jb - 1, jb + 1}) {
    if (jb == 0 && j == jb - 1) continue;
    if (j >= m) continue;
    GuessCandidate k;
    std::copy(ws->profile_theta[j].begin(), ws->profile_theta[j].end(), k.th);
    k.cost = f[j];
    k.curvature = best_curvature;
    all.push_back(k);
    ws->profile_predicted.push_back(f[jb]);
  }
  // Best node first; minima that cannot come within 25 of it carry no
  // likelihood weight (exp(-12.5)) and are dropped; at most 4 are polished.
  const double best = *std::min_element(f.begin(), f.end());
  std::size_t keep = 0;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (ws->profile_predicted[i] <= best + 25.0) all[keep++] = all[i];
  all.resize(keep);
  std::sort(all.begin(), all.end(),
            [](const GuessCandidate& a, const GuessCandidate& b) { return a.cost < b.cost; });
  if (all.size() > 6) all.resize(6);
}

void Inverter::FullModelGuess(const Pixel& px, double* theta) const {
  const std::size_t nc = px.nc, ns = px.ns, np = px.np;
  double th[kMaxParams], con[kMaxChannels], jac[kMaxChannels * kMaxParams];
  for (std::size_t p = 0; p < np; ++p) th[p] = px.nominal[p];
  std::vector<int> free_s;
  for (std::size_t s = 0; s < ns; ++s)
    if (px.est[s]) {
      free_s.push_back(static_cast<int>(s));
      th[s] = 1e-9;
    }
  px.ApplyTies(th);
  FullModelContrast(*model_, t_amb_, th, px.tbg, con, jac);
  px.FoldJacobian(jac, nc);
  for (std::size_t p = 0; p < np; ++p) theta[p] = px.nominal[p];
  if (free_s.empty()) return;
  Eigen::MatrixXd a(nc, free_s.size());
  Eigen::VectorXd b(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    b[c] = (px.y[c] - con[c]) / px.noise[c];
    for (std::size_t k = 0; k < free_s.size(); ++k) a(c, k) = jac[c * np + free_s[k]] / px.noise[c];
  }
  Eigen::VectorXd u;
  SmallNnls(a, b, &u);
  for (std::size_t k = 0; k < free_s.size(); ++k) {
    const int s = free_s[k];
    theta[s] = std::min(std::max(u[k] + 1e-9, std::max(px.lower[s], 1e-7)), px.upper[s]);
  }
  px.ApplyTies(theta);
}

}  // namespace qogi
