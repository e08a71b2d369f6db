#include "engine/util/lookup.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "engine/util/check.h"

namespace qogi {
namespace {

// numpy.interp on ascending nodes (end values held).
inline double Interp(double a, const double* x, const double* y, std::size_t n) {
  if (a <= x[0]) return y[0];
  if (a >= x[n - 1]) return y[n - 1];
  const std::size_t hi = static_cast<std::size_t>(std::upper_bound(x, x + n, a) - x);
  const std::size_t lo = hi - 1;
  const double dx = x[hi] - x[lo];
  return dx > 0 ? y[lo] + (y[hi] - y[lo]) * (a - x[lo]) / dx : y[hi];
}

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
              const double f0 = Interp(a, x + j * num_nodes, y + j * num_nodes, num_nodes);
              const double f1 =
                  Interp(a, x + (j + 1) * num_nodes, y + (j + 1) * num_nodes, num_nodes);
              const double f = (1.0 - w) * f0 + w * f1;
              row[c] = static_cast<float>(v < 0 ? -f : (v > 0 ? f : 0.0));
            }
          }
      },
      num_threads, control);
}

}  // namespace qogi
