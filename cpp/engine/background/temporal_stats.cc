#include "engine/background/temporal_stats.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "engine/util/check.h"
#include "engine/util/parallel.h"

namespace qogi {
namespace {

// Pixels per chunk of work: a chunk gathers its pixels' series into one
// buffer (values x frames), a few MB at most.
constexpr std::size_t kChunk = 256;

void CheckStack(const void* frames, std::size_t n_frames, std::size_t frame_stride,
                std::size_t values, std::size_t at_least) {
  Require(frames != nullptr || n_frames * values == 0, "frames is null");
  Require(n_frames >= at_least,
          "need at least " + std::to_string(at_least) + " frames; got " + std::to_string(n_frames));
  Require(n_frames <= 1 || frame_stride >= values, "frame_stride (" + std::to_string(frame_stride) +
                                                       ") is less than the values per frame (" +
                                                       std::to_string(values) + ")");
}

// Series of pixels [begin, end) gathered into buf (pixel-major: each
// pixel's n_frames values contiguous).
template <typename T>
void Gather(const T* frames, std::size_t n_frames, std::size_t frame_stride, std::size_t begin,
            std::size_t end, std::vector<T>* buf) {
  buf->resize((end - begin) * n_frames);
  for (std::size_t t = 0; t < n_frames; ++t) {
    const T* row = frames + t * frame_stride;
    for (std::size_t p = begin; p < end; ++p) (*buf)[(p - begin) * n_frames + t] = row[p];
  }
}

// numpy's median of v (reordered) in T: the middle value, or the mean of
// the two middle values computed in T (np.mean of float32 sums in float32).
template <typename T>
T Median(T* v, std::size_t n) {
  const std::size_t m = n / 2;
  std::nth_element(v, v + m, v + n);
  if (n % 2) return v[m];
  const T lo = *std::max_element(v, v + m);
  const T sum = static_cast<T>(lo + v[m]);
  return static_cast<T>(sum / static_cast<T>(2));
}

}  // namespace

template <typename T>
void TemporalPercentiles(const T* frames, std::size_t n_frames, std::size_t frame_stride,
                         std::size_t values, const std::vector<double>& percentiles, double* out,
                         int num_threads) {
  CheckStack(frames, n_frames, frame_stride, values, 1);
  for (double q : percentiles)
    Require(std::isfinite(q) && q >= 0 && q <= 100,
            "percentiles must lie within [0, 100]; got " + FormatNumber(q));
  // numpy: quantile = q / 100; virtual index (T - 1) quantile; its floor
  // and the next index (clipped), gamma the fraction.
  struct Where {
    std::size_t prev, next;
    double gamma;
  };
  std::vector<Where> at;
  for (double q : percentiles) {
    const double virt = static_cast<double>(n_frames - 1) * (q / 100.0);
    const double fl = std::floor(virt);
    std::size_t prev = static_cast<std::size_t>(std::max(0.0, fl));
    prev = std::min(prev, n_frames - 1);
    const std::size_t next = std::min(prev + 1, n_frames - 1);
    at.push_back({prev, next, virt - fl});
  }
  ParallelFor(
      values, kChunk,
      [&](std::size_t begin, std::size_t end) {
        std::vector<T> buf;
        Gather(frames, n_frames, frame_stride, begin, end, &buf);
        for (std::size_t p = begin; p < end; ++p) {
          T* v = buf.data() + (p - begin) * n_frames;
          if (std::any_of(v, v + n_frames, [](T x) { return std::isnan(x); })) {
            for (std::size_t k = 0; k < at.size(); ++k)
              out[k * values + p] = std::numeric_limits<double>::quiet_NaN();
            continue;  // numpy: a series holding NaN has NaN percentiles
          }
          // Sorted once: every order statistic asked for at hand (numpy
          // partitions at each of them; the values there are the same).
          std::sort(v, v + n_frames, [](T a, T b) { return a < b; });
          for (std::size_t k = 0; k < at.size(); ++k) {
            const T a = v[at[k].prev], b = v[at[k].next];
            const T diff = static_cast<T>(b - a);  // in T, as numpy subtracts
            const double g = at[k].gamma;
            out[k * values + p] =
                g >= 0.5 ? static_cast<double>(b) - static_cast<double>(diff) * (1.0 - g)
                         : static_cast<double>(a) + static_cast<double>(diff) * g;
          }
        }
      },
      num_threads);
}

template <typename T>
void DifferenceSpread(const T* frames, std::size_t n_frames, std::size_t frame_stride,
                      std::size_t values, T* out, int num_threads) {
  CheckStack(frames, n_frames, frame_stride, values, 2);
  const std::size_t nd = n_frames - 1;
  ParallelFor(
      values, kChunk,
      [&](std::size_t begin, std::size_t end) {
        std::vector<T> buf, d(nd);
        Gather(frames, n_frames, frame_stride, begin, end, &buf);
        for (std::size_t p = begin; p < end; ++p) {
          const T* v = buf.data() + (p - begin) * n_frames;
          if (std::any_of(v, v + n_frames, [](T x) { return std::isnan(x); })) {
            out[p] = std::numeric_limits<T>::quiet_NaN();  // numpy's median of NaN
            continue;
          }
          for (std::size_t t = 0; t < nd; ++t) d[t] = static_cast<T>(v[t + 1] - v[t]);
          std::vector<T> work(d);
          const T med = Median(work.data(), nd);
          for (std::size_t t = 0; t < nd; ++t) work[t] = std::abs(static_cast<T>(d[t] - med));
          out[p] = Median(work.data(), nd);
        }
      },
      num_threads);
}

template void TemporalPercentiles<float>(const float*, std::size_t, std::size_t, std::size_t,
                                         const std::vector<double>&, double*, int);
template void TemporalPercentiles<double>(const double*, std::size_t, std::size_t, std::size_t,
                                          const std::vector<double>&, double*, int);
template void DifferenceSpread<float>(const float*, std::size_t, std::size_t, std::size_t, float*,
                                      int);
template void DifferenceSpread<double>(const double*, std::size_t, std::size_t, std::size_t,
                                       double*, int);

}  // namespace qogi
