// A minimal parallel-for over an index range, with cancellation and progress.
//
// Work is split into contiguous chunks handed out dynamically to
// `num_threads` workers; the calling thread is one of them and is the only one
// that calls the RunControl hooks, so a hook may safely take Python's GIL.
#pragma once

#include <cstddef>
#include <functional>

namespace qogi {

// Hooks a long computation calls between chunks of work. Both are optional.
struct RunControl {
  // Returns true to ask the computation to stop; it then throws qogi::Cancelled.
  std::function<bool()> cancelled;
  // Receives the finished fraction in [0, 1].
  std::function<void(double)> progress;
};

// Number of worker threads to use for `requested` (0 = all hardware threads).
int ResolveThreads(int requested);

// Calls body(begin, end) over [0, n) in chunks of at most `chunk` indices.
// Exceptions thrown by `body` stop the loop and are rethrown on the caller.
void ParallelFor(std::size_t n, std::size_t chunk,
                 const std::function<void(std::size_t, std::size_t)>& body, int num_threads = 0,
                 const RunControl* control = nullptr);

}  // namespace qogi
