#include "engine/util/lookup.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "engine/util/check.h"

namespace qogi {
namespace {

// numpy.interp on ascending nodes (end values held), with the interval found
// from a bucket index over the value's binary exponent and its top three
// mantissa bits (8 buckets per octave) and a short forward scan: the same
// interval as a binary search (the last node <= the value), so the same
// result, without its mispredicted branches.
class Interpolant {
 public:
  Interpolant(const double* x, const double* y, std::size_t n) : x_(x), y_(y), n_(n) {
    // Buckets from the first positive node's octave to the last node's.
    std::size_t first = 0;
    while (first < n_ && !(x_[first] > 0)) ++first;
    if (first >= n_ || n_ < 2) return;
    lo_key_ = Key(x_[first]);
    const long hi_key = Key(x_[n_ - 1]);
    start_.resize(static_cast<std::size_t>(hi_key - lo_key_ + 1));
    std::size_t lo = 0;
    for (long b = lo_key_; b <= hi_key; ++b) {
      const double v = BucketStart(b);
      while (lo + 1 < n_ && x_[lo + 1] <= v) ++lo;
      start_[static_cast<std::size_t>(b - lo_key_)] = lo;
    }
  }

  double operator()(double a) const {
    if (a <= x_[0]) return y_[0];
    if (a >= x_[n_ - 1]) return y_[n_ - 1];
    std::size_t lo = 0;
    if (!start_.empty()) {
      const long b = Key(a) - lo_key_;
      if (b >= 0) lo = start_[std::min(static_cast<std::size_t>(b), start_.size() - 1)];
    }
    while (x_[lo + 1] <= a) ++lo;  // stops before n - 1: a < x[n - 1]
    const std::size_t hi = lo + 1;
    const double dx = x_[hi] - x_[lo];
    return dx > 0 ? y_[lo] + (y_[hi] - y_[lo]) * (a - x_[lo]) / dx : y_[hi];
  }

 private:
  // Bucket of a positive value: its exponent and top 3 mantissa bits.
  static long Key(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    return static_cast<long>(bits >> 49);
  }
  static double BucketStart(long key) {
    const std::uint64_t bits = static_cast<std::uint64_t>(key) << 49;
    double v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }

  const double* x_;
  const double* y_;
  std::size_t n_;
  long lo_key_ = 0;
  std::vector<std::size_t> start_;
};

}  // namespace

void LookupLines(float* stack, std::size_t frames, std::size_t height, std::size_t width,
                 bool lines_are_rows, const double* x, const double* y, std::size_t num_tables,
                 std::size_t num_nodes, const int* node_of_line, const double* weight_of_line,
                 int num_threads, const RunControl* control) {
  Require(num_nodes >= 1, "LookupLines needs at least one node per table");
  const std::size_t lines = lines_are_rows ? height : width;
  for (std::size_t k = 0; k < lines; ++k) {
    const int j = node_of_line[k];
    Require(j >= 0 && static_cast<std::size_t>(j) + 1 < num_tables,
            "node_of_line[" + std::to_string(k) + "] = " + std::to_string(j) +
                " must be within [0, " + std::to_string(num_tables - 1) + ")");
    Require(weight_of_line[k] >= 0 && weight_of_line[k] <= 1,
            "weight_of_line values must be within [0, 1]");
  }
  for (std::size_t j = 0; j < num_tables; ++j)
    for (std::size_t m = 1; m < num_nodes; ++m)
      Require(x[j * num_nodes + m] >= x[j * num_nodes + m - 1],
              "lookup nodes must be ascending (table " + std::to_string(j) + ")");
  std::vector<Interpolant> f;
  for (std::size_t j = 0; j < num_tables; ++j)
    f.emplace_back(x + j * num_nodes, y + j * num_nodes, num_nodes);
  ParallelFor(
      frames, 1,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t t = b; t < e; ++t)
          for (std::size_t r = 0; r < height; ++r) {
            float* row = stack + (t * height + r) * width;
            for (std::size_t c = 0; c < width; ++c) {
              const std::size_t k = lines_are_rows ? r : c;
              const std::size_t j = static_cast<std::size_t>(node_of_line[k]);
              const double w = weight_of_line[k];
              const double v = row[c];
              const double a = std::abs(v);
              const double fv = (1.0 - w) * f[j](a) + w * f[j + 1](a);
              row[c] = static_cast<float>(v < 0 ? -fv : (v > 0 ? fv : 0.0));
            }
          }
      },
      num_threads, control);
}

}  // namespace qogi
