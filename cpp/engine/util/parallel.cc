#include "engine/util/parallel.h"

#include <cxxabi.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "engine/util/check.h"

namespace qogi {

int ResolveThreads(int requested) {
  if (requested < 0)
    throw std::invalid_argument("num_threads must be >= 0 (0 = all cores); got " +
                                std::to_string(requested));
  if (requested > 0) return requested;
  const unsigned hw = std::thread::hardware_concurrency();
  return hw == 0 ? 1 : static_cast<int>(hw);
}

void ParallelFor(std::size_t n, std::size_t chunk,
                 const std::function<void(std::size_t, std::size_t)>& body, int num_threads,
                 const RunControl* control) {
  if (n == 0) return;
  chunk = std::max<std::size_t>(1, chunk);
  const std::size_t num_chunks = (n + chunk - 1) / chunk;
  const int threads =
      static_cast<int>(std::min<std::size_t>(num_chunks, ResolveThreads(num_threads)));

  std::atomic<std::size_t> next{0};
  std::atomic<std::size_t> done{0};
  std::atomic<bool> stop{false};
  std::exception_ptr error;
  std::mutex error_mutex;

  auto record_error = [&](std::exception_ptr e) {
    std::lock_guard<std::mutex> lock(error_mutex);
    if (!error) error = e;
    stop = true;
  };
  // Runs f; false when it threw (the error recorded, the others stopped). A
  // thread being torn down (pthread_exit / pthread_cancel, e.g. a Python
  // thread that takes the GIL while the interpreter exits) stops the others
  // and lets the unwind continue: swallowing it aborts the process ("FATAL:
  // exception not rethrown").
  auto guarded = [&](const auto& f) {
    try {
      f();
      return true;
    } catch (abi::__forced_unwind&) {
      stop = true;
      throw;
    } catch (...) {
      record_error(std::current_exception());
      return false;
    }
  };
  auto worker = [&](bool is_caller) {
    auto last_hook = std::chrono::steady_clock::now() - std::chrono::seconds(1);
    while (!stop) {
      const std::size_t c = next.fetch_add(1);
      if (c >= num_chunks) break;
      const std::size_t b = c * chunk, e = std::min(n, b + chunk);
      if (!guarded([&] { body(b, e); })) break;
      const std::size_t finished = done.fetch_add(1) + 1;
      if (is_caller && control) {
        const auto now = std::chrono::steady_clock::now();
        if (now - last_hook < std::chrono::milliseconds(50) && finished < num_chunks) continue;
        last_hook = now;
        const bool ok = guarded([&] {
          if (control->cancelled && control->cancelled()) throw Cancelled();
          if (control->progress) control->progress(static_cast<double>(finished) / num_chunks);
        });
        if (!ok) break;
      }
    }
  };

  std::vector<std::thread> pool;
  pool.reserve(threads > 0 ? threads - 1 : 0);
  auto join_all = [&pool] {
    for (auto& t : pool)
      if (t.joinable()) t.join();
  };
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker, false);
  try {
    worker(true);
  } catch (...) {
    // Only a forced unwind gets here: the workers see `stop` and finish
    // their chunk; destroying joinable threads would std::terminate.
    join_all();
    throw;
  }
  join_all();
  if (error) std::rethrow_exception(error);
  if (control && control->progress) control->progress(1.0);
}

}  // namespace qogi
