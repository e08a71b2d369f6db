#include "engine/inversion/bspline.h"

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <string>

#include "engine/util/check.h"

namespace qogi {

struct CubicSplineAxis::Factor {
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
};

CubicSplineAxis::CubicSplineAxis(int n) : n_(n) {
  Require(n == 1 || n >= 4,
          "a cubic spline axis needs 1 or at least 4 nodes; got " + std::to_string(n));
  if (n == 1) return;
  const int m = n + 2;
  std::vector<Eigen::Triplet<double>> t;
  // Interpolation rows.
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 1.0 / 6.0);
    t.emplace_back(i, i + 1, 4.0 / 6.0);
    t.emplace_back(i, i + 2, 1.0 / 6.0);
  }
  // Not-a-knot rows: -c_i + 4 c_{i+1} - 6 c_{i+2} + 4 c_{i+3} - c_{i+4} = 0
  // at i = 0 (knot 1) and i = n - 3 (knot n - 2).
  const double nak[5] = {-1, 4, -6, 4, -1};
  for (int k = 0; k < 5; ++k) {
    t.emplace_back(n, k, nak[k]);
    t.emplace_back(n + 1, n - 3 + k, nak[k]);
  }
  Eigen::SparseMatrix<double> a(m, m);
  a.setFromTriplets(t.begin(), t.end());
  auto f = std::make_shared<Factor>();
  f->lu.compute(a);
  Require(f->lu.info() == Eigen::Success, "cubic spline collocation matrix is singular");
  factor_ = f;
}

void CubicSplineAxis::Prefilter(const double* f, std::ptrdiff_t fs, double* c,
                                std::ptrdiff_t cs) const {
  if (n_ == 1) {
    c[0] = f[0];
    return;
  }
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n_ + 2);
  for (int i = 0; i < n_; ++i) rhs[i] = f[i * fs];
  const Eigen::VectorXd sol = factor_->lu.solve(rhs);
  for (int r = 0; r < n_ + 2; ++r) c[r * cs] = sol[r];
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
  for (int k = 0; k < sw.count; ++k)
    s += sw.w[k] * coef_[static_cast<std::size_t>(sw.first + k) * width_ + v];
  return s;
}

double UniformSpline::Slope(double x, int v) const {
  const SplineWeights sw = axis_.Weights((x - x0_) / h_, below_, above_);
  double s = 0;
  for (int k = 0; k < sw.count; ++k)
    s += sw.dw[k] * coef_[static_cast<std::size_t>(sw.first + k) * width_ + v];
  return s / h_;
}

}  // namespace qogi
