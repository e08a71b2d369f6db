#include "engine/util/parallel.h"

#include <gtest/gtest.h>

#include <pthread.h>

#include <atomic>
#include <chrono>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <vector>

#include "engine/util/check.h"

namespace qogi {
namespace {

TEST(ParallelFor, VisitsEveryIndexExactlyOnce) {
  std::vector<int> hits(10007, 0);
  ParallelFor(
      hits.size(), 64,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) hits[i] += 1;
      },
      4);
  for (int h : hits) EXPECT_EQ(h, 1);
}

TEST(ParallelFor, RethrowsWorkerException) {
  EXPECT_THROW(ParallelFor(
                   1000, 10,
                   [](std::size_t b, std::size_t) {
                     if (b == 500) throw std::invalid_argument("bad");
                   },
                   2),
               std::invalid_argument);
}

TEST(ParallelFor, CancellationStopsEarlyAndThrows) {
  std::atomic<std::size_t> processed{0};
  RunControl control;
  control.cancelled = [] { return true; };
  EXPECT_THROW(ParallelFor(
                   1000000, 1, [&](std::size_t, std::size_t) { ++processed; }, 2, &control),
               Cancelled);
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

// A thread torn down inside a hook (pthread_exit: what Python does to a
// thread that takes the GIL while the interpreter exits) unwinds through
// ParallelFor: the workers are joined and the unwind continues. Swallowing it
// aborted the process ("FATAL: exception not rethrown").
namespace {
struct ExitInHook {
  std::atomic<int> chunks{0};
  bool returned = false;
};

void* RunExitingInHook(void* arg) {
  auto* s = static_cast<ExitInHook*>(arg);
  qogi::RunControl control;
  control.cancelled = [] {
    pthread_exit(nullptr);
    return false;
  };
  qogi::ParallelFor(
      1000, 1,
      [s](std::size_t, std::size_t) {
        s->chunks.fetch_add(1);
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      },
      4, &control);
  s->returned = true;
  return nullptr;
}
}  // namespace

TEST(ParallelFor, LetsAThreadExitFromAHookAfterJoiningItsWorkers) {
  ExitInHook state;
  pthread_t t;
  ASSERT_EQ(pthread_create(&t, nullptr, RunExitingInHook, &state), 0);
  ASSERT_EQ(pthread_join(t, nullptr), 0);
  EXPECT_FALSE(state.returned);         // the thread exited inside ParallelFor
  EXPECT_LT(state.chunks.load(), 1000);  // and the workers stopped early
}
