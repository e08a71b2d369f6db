// Drifting backgrounds: the drift's velocity and the two-layer background
// (see drifting.h).
//
// Written rather than taken from OpenCV's background subtractors (MOG2, KNN):
// those model each pixel in the camera's frame, so a cloud drifting through a
// pixel becomes foreground exactly as the gas does; here the drifting part is
// followed in its own frame, measured apart from the gas.
#include "engine/background/drifting.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "engine/registration/registration.h"
#include "engine/util/check.h"
#include "engine/util/parallel.h"

namespace qogi {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// The q-th percentile [%] of v (reordered), interpolated linearly between
// order statistics (numpy's default); NaN for an empty v.
float Percentile(std::vector<float>& v, double q) {
  const std::size_t n = v.size();
  if (n == 0) return kNaN;
  const double pos = q / 100.0 * static_cast<double>(n - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(pos));
  std::nth_element(v.begin(), v.begin() + lo, v.end());
  const float a = v[lo];
  if (lo + 1 >= n) return a;
  const float b = *std::min_element(v.begin() + lo + 1, v.end());
  return static_cast<float>(a + (pos - static_cast<double>(lo)) * (b - a));
}

// Bilinear value of a CV_32F image at (x, y), inside [0, w-1] x [0, h-1].
inline float Bilinear(const cv::Mat& m, double x, double y) {
  const int x0 = std::min(static_cast<int>(x), m.cols - 2 < 0 ? 0 : m.cols - 2);
  const int y0 = std::min(static_cast<int>(y), m.rows - 2 < 0 ? 0 : m.rows - 2);
  const double fx = x - x0, fy = y - y0;
  const int x1 = std::min(x0 + 1, m.cols - 1), y1 = std::min(y0 + 1, m.rows - 1);
  const float* r0 = m.ptr<float>(y0);
  const float* r1 = m.ptr<float>(y1);
  return static_cast<float>((1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x1]) +
                            fy * ((1 - fx) * r1[x0] + fx * r1[x1]));
}

void CheckFrames(const std::vector<cv::Mat>& frames, const std::vector<double>& times_s,
                 std::size_t at_least) {
  CheckSameLength(frames.size(), times_s.size(), "frames", "times_s");
  Require(frames.size() >= at_least, "need at least " + std::to_string(at_least) + " frames; got " +
                                         std::to_string(frames.size()));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const cv::Mat& f = frames[i];
    Require(!f.empty() && f.channels() == 1 && (f.depth() == CV_32F || f.depth() == CV_64F),
            "frame " + std::to_string(i) + " must be a non-empty single-channel float image");
    Require(f.size() == frames[0].size(),
            "frame " + std::to_string(i) + " differs in size from frame 0");
    CheckFinite(times_s[i], "times_s");
    Require(i == 0 || times_s[i] > times_s[i - 1],
            "times_s must increase; got " + FormatNumber(times_s[i]) + " after " +
                FormatNumber(i ? times_s[i - 1] : 0.0) + " at " + std::to_string(i));
  }
}

std::vector<cv::Mat> AsFloat32(const std::vector<cv::Mat>& frames) {
  std::vector<cv::Mat> out(frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].depth() == CV_32F)
      out[i] = frames[i];
    else
      frames[i].convertTo(out[i], CV_32F);
  }
  return out;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + m, v.end());
  return v[m];
}

double Spread(const std::vector<double>& v) {
  if (v.size() < 2) return 0.0;
  const double med = Median(v);
  std::vector<double> d(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) d[i] = std::abs(v[i] - med);
  return 1.4826 * Median(d);
}

}  // namespace

void DriftOptions::Check() const {
  Require(difference_lag >= 1,
          "DriftOptions.difference_lag must be >= 1; got " + std::to_string(difference_lag));
  Require(short_lag >= 1, "DriftOptions.short_lag must be >= 1; got " + std::to_string(short_lag));
  Require(long_lag >= short_lag, "DriftOptions.long_lag must be >= short_lag (" +
                                     std::to_string(short_lag) + "); got " +
                                     std::to_string(long_lag));
  Require(max_pairs >= 1, "DriftOptions.max_pairs must be >= 1; got " + std::to_string(max_pairs));
  CheckInRange(smoothing_px, 0.0, 20.0, "DriftOptions.smoothing_px", "px");
}

DriftResult MeasureDrift(const std::vector<cv::Mat>& frames_in, const std::vector<double>& times_s,
                         const DriftOptions& options) {
  options.Check();
  const int k = options.difference_lag;
  CheckFrames(frames_in, times_s, static_cast<std::size_t>(k + options.short_lag + 1));
  const std::vector<cv::Mat> frames = AsFloat32(frames_in);
  const int n = static_cast<int>(frames.size());
  const int n_diff = n - k;  // difference images E_0 .. E_{n_diff - 1}
  // E_i = F_{i+k} - F_i in units of its own robust spread (the registration's
  // tolerances are in pixels, its weights relative; the scaling keeps float
  // rounding far below the noise).
  auto difference = [&](int i) {
    cv::Mat e;
    cv::subtract(frames[i + k], frames[i], e, cv::noArray(), CV_32F);
    std::vector<float> v(e.begin<float>(), e.end<float>());
    const float med = Percentile(v, 50.0);
    for (float& x : v) x = std::abs(x - med);
    const float mad = Percentile(v, 50.0);
    if (mad > 0) e /= 1.4826 * mad;
    return e;
  };
  RegistrationOptions reg;
  reg.rotation = false;
  reg.smoothing_px = options.smoothing_px;
  DriftResult out;
  // Registers E_{i+lag} to E_i for up to max_pairs i spread over the run,
  // starting from velocity (vx, vy); the converged pairs' velocities.
  auto pairs = [&](int lag, double vx, double vy, std::vector<double>* ux, std::vector<double>* uy,
                   std::vector<double>* inliers) {
    const int last = n_diff - 1 - lag;  // largest i
    if (last < 0) return 0;
    const int count = std::min(options.max_pairs, last + 1);
    int made = 0;
    for (int p = 0; p < count; ++p) {
      const int i = count == 1 ? 0 : static_cast<int>(std::lround(double(p) * last / (count - 1)));
      const double dt = times_s[i + lag] - times_s[i];
      const double sx = vx * dt, sy = vy * dt;
      reg.max_shift_px = std::max(8.0, 2.0 * std::hypot(sx, sy) + 4.0);
      const FrameRegistration fr(difference(i), cv::Mat(), reg);
      const RegistrationResult r = fr.Register(difference(i + lag), RigidShift{sx, sy, 0.0});
      ++made;
      if (!r.converged) continue;
      ux->push_back(r.shift.dx_px / dt);
      uy->push_back(r.shift.dy_px / dt);
      inliers->push_back(r.inlier_fraction);
    }
    return made;
  };
  std::vector<double> ux, uy, inl;
  const int made_short = pairs(options.short_lag, 0.0, 0.0, &ux, &uy, &inl);
  out.pairs = made_short;
  out.converged = static_cast<int>(ux.size());
  if (made_short == 0 || 2 * out.converged < made_short) return out;  // not measured
  out.measured = true;
  out.vx_px_s = Median(ux);
  out.vy_px_s = Median(uy);
  out.spread_vx_px_s = Spread(ux);
  out.spread_vy_px_s = Spread(uy);
  out.inlier_fraction = Median(inl);
  const int long_lag = std::min(options.long_lag, n_diff - 1);
  if (long_lag > options.short_lag) {
    std::vector<double> lx, ly, linl;
    const int made_long = pairs(long_lag, out.vx_px_s, out.vy_px_s, &lx, &ly, &linl);
    if (made_long > 0 && 2 * static_cast<int>(lx.size()) >= made_long) {
      out.pairs = made_long;
      out.converged = static_cast<int>(lx.size());
      out.vx_px_s = Median(lx);
      out.vy_px_s = Median(ly);
      out.spread_vx_px_s = Spread(lx);
      out.spread_vy_px_s = Spread(ly);
      out.inlier_fraction = Median(linl);
    }
  }
  return out;
}

void DriftingBackgroundOptions::Check() const {
  Require(
      percentile > 0.0 && percentile < 50.0,
      "DriftingBackgroundOptions.percentile must be in (0, 50) %; got " + FormatNumber(percentile));
  CheckPositive(window_s, "DriftingBackgroundOptions.window_s", "s");
  Require(iterations >= 1 && iterations <= 20,
          "DriftingBackgroundOptions.iterations must be within 1-20; got " +
              std::to_string(iterations));
  Require(num_threads >= 0,
          "DriftingBackgroundOptions.num_threads must be >= 0; got " + std::to_string(num_threads));
}

DriftingBackground::DriftingBackground(const std::vector<cv::Mat>& frames_in,
                                       const std::vector<double>& times_s, double vx_px_s,
                                       double vy_px_s, double sign,
                                       const DriftingBackgroundOptions& options)
    : options_(options), times_(times_s), vx_(vx_px_s), vy_(vy_px_s) {
  options.Check();
  CheckFrames(frames_in, times_s, 1);
  CheckFinite(vx_px_s, "vx_px_s");
  CheckFinite(vy_px_s, "vy_px_s");
  Require(sign != 0.0 && std::isfinite(sign), "sign must be +1 or -1; got " + FormatNumber(sign));
  q_ = sign > 0 ? options.percentile : 100.0 - options.percentile;
  const std::vector<cv::Mat> frames = AsFloat32(frames_in);
  width_ = frames[0].cols;
  height_ = frames[0].rows;
  // Knots every half window; a run no longer than the window has one, in its
  // middle, that sees every frame.
  const double t0 = times_.front(), t1 = times_.back(), dur = t1 - t0;
  if (dur <= options.window_s) {
    knot_t_ = {0.5 * (t0 + t1)};
    half_window_s_ = 0.5 * dur;
  } else {
    const double step = 0.5 * options.window_s;
    const int nk = static_cast<int>(std::ceil(dur / step)) + 1;
    for (int j = 0; j < nk; ++j) knot_t_.push_back(t0 + j * step);
    half_window_s_ = 0.5 * options.window_s;
  }
  // The drifting layer first, from the frames as they are (S = 0): its
  // error is then the static layer's variation along each point's path, a
  // fraction of the clouds' contrast; starting from the static percentile
  // instead leaves the clouds that never clear a pixel in S, and the
  // alternation removes them only slowly.
  static_ = cv::Mat::zeros(height_, width_, CV_32F);
  for (int it = 0; it < options.iterations; ++it) {
    EstimateLayers(frames);
    EstimateStatic(frames);
  }
  EstimateLayers(frames);
}

float DriftingBackground::LayerAt(int k, double x, double y) const {
  const Layer& l = layers_[k];
  const double u = x - l.x0, v = y - l.y0;
  if (!(u >= 0 && v >= 0 && u <= l.values.cols - 1 && v <= l.values.rows - 1)) return kNaN;
  // Bilinear over the corners seen (weights renormalised): the image's
  // first row at time t lies between a drifting-frame row that the window's
  // frames saw and one that only later frames see.
  const int u0 = std::min(static_cast<int>(u), std::max(0, l.values.cols - 2));
  const int v0 = std::min(static_cast<int>(v), std::max(0, l.values.rows - 2));
  const int u1 = std::min(u0 + 1, l.values.cols - 1), v1 = std::min(v0 + 1, l.values.rows - 1);
  const double fu = u - u0, fv = v - v0;
  const float c[4] = {l.values.at<float>(v0, u0), l.values.at<float>(v0, u1),
                      l.values.at<float>(v1, u0), l.values.at<float>(v1, u1)};
  const double w[4] = {(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv};
  double sum = 0, weight = 0;
  for (int i = 0; i < 4; ++i) {
    if (std::isnan(c[i]) || w[i] <= 0) continue;
    sum += w[i] * c[i];
    weight += w[i];
  }
  return weight > 0 ? static_cast<float>(sum / weight) : kNaN;
}

float DriftingBackground::DriftingAt(double t, int x, int y) const {
  const int nk = knots();
  int j = 0;
  while (j + 1 < nk && knot_t_[j + 1] <= t) ++j;
  const double yx = x - vx_ * t, yy = y - vy_ * t;
  if (nk == 1 || j + 1 >= nk || t <= knot_t_[0]) return LayerAt(t <= knot_t_[0] ? 0 : j, yx, yy);
  const double w = (t - knot_t_[j]) / (knot_t_[j + 1] - knot_t_[j]);
  const float a = LayerAt(j, yx, yy), b = LayerAt(j + 1, yx, yy);
  if (std::isnan(a)) return b;  // NaN when neither knot saw the point
  if (std::isnan(b)) return a;
  return static_cast<float>((1 - w) * a + w * b);
}

void DriftingBackground::EstimateStatic(const std::vector<cv::Mat>& frames) {
  const int n = static_cast<int>(frames.size());
  cv::Mat s(height_, width_, CV_32F);
  ParallelFor(
      static_cast<std::size_t>(height_), 4,
      [&](std::size_t r0, std::size_t r1) {
        std::vector<float> v;
        v.reserve(n);
        for (int y = static_cast<int>(r0); y < static_cast<int>(r1); ++y) {
          float* out = s.ptr<float>(y);
          for (int x = 0; x < width_; ++x) {
            // Frames at which the drifting layer was not seen here are left out.
            v.clear();
            for (int i = 0; i < n; ++i) {
              const float m = DriftingAt(times_[i], x, y);
              if (!std::isnan(m)) v.push_back(frames[i].ptr<float>(y)[x] - m);
            }
            out[x] = v.empty() ? 0.f : Percentile(v, q_);
          }
        }
      },
      options_.num_threads);
  static_ = s;
}

void DriftingBackground::EstimateLayers(const std::vector<cv::Mat>& frames) {
  const int n = static_cast<int>(frames.size());
  // What the drifting layer carries: each frame less the static layer.
  std::vector<cv::Mat> rest(n);
  for (int i = 0; i < n; ++i) cv::subtract(frames[i], static_, rest[i], cv::noArray(), CV_32F);
  layers_.assign(knot_t_.size(), Layer{});
  fallback_.assign(knot_t_.size(), 0.f);
  for (std::size_t k = 0; k < knot_t_.size(); ++k) {
    std::vector<int> use;
    for (int i = 0; i < n; ++i)
      if (std::abs(times_[i] - knot_t_[k]) <= half_window_s_ + 1e-9) use.push_back(i);
    if (use.empty()) {  // no frame near this knot: the nearest frame's
      int best = 0;
      for (int i = 1; i < n; ++i)
        if (std::abs(times_[i] - knot_t_[k]) < std::abs(times_[best] - knot_t_[k])) best = i;
      use.push_back(best);
    }
    // The drifting-frame points y = x - v t that the window's frames see.
    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
    for (int i : use) {
      xmin = std::min(xmin, -vx_ * times_[i]);
      xmax = std::max(xmax, width_ - 1 - vx_ * times_[i]);
      ymin = std::min(ymin, -vy_ * times_[i]);
      ymax = std::max(ymax, height_ - 1 - vy_ * times_[i]);
    }
    Layer& l = layers_[k];
    l.x0 = static_cast<int>(std::floor(xmin));
    l.y0 = static_cast<int>(std::floor(ymin));
    const int w = static_cast<int>(std::ceil(xmax)) - l.x0 + 1;
    const int h = static_cast<int>(std::ceil(ymax)) - l.y0 + 1;
    l.values.create(h, w, CV_32F);
    ParallelFor(
        static_cast<std::size_t>(h), 4,
        [&](std::size_t r0, std::size_t r1) {
          std::vector<float> v;
          v.reserve(use.size());
          for (int r = static_cast<int>(r0); r < static_cast<int>(r1); ++r) {
            float* out = l.values.ptr<float>(r);
            for (int c = 0; c < w; ++c) {
              v.clear();
              for (int i : use) {
                const double px = l.x0 + c + vx_ * times_[i], py = l.y0 + r + vy_ * times_[i];
                if (px < 0 || py < 0 || px > width_ - 1 || py > height_ - 1) continue;
                v.push_back(Bilinear(rest[i], px, py));
              }
              out[c] = Percentile(v, q_);
            }
          }
        },
        options_.num_threads);
    std::vector<float> seen;
    for (auto it = l.values.begin<float>(); it != l.values.end<float>(); ++it)
      if (!std::isnan(*it)) seen.push_back(*it);
    fallback_[k] = seen.empty() ? 0.f : Percentile(seen, 50.0);
  }
}

int DriftingBackground::NearestKnot(double t) const {
  int best = 0;
  for (int k = 1; k < knots(); ++k)
    if (std::abs(knot_t_[k] - t) < std::abs(knot_t_[best] - t)) best = k;
  return best;
}

void DriftingBackground::At(double time_s, cv::Mat* out) const {
  CheckFinite(time_s, "time_s");
  out->create(height_, width_, CV_32F);
  ParallelFor(
      static_cast<std::size_t>(height_), 8,
      [&](std::size_t r0, std::size_t r1) {
        for (int y = static_cast<int>(r0); y < static_cast<int>(r1); ++y) {
          float* o = out->ptr<float>(y);
          const float* s = static_.ptr<float>(y);
          for (int x = 0; x < width_; ++x) {
            const float m = DriftingAt(time_s, x, y);
            // Unseen by every knot (a time beyond the frames given): the
            // nearest knot's median level.
            o[x] = s[x] + (std::isnan(m) ? fallback_[NearestKnot(time_s)] : m);
          }
        }
      },
      options_.num_threads);
}

}  // namespace qogi
