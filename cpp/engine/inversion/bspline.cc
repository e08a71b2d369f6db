#include "engine/inversion/bspline.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>

#include "engine/util/check.h"

namespace qogi {

CubicSplineAxis::CubicSplineAxis(int n) : n_(n) {
  Require(n == 1 || n >= 4, "a cubic spline axis needs 1 or at least 4 nodes; got " +
                                std::to_string(n));
  if (n == 1) return;
  const int m = n + 2;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(m, m);
  // Interpolation rows.
  for (int i = 0; i < n; ++i) {
    a(i, i) = 1.0 / 6.0;
    a(i, i + 1) = 4.0 / 6.0;
    a(i, i + 2) = 1.0 / 6.0;
  }
  // Not-a-knot rows: -c_i + 4 c_{i+1} - 6 c_{i+2} + 4 c_{i+3} - c_{i+4} = 0
  // at i = 0 (knot 1) and i = n - 3 (knot n - 2).
  const double nak[5] = {-1, 4, -6, 4, -1};
  for (int k = 0; k < 5; ++k) {
    a(n, k) = nak[k];
    a(n + 1, n - 3 + k) = nak[k];
  }
  const Eigen::MatrixXd inv = a.fullPivLu().inverse();
  prefilter_.resize(static_cast<std::size_t>(m) * n);
  for (int r = 0; r < m; ++r)
    for (int i = 0; i < n; ++i) prefilter_[r * n + i] = inv(r, i);
}

void CubicSplineAxis::Prefilter(const double* f, std::ptrdiff_t fs, double* c,
                                std::ptrdiff_t cs) const {
  if (n_ == 1) {
    c[0] = f[0];
    return;
  }
  const int m = n_ + 2;
  for (int r = 0; r < m; ++r) {
    const double* row = &prefilter_[static_cast<std::size_t>(r) * n_];
    double v = 0;
    for (int i = 0; i < n_; ++i) v += row[i] * f[i * fs];
    c[r * cs] = v;
  }
}

namespace {

void BasisAt(double f, double* w, double* dw) {
  const double g = 1.0 - f;
  w[0] = g * g * g / 6.0;
  w[1] = (3.0 * f * f * f - 6.0 * f * f + 4.0) / 6.0;
  w[2] = (-3.0 * f * f * f + 3.0 * f * f + 3.0 * f + 1.0) / 6.0;
  w[3] = f * f * f / 6.0;
  dw[0] = -0.5 * g * g;
  dw[1] = 0.5 * (3.0 * f * f - 4.0 * f);
  dw[2] = 0.5 * (-3.0 * f * f + 2.0 * f + 1.0);
  dw[3] = 0.5 * f * f;
}

}  // namespace

SplineWeights CubicSplineAxis::Weights(double t, Extrapolation below, Extrapolation above) const {
  SplineWeights sw;
  if (n_ == 1) {
    sw.first = 0;
    sw.count = 1;
    sw.w[0] = 1.0;
    sw.dw[0] = 0.0;
    return sw;
  }
  const double t_max = n_ - 1;
  if (t >= 0.0 && t <= t_max) {
    int i = static_cast<int>(std::floor(t));
    i = std::min(i, n_ - 2);
    sw.first = i;
    BasisAt(t - i, sw.w, sw.dw);
    return sw;
  }
  // Outside: the end node's value (and slope, for kLinear).
  const bool low = t < 0.0;
  const double edge = low ? 0.0 : t_max;
  const int i = low ? 0 : n_ - 2;
  sw.first = i;
  BasisAt(low ? 0.0 : 1.0, sw.w, sw.dw);
  const Extrapolation mode = low ? below : above;
  if (mode == Extrapolation::kLinear) {
    for (int k = 0; k < 4; ++k) sw.w[k] += (t - edge) * sw.dw[k];
  } else {
    for (int k = 0; k < 4; ++k) sw.dw[k] = 0.0;
  }
  return sw;
}

UniformSpline::UniformSpline(double x0, double h, int n, int width,
                             const std::vector<double>& values, Extrapolation below,
                             Extrapolation above)
    : x0_(x0), h_(h), width_(width), below_(below), above_(above), axis_(n) {
  CheckPositive(h, "spline step");
  Require(width >= 1, "spline width must be >= 1");
  Require(values.size() == static_cast<std::size_t>(n) * width,
          "spline values: expected " + std::to_string(static_cast<std::size_t>(n) * width) +
              ", got " + std::to_string(values.size()));
  coef_.assign(static_cast<std::size_t>(axis_.num_coefficients()) * width, 0.0);
  for (int v = 0; v < width; ++v) axis_.Prefilter(&values[v], width, &coef_[v], width);
}

void UniformSpline::Evaluate(double x, double* value, double* slope) const {
  const SplineWeights sw = axis_.Weights((x - x0_) / h_, below_, above_);
  for (int v = 0; v < width_; ++v) {
    value[v] = 0;
    if (slope) slope[v] = 0;
  }
  const double inv_h = 1.0 / h_;
  for (int k = 0; k < sw.count; ++k) {
    const double* c = &coef_[static_cast<std::size_t>(sw.first + k) * width_];
    for (int v = 0; v < width_; ++v) {
      value[v] += sw.w[k] * c[v];
      if (slope) slope[v] += sw.dw[k] * inv_h * c[v];
    }
  }
}

double UniformSpline::Value(double x, int v) const {
  const SplineWeights sw = axis_.Weights((x - x0_) / h_, below_, above_);
  double s = 0;
  for (int k = 0; k < sw.count; ++k) s += sw.w[k] * coef_[static_cast<std::size_t>(sw.first + k) * width_ + v];
  return s;
}

double UniformSpline::Slope(double x, int v) const {
  const SplineWeights sw = axis_.Weights((x - x0_) / h_, below_, above_);
  double s = 0;
  for (int k = 0; k < sw.count; ++k) s += sw.dw[k] * coef_[static_cast<std::size_t>(sw.first + k) * width_ + v];
  return s / h_;
}

}  // namespace qogi
