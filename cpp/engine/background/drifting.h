// Background of a scene whose background moves on its own: broken clouds
// drifting across a sky, in front of (or behind) a static scene.
//
// Model (x a pixel, t a time, v the drift velocity):
//
//   background(x, t) = S(x) + M_t(x - v t),
//
// a static layer S (the sky's gradient and texture, a wall) and a drifting
// layer M (the clouds) carried rigidly at v, slowly changing in its own frame.
//
// * MeasureDrift: v from the run's frames. Differences of frames k apart,
//   E_i = F_{i+k} - F_i, hold no static layer at all (it cancels exactly),
//   and for a rigidly drifting layer E_j(x) = E_i(x - v (t_j - t_i)): the
//   difference images are shifted copies of each other, and the engine's
//   robust rigid registration (Tukey-weighted Gauss-Newton, which leaves out
//   the gas's own changes) measures v between them, first over a short lag
//   from rest, then over a long one warm-started from it.
// * DriftingBackground: S and M by alternating sign-aware low percentiles
//   (the gas raises a pixel's radiance, or lowers it: its background is the
//   low, or high, percentile of what the pixel sees over time):
//     M_k(y) = P_{t in window k} [F_t(y + v t) - S(y + v t)]  (the drifting frame)
//     S(x)   = P_{all t} [F_t(x) - M_t(x - v t)]               (the camera's frame)
//   M on knots every half window, each from the frames within half a window
//   of it (a running estimate: the clouds may change shape), linear in time
//   between knots. With v = 0 it is a running per-pixel percentile.
//
// Usage:
//   qogi::DriftResult d = qogi::MeasureDrift(frames, times_s, qogi::DriftOptions{});
//   qogi::DriftingBackground bg(frames, times_s, d.vx_px_s, d.vy_px_s, +1.0,
//                               qogi::DriftingBackgroundOptions{});
//   cv::Mat b;
//   bg.At(times_s[3], &b);  // the background of frame 3
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace qogi {

struct DriftOptions {
  // Frames between the two frames of each difference image, >= 1 (default 5).
  int difference_lag = 5;
  // Frames between the difference images registered from rest, >= 1 (default 2;
  // the drift over it must stay within the registration's basin, a few px).
  int short_lag = 2;
  // Frames between the difference images registered warm-started from the
  // short lag's velocity, >= short_lag (default 15): the precision grows with it.
  int long_lag = 15;
  // Registrations at most per lag, >= 1 (default 15), spread over the run.
  int max_pairs = 15;
  // Gaussian smoothing before registration [px sigma], 0-20 (default 1).
  double smoothing_px = 1.0;

  // Throws std::invalid_argument naming the first bad field.
  void Check() const;
};

struct DriftResult {
  double vx_px_s = 0.0;  // drift velocity to the right [px/s] (median over pairs)
  double vy_px_s = 0.0;  // drift velocity downwards [px/s]
  // Spread of the pairs' velocities (1.4826 MAD) [px/s]: how rigidly the
  // background drifts (not the precision of the median).
  double spread_vx_px_s = 0.0;
  double spread_vy_px_s = 0.0;
  int pairs = 0;       // registrations made at the long lag (short when none)
  int converged = 0;   // of which converged
  double inlier_fraction = 0.0;  // median fraction of pixels the fit kept
  // At least half the registrations converged (else v is 0 and not measured).
  bool measured = false;
};

// The drift velocity of the background of `frames` (same-size single-channel
// float images, one channel, in time order, evenly spaced) at `times_s` [s].
// Throws std::invalid_argument on bad input (fewer frames than
// difference_lag + short_lag + 1, sizes, times not increasing).
DriftResult MeasureDrift(const std::vector<cv::Mat>& frames, const std::vector<double>& times_s,
                         const DriftOptions& options);

struct DriftingBackgroundOptions {
  // Percentile taken on the gas's low side [%], in (0, 50) (default 5): the
  // low percentile for a gas that raises the radiance, 100 - it otherwise.
  double percentile = 5.0;
  // Length of the running window of the drifting layer [s], > 0 (default 10).
  // The gas must leave each of the layer's points in `percentile` % of the
  // window's frames: a 4 s window read the still sky preset's plume -31 %
  // (its core holds gas most of 4 s), the whole 10 s run -5 %.
  double window_s = 10.0;
  // Alternations between the static and the drifting layer (each: the
  // drifting layer given the static one, then the static one given it; a
  // last drifting layer after them), 1-20 (default 3).
  int iterations = 3;
  // Worker threads, >= 0 (default 0: all hardware threads).
  int num_threads = 0;

  // Throws std::invalid_argument naming the first bad field.
  void Check() const;
};

class DriftingBackground {
 public:
  // `frames`: same-size single-channel float images of one channel at
  // `times_s` [s] (increasing); (vx, vy) the drift [px/s]; `sign` > 0 where
  // the gas raises the radiance, < 0 where it lowers it. Throws
  // std::invalid_argument on bad input.
  DriftingBackground(const std::vector<cv::Mat>& frames, const std::vector<double>& times_s,
                     double vx_px_s, double vy_px_s, double sign,
                     const DriftingBackgroundOptions& options);

  // The background at `time_s` (within the frames' times or beyond, where the
  // nearest knot holds), CV_32F of the frames' size.
  void At(double time_s, cv::Mat* out) const;

  // The static layer S, CV_32F.
  const cv::Mat& static_layer() const { return static_; }
  // The number of knots of the drifting layer.
  int knots() const { return static_cast<int>(knot_t_.size()); }

 private:
  struct Layer {
    cv::Mat values;  // CV_32F, NaN where no frame saw the point
    int x0 = 0, y0 = 0;  // drifting-frame coordinates of values(0, 0)
  };
  // M_k at drifting-frame point (x, y) (bilinear over the corners seen);
  // NaN outside or unseen.
  float LayerAt(int k, double x, double y) const;
  // The drifting layer at time t at pixel (x, y) (knots interpolated; the
  // one that saw the point where the other did not); NaN where none did.
  float DriftingAt(double t, int x, int y) const;
  int NearestKnot(double t) const;
  void EstimateLayers(const std::vector<cv::Mat>& frames);
  void EstimateStatic(const std::vector<cv::Mat>& frames);

  DriftingBackgroundOptions options_;
  std::vector<double> times_;
  double vx_ = 0.0, vy_ = 0.0;
  double q_ = 5.0;  // the percentile taken, sign applied [%]
  int width_ = 0, height_ = 0;
  cv::Mat static_;
  std::vector<double> knot_t_;
  double half_window_s_ = 0.0;
  std::vector<Layer> layers_;
  std::vector<float> fallback_;  // per knot: its median, where a point is unseen
};

}  // namespace qogi
