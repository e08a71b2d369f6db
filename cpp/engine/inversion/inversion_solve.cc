// The table path's solve of one pixel (bounded LM or the profile over
// T_peak) and what follows a solution: columns, covariance and
// uncertainties, and the below-detection and failed fills.
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

void Inverter::SolveTable(Pixel* px, const double* start, Workspace* ws, bool precise,
                          double curvature) const {
  const std::size_t nc = px->nc, ns = px->ns, np = px->np;
  const SceneTable& t = *table_;
  double theta[kMaxParams];
  LmSettings set;
  for (std::size_t p = 0; p < np; ++p) {
    theta[p] =
        px->est[p] ? std::min(std::max(start[p], px->lower[p]), px->upper[p]) : px->nominal[p];
    if (px->est[p]) set.estimate |= static_cast<std::uint8_t>(1u << p);
  }
  px->ApplyTies(theta);
  set.max_iterations = options_.max_iterations;
  set.tolerance = options_.tolerance_chi2;
  // Precise: iterate on to 1e-10 of the tolerance, so that solutions from
  // different starts (cold, warm) agree to many digits (with T_peak
  // estimated, ProfileLm gets there in a few steps; joint steps in the
  // curved column-temperature valley would take dozens). Otherwise stop
  // once below the tolerance (or as soon as Gauss-Newton steps slow down or
  // fail).
  set.stop = 1e-10 * options_.tolerance_chi2;
  set.stop_when_slow = !precise;
  const std::size_t nr = NumRows(*px);
  const Pixel& cpx = *px;
  auto eval = [&](const double* th, double* r, double* jac) {
    double con[kMaxChannels];
    // The T_peak terms are reused while T_peak stays (ProfileLm's inner solves).
    if (ws->peak.peak_temperature_K != th[ns]) t.MakePeakTerms(th[ns], &ws->peak);
    t.Contrast(th, ws->peak, th[ns + 1], cpx.phi, con, jac);
    if (jac) cpx.FoldJacobian(jac, nc);
    for (std::size_t c = 0; c < nc; ++c) {
      r[c] = (con[c] - cpx.y[c]) / cpx.noise[c];
      if (jac)
        for (std::size_t p = 0; p < np; ++p) jac[c * np + p] /= cpx.noise[c];
    }
    PriorRows(cpx, th, r, jac);
    return std::all_of(r, r + nr, [](double v) { return std::isfinite(v); }) &&
           (!jac || std::all_of(jac, jac + nr * np, [](double v) { return std::isfinite(v); }));
  };
  std::uint8_t held = 0;
  double r[kMaxRows], jac[kMaxRows * kMaxParams], cost = 0;
  int iters = 0;
  const bool ok =
      px->est[ns] ? ProfileLm(*px, set, nr, eval, theta, &held, r, jac, &cost, &iters, &curvature)
                  : BoundedLm(*px, set, nr, eval, theta, &held, r, jac, &cost, &iters);
  px->curvature = curvature;
  for (std::size_t p = 0; p < np; ++p) px->theta[p] = theta[p];
  px->iterations += iters;
  px->bound_mask = held;
  if (!ok) {
    px->status = PixelStatus::kFailed;
    return;
  }
  px->status = held ? PixelStatus::kAtBound : PixelStatus::kConverged;
  double con[kMaxChannels];
  for (std::size_t c = 0; c < nc; ++c) {
    con[c] = r[c] * px->noise[c] + px->y[c];
    for (std::size_t p = 0; p < np; ++p) jac[c * np + p] *= px->noise[c];
  }
  FinishWith(px, con, jac, ws);
}

void Inverter::Columns(Pixel* px, Workspace* ws) const {
  const std::size_t ns = px->ns, np = px->np;
  const double tp = px->theta[ns], sg = px->theta[ns + 1];
  ws->Integral(tp, t_amb_);
  const double i = ws->int_i, di = ws->int_di;
  const double t_min = std::min(t_amb_, px->lower[ns]);
  for (std::size_t s = 0; s < ns; ++s) {
    const double k = column_factor_[s], x = px->theta[s];
    px->col[s] = k * x * sg * i;
    px->ppm[s] = 1e6 * kSqrt2Pi * x * sg;
    // Gradients over (x_s, T_peak, sigma).
    const int idx[3] = {static_cast<int>(s), static_cast<int>(ns), static_cast<int>(ns + 1)};
    const double gc[3] = {k * sg * i, k * x * sg * di, k * x * i};
    const double gp[3] = {1e6 * kSqrt2Pi * sg, 0.0, 1e6 * kSqrt2Pi * x};
    double vc = 0, vp = 0;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        const double cv = px->cov[idx[a] * np + idx[b]];
        vc += gc[a] * cv * gc[b];
        vp += gp[a] * cv * gp[b];
      }
    const double cap_c = k * px->upper[s] * px->upper[ns + 1] * kSqrt2Pi / t_min;
    const double cap_p = 1e6 * kSqrt2Pi * px->upper[s] * px->upper[ns + 1];
    px->col_sig[s] = std::min(std::sqrt(std::max(vc, 0.0)), cap_c);
    px->ppm_sig[s] = std::min(std::sqrt(std::max(vp, 0.0)), cap_p);
  }
}

void Inverter::FinishWith(Pixel* px, const double* con, const double* jac_in, Workspace* ws) const {
  const std::size_t nc = px->nc, np = px->np, ns = px->ns;
  px->prior_chi2 = 0;
  for (std::size_t p = 0; p < np; ++p)
    if (px->est[p] && px->prior_sigma[p] > 0) {
      const double r = (px->theta[p] - px->nominal[p]) / px->prior_sigma[p];
      px->prior_chi2 += r * r;
    }
  double jac[kMaxChannels * kMaxParams];
  std::copy(jac_in, jac_in + nc * np, jac);
  px->FoldJacobian(jac, nc);
  px->chi2 = 0;
  for (std::size_t c = 0; c < nc; ++c) {
    const double r = (con[c] - px->y[c]) / px->noise[c];
    px->chi2 += r * r;
  }
  int est[kMaxParams];
  int ne = 0, npr = 0;
  for (std::size_t p = 0; p < np; ++p)
    if (px->est[p]) {
      est[ne++] = static_cast<int>(p);
      if (px->prior_sigma[p] > 0) ++npr;
    }
  std::fill(px->cov, px->cov + np * np, 0.0);
  std::fill(px->psig, px->psig + np, 0.0);
  if (ne > 0) {
    const int nr = static_cast<int>(nc) + npr;
    // Fixed largest sizes: no heap allocations per pixel.
    using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, kMaxRows,
                                 kMaxParams>;
    using Square = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor,
                                 kMaxParams, kMaxParams>;
    using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxParams, 1>;
    Matrix j = Matrix::Zero(nr, ne);
    int row = static_cast<int>(nc);
    for (int e = 0; e < ne; ++e) {
      const int p = est[e];
      for (std::size_t c = 0; c < nc; ++c) j(c, e) = jac[c * np + p] / px->noise[c];
      if (px->prior_sigma[p] > 0) j(row++, e) = 1.0 / px->prior_sigma[p];
    }
    Vector d(ne);
    for (int e = 0; e < ne; ++e) {
      d[e] = j.col(e).norm();
      if (!(d[e] > 0) || !std::isfinite(d[e])) d[e] = 1.0;
      j.col(e) /= d[e];
    }
    Eigen::JacobiSVD<Matrix> svd(j, Eigen::ComputeThinV);
    const Vector sv = svd.singularValues();
    const double smax = sv.size() ? sv[0] : 0.0;
    const double smin = (sv.size() == ne) ? sv[ne - 1] : 0.0;
    px->cond = (smin > 0 && smax / smin < kConditionCap) ? smax / smin : kConditionCap;
    const double floor = std::max(smax, 1e-300) * 1e-8;
    Vector inv2 = Vector::Zero(ne);
    for (int k = 0; k < ne; ++k) {
      const double s = k < sv.size() ? std::max(sv[k], floor) : floor;
      inv2[k] = 1.0 / (s * s);
    }
    const Square& v = svd.matrixV();
    const Square covn = v * inv2.asDiagonal() * v.transpose();
    px->log_det = 0;
    for (int k = 0; k < ne; ++k) px->log_det += std::log(inv2[k]) - 2.0 * std::log(d[k]);
    for (int a = 0; a < ne; ++a)
      for (int b = 0; b < ne; ++b) px->cov[est[a] * np + est[b]] = covn(a, b) / (d[a] * d[b]);
    for (int a = 0; a < ne; ++a) {
      const int p = est[a];
      px->psig[p] =
          std::min(std::sqrt(std::max(px->cov[p * np + p], 0.0)), px->upper[p] - px->lower[p]);
    }
    // Tied fractions: x_s = ratio x_ref.
    for (std::size_t s = 0; s < ns; ++s) {
      const int r = px->tie_ref[s];
      if (r < 0) continue;
      const double k = px->tie_ratio[s];
      for (std::size_t q = 0; q < np; ++q) px->cov[s * np + q] = k * px->cov[r * np + q];
      for (std::size_t q = 0; q < np; ++q) px->cov[q * np + s] = k * px->cov[q * np + r];
      px->psig[s] = k * px->psig[r];
    }
  } else {
    px->cond = 1.0;
  }
  Columns(px, ws);
}

void Inverter::FillFailed(Pixel* px) const {
  const std::size_t ns = px->ns, np = px->np;
  px->status = PixelStatus::kFailed;
  for (std::size_t p = 0; p < np; ++p) {
    px->theta[p] = (p >= ns && std::isfinite(px->nominal[p])) ? px->nominal[p] : 0.0;
    px->psig[p] = 0;
  }
  std::fill(px->cov, px->cov + np * np, 0.0);
  for (std::size_t s = 0; s < ns; ++s)
    px->col[s] = px->col_sig[s] = px->ppm[s] = px->ppm_sig[s] = 0;
  px->chi2 = 0;
  px->cond = 0;
  px->bound_mask = 0;
}

void Inverter::FillBelowDetection(Pixel* px, Workspace* ws) const {
  const std::size_t nc = px->nc, ns = px->ns, np = px->np;
  px->status = PixelStatus::kBelowDetection;
  for (std::size_t p = 0; p < np; ++p) px->theta[p] = (p < ns && px->est[p]) ? 0.0 : px->nominal[p];
  px->ApplyTies(px->theta);
  std::fill(px->cov, px->cov + np * np, 0.0);
  std::fill(px->psig, px->psig + np, 0.0);
  px->chi2 = 0;
  for (std::size_t c = 0; c < nc; ++c)
    px->chi2 += (px->y[c] / px->noise[c]) * (px->y[c] / px->noise[c]);
  px->cond = 0;
  px->bound_mask = 0;
  Columns(px, ws);
  // Noise-equivalent column (1 sigma) of each estimated species in the thin
  // limit: the column whose contrast equals the noise, combined over
  // channels (tied species contribute to their reference's signal).
  const double tp = px->theta[ns], sg = px->theta[ns + 1];
  double thin[kMaxChannels * kMaxParams];  // [c * ns + s] d(Delta L)/du_s
  if (use_table_) {
    for (std::size_t c = 0; c < nc; ++c)
      for (std::size_t s = 0; s < ns; ++s) thin[c * ns + s] = table_->ThinSlope(c, s, tp, px->phi);
  } else {
    double th[kMaxParams], con[kMaxChannels], jac[kMaxChannels * kMaxParams];
    for (std::size_t p = 0; p < np; ++p) th[p] = px->theta[p];
    for (std::size_t s = 0; s < ns; ++s)
      if (px->est[s] || px->tie_ref[s] >= 0) th[s] = 1e-9;
    FullModelContrast(*model_, t_amb_, th, px->tbg, con, jac);
    for (std::size_t c = 0; c < nc; ++c)
      for (std::size_t s = 0; s < ns; ++s) thin[c * ns + s] = jac[c * np + s] / sg;
  }
  ws->Integral(tp, t_amb_);
  const double t_min = std::min(t_amb_, px->lower[ns]);
  for (std::size_t s = 0; s < ns; ++s) {
    if (!px->est[s]) continue;
    const double k = column_factor_[s];
    double sc = 0, sp = 0, yc = 0, yp = 0;  // yc, yp: sum_c (y_c / n_c) d_c
    for (std::size_t c = 0; c < nc; ++c) {
      double g = thin[c * ns + s];
      for (std::size_t s2 = 0; s2 < ns; ++s2)
        if (px->tie_ref[s2] == static_cast<int>(s)) g += px->tie_ratio[s2] * thin[c * ns + s2];
      const double dc = g / (k * ws->int_i) / px->noise[c];
      const double dp = g / (1e6 * kSqrt2Pi) / px->noise[c];
      sc += dc * dc;
      sp += dp * dp;
      yc += px->y[c] / px->noise[c] * dc;
      yp += px->y[c] / px->noise[c] * dp;
    }
    const double cap_c = k * px->upper[s] * px->upper[ns + 1] * kSqrt2Pi / t_min;
    const double cap_p = 1e6 * kSqrt2Pi * px->upper[s] * px->upper[ns + 1];
    px->col_sig[s] = sc > 0 ? std::min(1.0 / std::sqrt(sc), cap_c) : cap_c;
    px->ppm_sig[s] = sp > 0 ? std::min(1.0 / std::sqrt(sp), cap_p) : cap_p;
    // The thin-limit estimate, where the contrast is sensitive to the column
    // at all (an insensitive pixel keeps 0: its estimate would be noise
    // divided by nearly nothing).
    const bool sensitive = sc > 0 && 1.0 / std::sqrt(sc) < cap_c;
    if (options_.signed_below_detection && sensitive) {
      px->col[s] = yc / sc;
      px->ppm[s] = sp > 0 ? yp / sp : 0.0;
    }
    for (std::size_t s2 = 0; s2 < ns; ++s2)
      if (px->tie_ref[s2] == static_cast<int>(s)) {
        px->col_sig[s2] = px->tie_ratio[s2] * column_factor_[s2] / k * px->col_sig[s];
        px->ppm_sig[s2] = px->tie_ratio[s2] * px->ppm_sig[s];
        if (options_.signed_below_detection && sensitive) {
          px->col[s2] = px->tie_ratio[s2] * column_factor_[s2] / k * px->col[s];
          px->ppm[s2] = px->tie_ratio[s2] * px->ppm[s];
        }
      }
  }
}

}  // namespace qogi
