// Monotone piecewise-linear lookups applied line by line to an image stack.
#pragma once

#include <cstddef>

#include "engine/util/parallel.h"

namespace qogi {

// Replaces every value v of `stack` [T][H][W] (float, in place) by
//   sign(v) ((1 - w_k) f_j(|v|) + w_k f_{j+1}(|v|)),  j = node_of_line[k],
// where k is the value's line (its row when lines_are_rows, else its
// column), w_k = weight_of_line[k] in [0, 1], and f_j the piecewise-linear
// function through (x[j][m], y[j][m]), m < num_nodes, x ascending, held at
// the end values outside [x[j][0], x[j][num_nodes - 1]] (as numpy.interp).
// x and y are [num_tables][num_nodes]; node_of_line[k] + 1 < num_tables.
void LookupLines(float* stack, std::size_t frames, std::size_t height, std::size_t width,
                 bool lines_are_rows, const double* x, const double* y, std::size_t num_tables,
                 std::size_t num_nodes, const int* node_of_line, const double* weight_of_line,
                 int num_threads = 0, const RunControl* control = nullptr);

}  // namespace qogi
