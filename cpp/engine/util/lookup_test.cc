#include "engine/util/lookup.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace qogi {
namespace {

// Two tables (f_0 = 2x, f_1 = 4x on [0, 1], held beyond), three lines with
// weights 0, 0.5, 1: each value becomes sign(v) (2 + 2 w) |v|, clamped at |v| = 1.
TEST(LookupLines, BlendsTwoTablesPerLineWithSignAndEndValues) {
  const std::vector<double> x{0.0, 0.5, 1.0, 0.0, 0.5, 1.0};
  const std::vector<double> y{0.0, 1.0, 2.0, 0.0, 2.0, 4.0};
  const std::vector<int> node{0, 0, 0};
  const std::vector<double> w{0.0, 0.5, 1.0};
  for (bool rows : {true, false}) {
    // 2 frames of 3 x 3 (lines: rows or columns).
    std::vector<float> s{0.25f, -0.5f, 2.0f, 0.25f, -0.5f, 2.0f, 0.25f, -0.5f, 2.0f,
                         0.0f,  0.75f, -3.f, 0.0f,  0.75f, -3.f, 0.0f,  0.75f, -3.f};
    const std::vector<float> in = s;
    LookupLines(s.data(), 2, 3, 3, rows, x.data(), y.data(), 2, 3, node.data(), w.data(), 2);
    for (std::size_t t = 0; t < 2; ++t)
      for (std::size_t r = 0; r < 3; ++r)
        for (std::size_t c = 0; c < 3; ++c) {
          const std::size_t i = (t * 3 + r) * 3 + c;
          const double v = in[i];
          const double a = std::min(std::abs(v), 1.0);
          const double slope = 2.0 + 2.0 * w[rows ? r : c];
          const double want = (v < 0 ? -1 : (v > 0 ? 1 : 0)) * slope * a;
          EXPECT_NEAR(s[i], want, 1e-6) << "rows " << rows << " at " << i;
        }
  }
}

// Geometric nodes over eight decades (as the pipeline's contrast -> column
// lookups), a repeated node and values at, between, below and above the
// nodes: exactly numpy.interp's values (the same interval as a binary search).
TEST(LookupLines, EqualsABinarySearchInterpolationExactly) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const std::size_t n = 65;
  std::vector<double> x(2 * n), y(2 * n);
  for (std::size_t j = 0; j < 2; ++j) {
    x[j * n] = 0.0;
    y[j * n] = 0.0;
    for (std::size_t m = 1; m < n; ++m) {
      x[j * n + m] = 1e-8 * std::pow(10.0, 8.0 * (m - 1) / (n - 2)) * (1 + 0.1 * j);
      y[j * n + m] = std::sqrt(x[j * n + m]) * (2 + j);
    }
    x[j * n + 30] = x[j * n + 29];  // a repeated node
  }
  auto reference = [&](double a, std::size_t j) {
    const double* xs = &x[j * n];
    const double* ys = &y[j * n];
    if (a <= xs[0]) return ys[0];
    if (a >= xs[n - 1]) return ys[n - 1];
    const std::size_t hi = std::upper_bound(xs, xs + n, a) - xs, lo = hi - 1;
    const double dx = xs[hi] - xs[lo];
    return dx > 0 ? ys[lo] + (ys[hi] - ys[lo]) * (a - xs[lo]) / dx : ys[hi];
  };
  const std::size_t w = 4001;
  std::vector<float> s(w);
  for (std::size_t c = 0; c < w; ++c) {
    const double r = u01(rng);
    s[c] =
        static_cast<float>(c % 7 == 0 ? x[c % n] : (c % 2 ? -1 : 1) * std::pow(10.0, -10 + 11 * r));
  }
  const std::vector<float> in = s;
  const std::vector<int> node{0};
  const std::vector<double> wt{0.3};
  LookupLines(s.data(), 1, 1, w, true, x.data(), y.data(), 2, n, node.data(), wt.data(), 2);
  for (std::size_t c = 0; c < w; ++c) {
    const double v = in[c], a = std::abs(v);
    const double f = 0.7 * reference(a, 0) + 0.3 * reference(a, 1);
    EXPECT_EQ(s[c], static_cast<float>(v < 0 ? -f : (v > 0 ? f : 0.0))) << c << " " << v;
  }
}

TEST(LookupLines, RejectsBadLinesAndNodes) {
  const std::vector<double> x{0.0, 1.0, 0.0, 1.0}, y{0.0, 1.0, 0.0, 1.0};
  std::vector<float> s(4, 0.5f);
  const std::vector<int> bad_node{1, 0};
  const std::vector<double> w{0.0, 0.0}, bad_w{0.0, 1.5};
  const std::vector<int> node{0, 0};
  EXPECT_THROW(
      LookupLines(s.data(), 1, 2, 2, true, x.data(), y.data(), 2, 2, bad_node.data(), w.data()),
      std::invalid_argument);
  EXPECT_THROW(
      LookupLines(s.data(), 1, 2, 2, true, x.data(), y.data(), 2, 2, node.data(), bad_w.data()),
      std::invalid_argument);
  const std::vector<double> down{1.0, 0.0, 0.0, 1.0};
  EXPECT_THROW(
      LookupLines(s.data(), 1, 2, 2, true, down.data(), y.data(), 2, 2, node.data(), w.data()),
      std::invalid_argument);
}

}  // namespace
}  // namespace qogi
