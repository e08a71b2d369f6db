// Post-processing of velocity fields, as pure functions on masks: outlier
// detection by the normalised median test, replacement of rejected vectors,
// temporal filtering over a window of frames, and plume-only masks.
//
// Vector fields are CV_32F maps u, v [px/frame] (a dense per-pixel flow or a
// PIV grid); masks are CV_8U, nonzero = set. Inputs are never modified.
#pragma once

#include <opencv2/core.hpp>

#include <vector>

namespace qogi {

struct MedianTestOptions {
  // Threshold on the normalised residual |u0 - um| / (rm + epsilon), per
  // component. Westerweel & Scarano (2005) recommend 2. > 0. Default 2.
  double threshold = 2.0;
  // Noise level of the vectors [px/frame] added to the median residual rm:
  // keeps smooth fields from being flagged. > 0. Default 0.1.
  double epsilon = 0.1;
  // Neighbourhood radius [vectors]: 1 = the 8 neighbours of a 3 x 3 block.
  // [1, 10]. Default 1.
  int radius = 1;

  void Check() const;
};

// Normalised median test (Westerweel & Scarano, "Universal outlier detection
// for PIV data", Exp. Fluids 39, 1096-1100, 2005). For every valid vector,
// with um the median of its valid neighbours' u and rm the median of
// |u_i - um| over them (same for v), the vector is an outlier when
// |u0 - um| / (rm + epsilon) > threshold for u or for v. Vectors with fewer
// than 2 valid neighbours are not tested. Returns CV_8U, 1 = outlier.
cv::Mat NormalisedMedianTest(const cv::Mat& u, const cv::Mat& v, const cv::Mat& valid,
                             const MedianTestOptions& options = {});

// Replaces every vector where `keep` is 0 by the median of its kept (or
// already replaced) 8 neighbours, growing inwards from the kept vectors for at
// most max_distance sweeps (0 = until every vector is replaced). Writes the
// new fields and `filled` (CV_8U, 1 = vector replaced by this call). Vectors
// that could not be reached keep their value and are not marked filled.
void ReplaceVectors(const cv::Mat& u, const cv::Mat& v, const cv::Mat& keep, int max_distance,
                    cv::Mat& u_out, cv::Mat& v_out, cv::Mat& filled);

enum class TemporalStatistic { kMean, kMedian };

struct TemporalFilterOptions {
  // Window length [frames], odd, centred on each frame (shortened at the
  // ends of the sequence). [1, 1001]. Default 5.
  int window = 5;
  // Mean or median of the valid vectors in the window. Default median.
  TemporalStatistic statistic = TemporalStatistic::kMedian;
  // Share of the window's frames in which a pixel's vector must be valid for
  // the filtered vector to be valid. [0, 1]. Default 0.5.
  double min_valid_fraction = 0.5;

  void Check() const;
};

// Filters a sequence of vector fields pixel by pixel over time: vector t of
// the output is the mean or median of the valid vectors at that pixel in
// frames [t - window/2, t + window/2]. u, v, valid: one map per frame, all of
// one size. Pixels without enough valid vectors keep their input value and
// are invalid in valid_out.
void TemporalFilter(const std::vector<cv::Mat>& u, const std::vector<cv::Mat>& v,
                    const std::vector<cv::Mat>& valid, const TemporalFilterOptions& options,
                    std::vector<cv::Mat>& u_out, std::vector<cv::Mat>& v_out,
                    std::vector<cv::Mat>& valid_out);

// Backward displacement of a forward map x -> x + w(x): b(x) = y - x where
// y + w(y) = x, by the fixed-point iteration y = x - w(y) (w sampled
// bilinearly, replicated beyond the border), at most `iterations` sweeps,
// each pixel stopping once its vector moves by less than 1e-4 px. Converges
// where |grad w| < 1, i.e. wherever the map does not fold. u, v: CV_32F, one
// size.
void InvertDisplacement(const cv::Mat& u, const cv::Mat& v, int iterations, cv::Mat& bu,
                        cv::Mat& bv);

// Velocity [px/frame] at the time of every frame of a sequence, from the
// forward displacements of its consecutive pairs (pair k maps frame k to
// frame k + 1; T - 1 pairs in, T maps out). For frame t, 0 < t < T - 1:
//
//   vel_t(x) = (w_t(x) - b_t(x)) / 2,   b_t the inverse of w_{t-1},
//
// the central difference of the trajectory through x at time t: exact for
// trajectories with constant acceleration, where w_t alone (the mean velocity
// over [t, t + 1] along the path, i.e. of the gas at x + w_t / 2 half a frame
// later) is off by half the acceleration times the frame interval. A gas
// parcel leaving a laminar exit at 0.3 m/s and reaching 0.7 m/s 2 cm higher
// accelerates by ~10 m/s2: at 15 Hz that is 0.3 m/s, i.e. 50 %, of error
// in the forward displacement alone. Frame 0 gets w_0, frame T - 1 gets
// -b_{T-1}. Needs T - 1 >= 1 pairs of one size. Frames are processed in
// parallel on `num_threads` threads (0 = all); outputs passed in with T maps
// of the right size and type (e.g. views of a caller's array) are written in
// place.
void FrameVelocity(const std::vector<cv::Mat>& u, const std::vector<cv::Mat>& v,
                   std::vector<cv::Mat>& u_out, std::vector<cv::Mat>& v_out, int num_threads = 0);

struct PlumeMaskOptions {
  // Absolute threshold in the input's unit (e.g. kg/m2): gas where the value
  // is >= it. >= 0. Default 0 (only the relative threshold applies).
  double threshold = 0.0;
  // Threshold relative to the frame's 99th-percentile value. [0, 1].
  // Default 0.1. The larger of the two thresholds applies.
  double relative_threshold = 0.1;
  // Radius [px] of the morphological opening that removes isolated noise
  // pixels (0 = none). [0, 50]. Default 1.
  int open_radius = 1;
  // Radius [px] of the closing that fills small holes (0 = none). [0, 50].
  // Default 2.
  int close_radius = 2;
  // Connected regions smaller than this [px] are dropped. >= 0. Default 20.
  int min_area = 20;
  // Final dilation [px] so that the plume edge (where texture is) is kept.
  // [0, 50]. Default 2.
  int dilate_radius = 2;

  void Check() const;
};

// Gas mask of one column-density (or contrast) map: threshold, opening,
// closing, removal of small regions, dilation. Returns CV_8U, 1 = gas.
cv::Mat PlumeMask(const cv::Mat& density, const PlumeMaskOptions& options = {});

}  // namespace qogi
