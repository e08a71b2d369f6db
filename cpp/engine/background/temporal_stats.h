// Per-pixel statistics over time of a stack of frames: the temporal-
// percentile background's (python/qogi/pipeline/background_choice.py).
//
// A stack is T frames of P values each (a frame's channels and pixels, in
// any order, contiguous within a frame), frame t starting at
// frames + t * frame_stride. Both functions equal numpy's to the last bit,
// for float and double values:
//
// * TemporalPercentiles: np.percentile(stack, q, axis=0) (numpy's default,
//   "linear": Hyndman and Fan's 7th definition, the order statistics at
//   (T - 1) q / 100 interpolated as numpy's _lerp does), as double;
// * DifferenceSpread: np.median(|d - np.median(d, axis=0)|, axis=0) with
//   d = np.diff(stack, axis=0), the frame-to-frame differences' median
//   absolute deviation (the pixel noise times sqrt(2) / 1.4826), in the
//   values' own type (numpy's median of an even count: the mean of the two
//   middle values in that type).
//
// Usage:
//   std::vector<double> out(q.size() * P);
//   qogi::TemporalPercentiles(frames, T, P, P, q, out.data());
#pragma once

#include <cstddef>
#include <vector>

namespace qogi {

template <typename T>
void TemporalPercentiles(const T* frames, std::size_t n_frames, std::size_t frame_stride,
                         std::size_t values, const std::vector<double>& percentiles, double* out,
                         int num_threads = 1);

template <typename T>
void DifferenceSpread(const T* frames, std::size_t n_frames, std::size_t frame_stride,
                      std::size_t values, T* out, int num_threads = 1);

}  // namespace qogi
