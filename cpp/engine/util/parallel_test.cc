#include "engine/util/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <stdexcept>
#include <vector>

#include "engine/util/check.h"

namespace qogi {
namespace {

TEST(ParallelFor, VisitsEveryIndexExactlyOnce) {
  std::vector<int> hits(10007, 0);
  ParallelFor(hits.size(), 64, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) hits[i] += 1;
  }, 4);
  for (int h : hits) EXPECT_EQ(h, 1);
}

TEST(ParallelFor, RethrowsWorkerException) {
  EXPECT_THROW(ParallelFor(1000, 10, [](std::size_t b, std::size_t) {
    if (b == 500) throw std::invalid_argument("bad");
  }, 2), std::invalid_argument);
}

TEST(ParallelFor, CancellationStopsEarlyAndThrows) {
  std::atomic<std::size_t> processed{0};
  RunControl control;
  control.cancelled = [] { return true; };
  EXPECT_THROW(ParallelFor(1000000, 1, [&](std::size_t, std::size_t) {
    ++processed;
  }, 2, &control), Cancelled);
  EXPECT_LT(processed.load(), 1000000u);
}

TEST(ParallelFor, ProgressEndsAtOne) {
  double last = -1;
  RunControl control;
  control.progress = [&](double f) { last = f; };
  ParallelFor(100, 7, [](std::size_t, std::size_t) {}, 2, &control);
  EXPECT_DOUBLE_EQ(last, 1.0);
}

TEST(ResolveThreads, RejectsNegative) {
  EXPECT_THROW(ResolveThreads(-1), std::invalid_argument);
  EXPECT_GE(ResolveThreads(0), 1);
}

}  // namespace
}  // namespace qogi
