#include "engine/velocimetry/piv.h"

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "engine/util/check.h"
#include "engine/velocimetry/image_ops.h"
#include "engine/velocimetry/postprocess.h"

namespace qogi {

using namespace flow_ops;

void PivOptions::Check() const {
  CheckInRange(window_size, 8, 256, "PivOptions.window_size", "px");
  Require(window_size % 2 == 0,
          "PivOptions.window_size must be even; got " + std::to_string(window_size));
  CheckInRange(initial_window_size, 8, 512, "PivOptions.initial_window_size", "px");
  Require(initial_window_size % 2 == 0, "PivOptions.initial_window_size must be even; got " +
                                            std::to_string(initial_window_size));
  Require(initial_window_size >= window_size,
          "PivOptions.initial_window_size must be >= window_size (" + std::to_string(window_size) +
              "); got " + std::to_string(initial_window_size));
  CheckInRange(overlap, 0, 0.9, "PivOptions.overlap");
  CheckInRange(final_passes, 1, 20, "PivOptions.final_passes");
  CheckPositive(median_threshold, "PivOptions.median_threshold");
  CheckPositive(median_epsilon, "PivOptions.median_epsilon", "px");
  CheckInRange(min_correlation, 0, 1, "PivOptions.min_correlation");
  CheckInRange(min_mask_fraction, 0, 1, "PivOptions.min_mask_fraction");
}

PivFlow::PivFlow(const PivOptions& options) : options_(options) { options_.Check(); }

namespace {

// Bilinear sample of a CV_32F map at (x, y), clamped to the map.
inline float Sample(const cv::Mat& m, float x, float y) {
  x = std::min(std::max(x, 0.f), static_cast<float>(m.cols - 1));
  y = std::min(std::max(y, 0.f), static_cast<float>(m.rows - 1));
  const int ix = std::min(static_cast<int>(x), std::max(m.cols - 2, 0));
  const int iy = std::min(static_cast<int>(y), std::max(m.rows - 2, 0));
  const int ix1 = std::min(ix + 1, m.cols - 1), iy1 = std::min(iy + 1, m.rows - 1);
  const float tx = x - ix, ty = y - iy;
  const float* r0 = m.ptr<float>(iy);
  const float* r1 = m.ptr<float>(iy1);
  return (1 - ty) * ((1 - tx) * r0[ix] + tx * r0[ix1]) + ty * ((1 - tx) * r1[ix] + tx * r1[ix1]);
}

// Sub-pixel offset of a peak from three samples (left, centre, right):
// three-point Gaussian fit, parabolic where a sample is not positive.
inline float PeakOffset(float l, float c, float r) {
  if (l > 0 && c > 0 && r > 0) {
    const float ll = std::log(l), lc = std::log(c), lr = std::log(r);
    const float den = 2.f * (ll - 2.f * lc + lr);
    if (den < 0.f) return std::max(-0.5f, std::min(0.5f, (ll - lr) / den));
  }
  const float den = 2.f * (l - 2.f * c + r);
  if (den < 0.f) return std::max(-0.5f, std::min(0.5f, (l - r) / den));
  return 0.f;
}

}  // namespace

void PivFlow::ToDense(const Grid& g, cv::Mat& u, cv::Mat& v) const {
  const cv::Size size = i0n_.size();
  u.create(size, CV_32FC1);
  v.create(size, CV_32FC1);
  const float inv = 1.f / g.step;
  ParallelRows(size.height, size.width, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float gy = static_cast<float>((y - g.y0) * inv);
      float* pu = u.ptr<float>(y);
      float* pv = v.ptr<float>(y);
      for (int x = 0; x < size.width; ++x) {
        const float gx = static_cast<float>((x - g.x0) * inv);
        pu[x] = Sample(g.u, gx, gy);
        pv[x] = Sample(g.v, gx, gy);
      }
    }
  });
}

void PivFlow::Pass(int n, bool deform, const cv::Mat& mask) {
  const PivOptions& o = options_;
  const int W = i0n_.cols, H = i0n_.rows;
  Grid& g = grid_;
  g.n = n;
  g.step = std::max(1, static_cast<int>(std::lround(n * (1.0 - o.overlap))));
  g.nx = (W - n) / g.step + 1;
  g.ny = (H - n) / g.step + 1;
  const int left0 = (W - ((g.nx - 1) * g.step + n)) / 2;
  const int top0 = (H - ((g.ny - 1) * g.step + n)) / 2;
  g.x0 = left0 + 0.5 * (n - 1);
  g.y0 = top0 + 0.5 * (n - 1);
  g.u.create(g.ny, g.nx, CV_32FC1);
  g.v.create(g.ny, g.nx, CV_32FC1);
  g.corr.create(g.ny, g.nx, CV_32FC1);
  g.ok.create(g.ny, g.nx, CV_8UC1);

  if (deform) {
    // Central-difference deformation: frame 1 at x - w/2, frame 2 at x + w/2.
    hu_ = pu_ * 0.5;
    hv_ = pv_ * 0.5;
    Warp(i1n_, hu_, hv_, d1_);
    hu_ = -hu_;
    hv_ = -hv_;
    Warp(i0n_, hu_, hv_, d0_);
  }
  const cv::Mat& f0 = deform ? d0_ : i0n_;
  const cv::Mat& f1 = deform ? d1_ : i1n_;
  const bool has_mask = !mask.empty();
  const double min_mask = o.min_mask_fraction * n * n;

  cv::parallel_for_(cv::Range(0, g.ny), [&](const cv::Range& rows) {
    cv::Mat a(n, n, CV_32FC1), b(n, n, CV_32FC1), fa, fb, spec, corr;
    for (int j = rows.start; j < rows.end; ++j) {
      for (int i = 0; i < g.nx; ++i) {
        const int left = left0 + i * g.step, top = top0 + j * g.step;
        const float cx = static_cast<float>(g.x0 + i * g.step);
        const float cy = static_cast<float>(g.y0 + j * g.step);
        // Predictor at the window centre; without deformation the windows
        // are offset by its integer part, split between the frames.
        const float pu = Sample(pu_, cx, cy), pv = Sample(pv_, cx, cy);
        int sx0 = 0, sy0 = 0, sx1 = 0, sy1 = 0;
        if (!deform) {
          const int ix = static_cast<int>(std::lround(pu));
          const int iy = static_cast<int>(std::lround(pv));
          sx0 = -(ix / 2);
          sy0 = -(iy / 2);
          sx1 = ix + sx0;
          sy1 = iy + sy0;
          // Keep both windows inside the frame.
          sx0 = std::max(-left, std::min(W - n - left, sx0));
          sy0 = std::max(-top, std::min(H - n - top, sy0));
          sx1 = std::max(-left, std::min(W - n - left, sx1));
          sy1 = std::max(-top, std::min(H - n - top, sy1));
        }
        const float base_u = deform ? pu : static_cast<float>(sx1 - sx0);
        const float base_v = deform ? pv : static_cast<float>(sy1 - sy0);
        g.u.at<float>(j, i) = base_u;
        g.v.at<float>(j, i) = base_v;
        g.corr.at<float>(j, i) = 0.f;
        g.ok.at<uchar>(j, i) = 0;
        if (has_mask && cv::sum(mask(cv::Rect(left, top, n, n)))[0] < min_mask) continue;
        f0(cv::Rect(left + sx0, top + sy0, n, n)).copyTo(a);
        f1(cv::Rect(left + sx1, top + sy1, n, n)).copyTo(b);
        const double ma = cv::mean(a)[0], mb = cv::mean(b)[0];
        a -= ma;
        b -= mb;
        const double ea = a.dot(a), eb = b.dot(b);
        if (!(ea > 0) || !(eb > 0)) continue;
        cv::dft(a, fa);
        cv::dft(b, fb);
        cv::mulSpectrums(fb, fa, spec, 0, /*conjB=*/true);
        cv::dft(spec, corr, cv::DFT_INVERSE | cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
        // corr(s) = sum_x a(x) b(x + s), circular; s wraps at n/2.
        cv::Point peak;
        double peak_value;
        cv::minMaxLoc(corr, nullptr, &peak_value, nullptr, &peak);
        const float norm = static_cast<float>(1.0 / std::sqrt(ea * eb));
        auto at = [&](int x, int y) { return corr.at<float>((y + n) % n, (x + n) % n) * norm; };
        const float c0 = at(peak.x, peak.y);
        const float dx = PeakOffset(at(peak.x - 1, peak.y), c0, at(peak.x + 1, peak.y));
        const float dy = PeakOffset(at(peak.x, peak.y - 1), c0, at(peak.x, peak.y + 1));
        const int px = peak.x < n / 2 ? peak.x : peak.x - n;
        const int py = peak.y < n / 2 ? peak.y : peak.y - n;
        g.u.at<float>(j, i) = base_u + px + dx;
        g.v.at<float>(j, i) = base_v + py + dy;
        g.corr.at<float>(j, i) = std::max(0.f, std::min(1.f, c0));
        g.ok.at<uchar>(j, i) = c0 >= o.min_correlation ? 1 : 0;
      }
    }
  });

  // Validation and replacement between passes.
  MedianTestOptions mt;
  mt.threshold = o.median_threshold;
  mt.epsilon = o.median_epsilon;
  const cv::Mat outliers = NormalisedMedianTest(g.u, g.v, g.ok, mt);
  g.ok.setTo(0, outliers);
  cv::Mat ru, rv, filled;
  ReplaceVectors(g.u, g.v, g.ok, 0, ru, rv, filled);
  g.u = ru;
  g.v = rv;
}

void PivFlow::CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                          FlowField& flow) {
  const PivOptions& o = options_;
  const int W = prev.cols, H = prev.rows;
  Require(o.window_size <= std::min(W, H), "PivOptions.window_size (" +
                                               std::to_string(o.window_size) +
                                               " px) must not exceed the frame's smaller side (" +
                                               std::to_string(std::min(W, H)) + " px)");
  if (!NormalisePair(prev, next, mask, i0n_, i1n_, flow)) return;
  StartFlow(flow, warm, prev.size(), pu_, pv_);
  // Window sizes: halving from the initial size (those that fit the frame)
  // down to the final size, then the extra final passes.
  std::vector<int> sizes;
  for (int n = o.initial_window_size; n > o.window_size; n /= 2)
    if (n <= std::min(W, H)) sizes.push_back(n);
  for (int k = 0; k < o.final_passes; ++k) sizes.push_back(o.window_size);
  cv::Mat mask01;
  if (!mask.empty()) mask01 = mask != 0;
  if (!mask01.empty()) mask01 /= 255;
  for (std::size_t p = 0; p < sizes.size(); ++p) {
    Pass(sizes[p], o.deform && (p > 0 || warm), mask01);
    ToDense(grid_, pu_, pv_);
  }
  // Midpoint displacement -> forward map at the pixels of prev:
  // w(x) = w_mid(x + w(x) / 2), by fixed-point iteration.
  pu_.copyTo(flow.u);
  pv_.copyTo(flow.v);
  for (int it = 0; it < 3; ++it) {
    ParallelRows(H, W, [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y) {
        float* fu = flow.u.ptr<float>(y);
        float* fv = flow.v.ptr<float>(y);
        for (int x = 0; x < W; ++x) {
          const float mx = x + 0.5f * fu[x], my = y + 0.5f * fv[x];
          fu[x] = Sample(pu_, mx, my);
          fv[x] = Sample(pv_, mx, my);
        }
      }
    });
  }
  // Quality (correlation) and validity from the final grid: a pixel is valid
  // when it lies within the grid of window centres and its nearest vector was
  // measured (not replaced).
  const Grid& g = grid_;
  const float inv = 1.f / g.step;
  flow.valid.setTo(0);
  for (int y = 0; y < H; ++y) {
    const float gy = static_cast<float>((y - g.y0) * inv);
    uchar* pv = flow.valid.ptr<uchar>(y);
    for (int x = 0; x < W; ++x) {
      const float gx = static_cast<float>((x - g.x0) * inv);
      if (gx < -1e-3f || gy < -1e-3f || gx > g.nx - 1 + 1e-3f || gy > g.ny - 1 + 1e-3f) continue;
      const int ix = std::min(g.nx - 1, std::max(0, static_cast<int>(std::lround(gx))));
      const int iy = std::min(g.ny - 1, std::max(0, static_cast<int>(std::lround(gy))));
      pv[x] = g.ok.at<uchar>(iy, ix) ? 1 : 0;
    }
  }
  ApplyMask(mask, flow.u, flow.v, flow.valid);
  FinishWithBrightnessResidual(i0n_, i1n_, flow);  // residual_ratio, inside
  for (int y = 0; y < H; ++y) {
    const float gy = static_cast<float>((y - g.y0) * inv);
    float* pq = flow.quality.ptr<float>(y);
    for (int x = 0; x < W; ++x) pq[x] = Sample(g.corr, static_cast<float>((x - g.x0) * inv), gy);
  }
}

}  // namespace qogi
