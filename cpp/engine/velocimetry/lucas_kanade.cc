#include "engine/velocimetry/lucas_kanade.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "engine/util/check.h"
#include "engine/velocimetry/image_ops.h"

namespace qogi {

using namespace flow_ops;

void LucasKanadeOptions::Check() const {
  CheckInRange(window_sigma, 0.5, 50, "LucasKanadeOptions.window_sigma", "px");
  CheckInRange(levels, 1, 12, "LucasKanadeOptions.levels");
  CheckInRange(min_level_size, 4, 4096, "LucasKanadeOptions.min_level_size", "px");
  CheckInRange(finest_level, 0, 10, "LucasKanadeOptions.finest_level");
  CheckInRange(iterations, 1, 50, "LucasKanadeOptions.iterations");
  CheckPositive(min_eigenvalue, "LucasKanadeOptions.min_eigenvalue");
}

LucasKanadeFlow::LucasKanadeFlow(const LucasKanadeOptions& options) : options_(options) {
  options_.Check();
}

namespace {
constexpr float kMaxStep = 1.0f;  // px on the current level, per iteration

// Smaller eigenvalue of [a b; b c].
inline float MinEigen(float a, float b, float c) {
  const float h = 0.5f * (a + c);
  const float d = std::sqrt(0.25f * (a - c) * (a - c) + b * b);
  return h - d;
}
}  // namespace

void LucasKanadeFlow::CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask,
                                  bool warm, FlowField& flow) {
  const LucasKanadeOptions& o = options_;
  if (!NormalisePair(prev, next, mask, i0n_, i1n_, flow)) return;
  const int levels = NumLevels(prev.size(), o.levels, o.min_level_size);
  const int finest = std::min(o.finest_level, levels - 1);
  BuildPyramid(i0n_, levels, p0_);
  BuildPyramid(i1n_, levels, p1_);
  const int top = levels - 1;
  if (warm) {
    ResampleFlow(flow.u, flow.v, p0_[top].size(), 1.0 / (1 << top), u_, v_);
  } else {
    u_ = cv::Mat::zeros(p0_[top].size(), CV_32FC1);
    v_ = cv::Mat::zeros(p0_[top].size(), CV_32FC1);
  }
  // Tikhonov damping of each step at the validity threshold: along a
  // direction the window does not constrain (aperture problem, e.g. along a
  // smooth plume column) the step shrinks by lambda / (lambda + tau) instead
  // of growing to kMaxStep; with 0.1 tau such steps drifted and, fed back
  // by warm starts, grew without bound over a plume sequence.
  const float tikhonov = static_cast<float>(o.min_eigenvalue);
  // Start of every pixel (warm start or zero), kept where the window turns
  // out not to support a vector (below).
  StartFlow(flow, warm, prev.size(), start_u_, start_v_);
  const double sigma = o.window_sigma;
  for (int l = top; l >= finest; --l) {
    if (l < top) {
      ResampleFlow(u_, v_, p0_[l].size(), 2.0, un_, vn_);
      std::swap(u_, un_);
      std::swap(v_, vn_);
    }
    const cv::Mat& i0 = p0_[l];
    FivePointGradient(i0, gx_, gy_);
    cv::GaussianBlur(gx_.mul(gx_), sxx_, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
    cv::GaussianBlur(gx_.mul(gy_), sxy_, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
    cv::GaussianBlur(gy_.mul(gy_), syy_, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
    for (int it = 0; it < o.iterations; ++it) {
      Warp(p1_[l], u_, v_, warped_, &inside_);
      cv::Mat it_img = warped_ - i0;
      cv::GaussianBlur(gx_.mul(it_img), bx_, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
      cv::GaussianBlur(gy_.mul(it_img), by_, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
      ParallelRows(i0.rows, i0.cols, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
          const float* a = sxx_.ptr<float>(y);
          const float* b = sxy_.ptr<float>(y);
          const float* c = syy_.ptr<float>(y);
          const float* ex = bx_.ptr<float>(y);
          const float* ey = by_.ptr<float>(y);
          float* pu = u_.ptr<float>(y);
          float* pv = v_.ptr<float>(y);
          const uchar* in = inside_.ptr<uchar>(y);
          for (int x = 0; x < i0.cols; ++x) {
            // x + w beyond the frame: no data to move it (the gas has left);
            // Gauss-Newton steps there would follow the replicated border.
            if (!in[x]) continue;
            const float aa = a[x] + tikhonov, cc = c[x] + tikhonov;
            const float det = aa * cc - b[x] * b[x];
            if (!(det > 0.f)) continue;
            float du = -(cc * ex[x] - b[x] * ey[x]) / det;
            float dv = -(aa * ey[x] - b[x] * ex[x]) / det;
            // The pyramid leaves at most ~1 px per level to find: longer
            // Gauss-Newton steps come from a poor linearisation, not motion.
            const float len = std::sqrt(du * du + dv * dv);
            if (len > kMaxStep) {
              du *= kMaxStep / len;
              dv *= kMaxStep / len;
            }
            pu[x] += du;
            pv[x] += dv;
          }
        }
      });
    }
  }
  if (finest > 0) {
    ResampleFlow(u_, v_, prev.size(), static_cast<double>(1 << finest), flow.u, flow.v);
  } else {
    u_.copyTo(flow.u);
    v_.copyTo(flow.v);
  }
  // Validity and quality from the structure tensor of the finest level solved.
  cv::Mat lam(p0_[finest].size(), CV_32FC1);
  for (int y = 0; y < lam.rows; ++y) {
    const float* a = sxx_.ptr<float>(y);
    const float* b = sxy_.ptr<float>(y);
    const float* c = syy_.ptr<float>(y);
    float* pl = lam.ptr<float>(y);
    for (int x = 0; x < lam.cols; ++x) pl[x] = MinEigen(a[x], b[x], c[x]);
  }
  if (finest > 0) cv::resize(lam, lam, prev.size(), 0, 0, cv::INTER_LINEAR);
  const float tau = static_cast<float>(o.min_eigenvalue);
  flow.valid.setTo(1);
  ApplyMask(mask, flow.u, flow.v, flow.valid);
  FinishWithBrightnessResidual(i0n_, i1n_, flow);  // residual_ratio, inside
  for (int y = 0; y < lam.rows; ++y) {
    const float* pl = lam.ptr<float>(y);
    float* pq = flow.quality.ptr<float>(y);
    uchar* pv = flow.valid.ptr<uchar>(y);
    for (int x = 0; x < lam.cols; ++x) {
      const float l = std::max(pl[x], 0.f);
      pq[x] = l / (l + tau);
      if (l < tau) {
        // Unsupported (aperture problem): keep the start. Gauss-Newton steps
        // along a direction the window does not constrain follow noise; fed
        // back by warm starts over a sequence they grew without bound on
        // smooth plume columns (hundreds of px/frame).
        pv[x] = 0;
        flow.u.at<float>(y, x) = start_u_.at<float>(y, x);
        flow.v.at<float>(y, x) = start_v_.at<float>(y, x);
      }
    }
  }
}

}  // namespace qogi
