#include "engine/util/lookup.h"

#include <gtest/gtest.h>

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

TEST(LookupLines, RejectsBadLinesAndNodes) {
  const std::vector<double> x{0.0, 1.0, 0.0, 1.0}, y{0.0, 1.0, 0.0, 1.0};
  std::vector<float> s(4, 0.5f);
  const std::vector<int> bad_node{1, 0};
  const std::vector<double> w{0.0, 0.0}, bad_w{0.0, 1.5};
  const std::vector<int> node{0, 0};
  EXPECT_THROW(LookupLines(s.data(), 1, 2, 2, true, x.data(), y.data(), 2, 2, bad_node.data(),
                           w.data()),
               std::invalid_argument);
  EXPECT_THROW(LookupLines(s.data(), 1, 2, 2, true, x.data(), y.data(), 2, 2, node.data(),
                           bad_w.data()),
               std::invalid_argument);
  const std::vector<double> down{1.0, 0.0, 0.0, 1.0};
  EXPECT_THROW(LookupLines(s.data(), 1, 2, 2, true, down.data(), y.data(), 2, 2, node.data(),
                           w.data()),
               std::invalid_argument);
}

}  // namespace
}  // namespace qogi
