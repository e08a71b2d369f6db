// Interpolating cubic B-splines on uniform grids, the building block of the
// inversion's per-scene tables.
//
// On an axis with n >= 4 nodes at grid coordinates t = 0, 1, ..., n-1 a cubic
// spline is s(t) = sum_j c_j beta3(t - j + 1) over n + 2 coefficients
// c_0 .. c_{n+1} (c_0 belongs to the virtual node t = -1). The coefficients
// interpolate the node values, (c_i + 4 c_{i+1} + c_{i+2}) / 6 = f_i, with
// not-a-knot end conditions (the third derivative is continuous at the second
// and the second-to-last node), so a cubic polynomial is reproduced exactly
// and the error is O(h^4) up to the ends. The spline is C2 inside the grid;
// outside it is continued linearly with the end value and slope (C1), or held
// at the end value (kHold). An axis with one node is constant.
//
// Tensor products of axes are formed by the callers: prefilter along each
// axis in turn, then evaluate with the product of the per-axis weights.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

namespace qogi {

// How a spline continues outside [0, n-1].
enum class Extrapolation {
  kLinear,  // value and slope of the end node, continued linearly
  kHold,    // value of the end node, zero slope
};

// Per-axis interpolation weights at one coordinate.
struct SplineWeights {
  int first = 0;       // index of the first of the `count` coefficients used
  int count = 4;       // 4, or 1 on a one-node axis
  double w[4] = {0, 0, 0, 0};   // value weights
  double dw[4] = {0, 0, 0, 0};  // d(value)/dt weights [per grid unit]
};

class CubicSplineAxis {
 public:
  // An axis with `num_nodes` nodes (1, or >= 4).
  explicit CubicSplineAxis(int num_nodes = 1);

  int num_nodes() const { return n_; }
  // Coefficients per line: n + 2, or 1 on a one-node axis.
  int num_coefficients() const { return n_ == 1 ? 1 : n_ + 2; }

  // Coefficients of one line: values f[k * f_stride] (k < n) into
  // c[j * c_stride] (j < num_coefficients()). f and c must not overlap.
  void Prefilter(const double* f, std::ptrdiff_t f_stride, double* c,
                 std::ptrdiff_t c_stride) const;

  // Weights at grid coordinate t; `below`/`above` choose the continuation
  // outside [0, n-1].
  SplineWeights Weights(double t, Extrapolation below = Extrapolation::kLinear,
                        Extrapolation above = Extrapolation::kLinear) const;

 private:
  struct Factor;  // sparse LU of the (n + 2) x (n + 2) collocation matrix
  int n_ = 1;
  std::shared_ptr<const Factor> factor_;
};

// A one-dimensional spline over [x0, x0 + (n-1) h] holding `width` values per
// node (evaluated together), e.g. a band radiance table or the Planck basis.
class UniformSpline {
 public:
  UniformSpline() = default;
  // values[k * width + v] at x = x0 + k h, k < n (n = 1 or >= 4).
  UniformSpline(double x0, double h, int num_nodes, int width, const std::vector<double>& values,
                Extrapolation below = Extrapolation::kLinear,
                Extrapolation above = Extrapolation::kLinear);

  double x0() const { return x0_; }
  double step() const { return h_; }
  double x_max() const { return x0_ + h_ * (axis_.num_nodes() - 1); }
  int width() const { return width_; }
  bool empty() const { return width_ == 0; }

  // All `width` values at x into value[v] and, when given, d/dx into slope[v].
  void Evaluate(double x, double* value, double* slope = nullptr) const;
  // Value v only.
  double Value(double x, int v = 0) const;
  double Slope(double x, int v = 0) const;
  // B-spline coefficients [coefficient * width + v] (num_nodes + 2 per value).
  const std::vector<double>& coefficients() const { return coef_; }

 private:
  double x0_ = 0, h_ = 1;
  int width_ = 0;
  Extrapolation below_ = Extrapolation::kLinear, above_ = Extrapolation::kLinear;
  CubicSplineAxis axis_;
  std::vector<double> coef_;  // [coefficient * width + v]
};

}  // namespace qogi
