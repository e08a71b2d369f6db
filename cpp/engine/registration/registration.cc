// Robust inverse-compositional Gauss-Newton registration (see registration.h).
//
// Written rather than taken from cv::findTransformECC: ECC has a mask but no
// robust weights (the plume's own motion pulls its estimate) and no
// covariance, and the caller needs each parameter's precision to know whether
// the scene can fix it at all (a sky graded only vertically fixes no dx).
#include "engine/registration/registration.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "engine/util/check.h"
#include "engine/util/interpolation.h"

namespace qogi {
namespace {

// 3x3 homogeneous matrix of W(.; p) about the centre (cx, cy).
cv::Matx33d WarpMatrix(const RigidShift& p, double cx, double cy) {
  const double c = std::cos(p.angle_rad), s = std::sin(p.angle_rad);
  return cv::Matx33d(c, -s, cx - c * cx + s * cy + p.dx_px,  //
                     s, c, cy - s * cx - c * cy + p.dy_px,  //
                     0, 0, 1);
}

RigidShift FromMatrix(const cv::Matx33d& m, double cx, double cy) {
  RigidShift p;
  p.angle_rad = std::atan2(m(1, 0), m(0, 0));
  // W(c) = c + d.
  p.dx_px = m(0, 0) * cx + m(0, 1) * cy + m(0, 2) - cx;
  p.dy_px = m(1, 0) * cx + m(1, 1) * cy + m(1, 2) - cy;
  return p;
}

void CheckImage(const cv::Mat& a, const char* name) {
  Require(!a.empty() && a.channels() == 1 && (a.depth() == CV_32F || a.depth() == CV_64F),
          std::string(name) + " must be a non-empty single-channel float image");
}

cv::Mat AsFloat(const cv::Mat& a) {
  if (a.depth() == CV_32F) return a;
  cv::Mat f;
  a.convertTo(f, CV_32F);
  return f;
}

// `a` as CV_32F, smoothed by a Gaussian of `sigma` px (none for 0).
cv::Mat Smoothed(const cv::Mat& a, double sigma) {
  cv::Mat f = AsFloat(a);
  if (sigma <= 0) return f.clone();
  cv::Mat out;
  cv::GaussianBlur(f, out, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
  return out;
}

// Bicubic resampling out(x, y) = src(map(x, y)), the border replicated.
// Written rather than cv::warpAffine / cv::remap: those quantise sub-pixel
// positions to 1/32 px (INTER_BITS), which is the size of the jitter's
// residual this module must resolve (a registration stalls on that grid).
template <typename Map>
void ResampleCubic(const cv::Mat& src, Map map, cv::Mat* out) {
  const cv::Mat f = AsFloat(src);
  cv::Mat dst(f.size(), CV_32F);
  const int w = f.cols, h = f.rows;
  for (int y = 0; y < h; ++y) {
    float* o = dst.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      double sx, sy;
      map(x, y, &sx, &sy);
      const double fx = std::floor(sx), fy = std::floor(sy);
      double wx[4], wy[4];
      CubicWeights(sx - fx, wx);
      CubicWeights(sy - fy, wy);
      const int x0 = static_cast<int>(fx) - 1, y0 = static_cast<int>(fy) - 1;
      if (x0 >= 0 && y0 >= 0 && x0 + 3 < w && y0 + 3 < h) {  // inside: no clamping
        double acc = 0.0;
        for (int j = 0; j < 4; ++j) {
          const float* p = f.ptr<float>(y0 + j) + x0;
          acc += wy[j] * (wx[0] * p[0] + wx[1] * p[1] + wx[2] * p[2] + wx[3] * p[3]);
        }
        o[x] = static_cast<float>(acc);
        continue;
      }
      int cols[4];
      for (int i = 0; i < 4; ++i) cols[i] = std::min(std::max(x0 + i, 0), w - 1);
      double acc = 0.0;
      for (int j = 0; j < 4; ++j) {
        const float* row = f.ptr<float>(std::min(std::max(y0 + j, 0), h - 1));
        acc += wy[j] * (wx[0] * row[cols[0]] + wx[1] * row[cols[1]] + wx[2] * row[cols[2]] +
                        wx[3] * row[cols[3]]);
      }
      o[x] = static_cast<float>(acc);
    }
  }
  *out = dst;
}

// Median of the values (destroys their order).
double Median(std::vector<float>* v) {
  if (v->empty()) return 0.0;
  const auto mid = v->begin() + static_cast<std::ptrdiff_t>(v->size() / 2);
  std::nth_element(v->begin(), mid, v->end());
  return *mid;
}

}  // namespace

void RegistrationOptions::Check() const {
  CheckInRange(max_iterations, 1, 200, "max_iterations");
  CheckPositive(tolerance_px, "tolerance_px", "px");
  CheckPositive(robust_scale, "robust_scale");
  CheckInRange(border_px, 0, 1000, "border_px", "px");
  CheckPositive(max_shift_px, "max_shift_px", "px");
  CheckInRange(smoothing_px, 0.0, 20.0, "smoothing_px", "px");
}

FrameRegistration::FrameRegistration(const cv::Mat& reference, const cv::Mat& mask,
                                     const RegistrationOptions& options)
    : options_(options) {
  options_.Check();
  CheckImage(reference, "reference");
  const int b = options_.border_px;
  Require(reference.rows > 2 * b + 2 && reference.cols > 2 * b + 2,
          "the reference (" + std::to_string(reference.cols) + "x" +
              std::to_string(reference.rows) + " px) must be larger than twice border_px (" +
              std::to_string(b) + ") + 2");
  ref_ = Smoothed(reference, options_.smoothing_px);
  use_ = cv::Mat::zeros(ref_.size(), CV_8U);
  use_(cv::Rect(b, b, ref_.cols - 2 * b, ref_.rows - 2 * b)).setTo(1);
  if (!mask.empty()) {
    Require(mask.type() == CV_8U && mask.size() == ref_.size(),
            "mask must be 8-bit with the reference's size");
    use_.setTo(0, mask == 0);
  }
  cv::Mat finite = (ref_ == ref_);  // NaN pixels are not used
  use_.setTo(0, finite == 0);
  Require(cv::countNonZero(use_) >= 64, "the mask leaves fewer than 64 pixels to register on");
  cv::Mat gx, gy;
  // Central differences, (f(x+1) - f(x-1)) / 2.
  cv::Sobel(ref_, gx, CV_32F, 1, 0, 1, 0.5, 0, cv::BORDER_REPLICATE);
  cv::Sobel(ref_, gy, CV_32F, 0, 1, 1, 0.5, 0, cv::BORDER_REPLICATE);
  const double cx = 0.5 * (ref_.cols - 1), cy = 0.5 * (ref_.rows - 1);
  radius_px_ = std::max(1.0, std::hypot(cx, cy));
  jac_[0] = gx;
  jac_[1] = gy;
  jac_[2].create(ref_.size(), CV_32F);
  for (int y = 0; y < ref_.rows; ++y) {
    const float* px = gx.ptr<float>(y);
    const float* py = gy.ptr<float>(y);
    float* pa = jac_[2].ptr<float>(y);
    for (int x = 0; x < ref_.cols; ++x)
      // d/d(angle * radius) of the reference at W(x; angle): (-(y - cy), x - cx) / radius.
      pa[x] = static_cast<float>((-(y - cy) * px[x] + (x - cx) * py[x]) / radius_px_);
  }
}

RigidShift FrameRegistration::Precision(double noise_sigma) const {
  CheckNonNegative(noise_sigma, "noise_sigma");
  const int np = options_.rotation ? 3 : 2;
  cv::Matx33d h = cv::Matx33d::zeros();
  for (int y = 0; y < ref_.rows; ++y) {
    const std::uint8_t* u = use_.ptr<std::uint8_t>(y);
    for (int x = 0; x < ref_.cols; ++x) {
      if (!u[x]) continue;
      const double j[3] = {jac_[0].at<float>(y, x), jac_[1].at<float>(y, x),
                           jac_[2].at<float>(y, x)};
      for (int a = 0; a < np; ++a)
        for (int c = 0; c < np; ++c) h(a, c) += j[a] * j[c];
    }
  }
  const double inf = std::numeric_limits<double>::infinity();
  if (!(h(0, 0) + h(1, 1) + h(2, 2) > 0)) return {inf, inf, np == 3 ? inf : 0.0};  // uniform
  if (np == 2) h(2, 2) = 1;
  // A small ridge: a direction the texture does not fix gets a huge sigma, not NaN.
  const double ridge = 1e-12 * (h(0, 0) + h(1, 1) + h(2, 2));
  for (int k = 0; k < 3; ++k) h(k, k) += ridge;
  const cv::Matx33d cov = h.inv(cv::DECOMP_LU);
  RigidShift s;
  s.dx_px = noise_sigma * std::sqrt(std::max(0.0, cov(0, 0)));
  s.dy_px = noise_sigma * std::sqrt(std::max(0.0, cov(1, 1)));
  s.angle_rad = np == 3 ? noise_sigma * std::sqrt(std::max(0.0, cov(2, 2))) / radius_px_ : 0.0;
  return s;
}

RegistrationResult FrameRegistration::Register(const cv::Mat& frame,
                                               const RigidShift& start) const {
  CheckImage(frame, "frame");
  Require(frame.size() == ref_.size(), "the frame must have the reference's size (" +
                                           std::to_string(ref_.cols) + "x" +
                                           std::to_string(ref_.rows) + " px)");
  const cv::Mat f = Smoothed(frame, options_.smoothing_px);
  const int np = options_.rotation ? 3 : 2;
  const double cx = 0.5 * (ref_.cols - 1), cy = 0.5 * (ref_.rows - 1);
  cv::Matx33d w = WarpMatrix(start, cx, cy);
  RegistrationResult r;
  cv::Mat warped;
  std::vector<float> res;
  res.reserve(static_cast<std::size_t>(ref_.total()));
  cv::Matx33d h_last = cv::Matx33d::eye();
  double sigma = 0.0;
  for (int it = 0; it < options_.max_iterations; ++it) {
    WarpToReference(f, FromMatrix(w, cx, cy), &warped);
    // The residual's robust spread (1.4826 MAD about its median), from every
    // other pixel of every other row (plenty for a spread, a quarter the sort).
    res.clear();
    for (int y = 0; y < ref_.rows; y += 2) {
      const std::uint8_t* u = use_.ptr<std::uint8_t>(y);
      const float* a = warped.ptr<float>(y);
      const float* t = ref_.ptr<float>(y);
      for (int x = y % 4 / 2; x < ref_.cols; x += 2)
        if (u[x] && std::isfinite(a[x])) res.push_back(a[x] - t[x]);
    }
    Require(res.size() >= 8, "fewer than 8 finite pixels to register on");
    const double med = Median(&res);
    for (float& e : res) e = static_cast<float>(std::abs(e - med));
    sigma = 1.4826 * Median(&res);
    if (!(sigma > 0)) sigma = std::numeric_limits<float>::min();
    const double cut = options_.robust_scale * sigma;
    cv::Matx33d h = cv::Matx33d::zeros();
    cv::Vec3d g(0, 0, 0);
    std::size_t used = 0, inliers = 0;
    for (int y = 0; y < ref_.rows; ++y) {
      const std::uint8_t* u = use_.ptr<std::uint8_t>(y);
      const float* a = warped.ptr<float>(y);
      const float* t = ref_.ptr<float>(y);
      const float* j0 = jac_[0].ptr<float>(y);
      const float* j1 = jac_[1].ptr<float>(y);
      const float* j2 = jac_[2].ptr<float>(y);
      for (int x = 0; x < ref_.cols; ++x) {
        if (!u[x] || !std::isfinite(a[x])) continue;
        ++used;
        const double e = a[x] - t[x];
        const double q = e / cut;
        if (std::abs(q) >= 1) continue;
        ++inliers;
        const double wt = (1 - q * q) * (1 - q * q);  // Tukey's biweight
        const double j[3] = {j0[x], j1[x], np == 3 ? j2[x] : 0.0};
        for (int k = 0; k < 3; ++k) {
          g[k] += wt * j[k] * e;
          for (int c = k; c < 3; ++c) h(k, c) += wt * j[k] * j[c];
        }
      }
    }
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < k; ++c) h(k, c) = h(c, k);
    r.inlier_fraction = used ? static_cast<double>(inliers) / used : 0.0;
    if (np == 2) h(2, 2) = 1;  // rotation held at its start
    // A small ridge keeps a direction the texture does not fix at its start.
    const double ridge = 1e-9 * (h(0, 0) + h(1, 1) + h(2, 2)) + 1e-300;
    for (int k = 0; k < 3; ++k) h(k, k) += ridge;
    h_last = h;
    const cv::Vec3d dp = h.solve(g, cv::DECOMP_LU);
    RigidShift d;
    d.dx_px = dp[0];
    d.dy_px = dp[1];
    d.angle_rad = np == 3 ? dp[2] / radius_px_ : 0.0;
    // Inverse compositional update: W(p) <- W(p) o W(dp)^-1.
    w = w * WarpMatrix(d, cx, cy).inv();
    r.iterations = it + 1;
    const double step = std::abs(dp[0]) + std::abs(dp[1]) + std::abs(np == 3 ? dp[2] : 0.0);
    const RigidShift now = FromMatrix(w, cx, cy);
    if (!(std::hypot(now.dx_px, now.dy_px) + std::abs(now.angle_rad) * radius_px_ <=
          options_.max_shift_px))
      break;
    if (step < options_.tolerance_px) {
      r.converged = true;
      break;
    }
  }
  r.shift = FromMatrix(w, cx, cy);
  r.residual_sigma = sigma;
  const cv::Matx33d cov = h_last.inv(cv::DECOMP_LU);
  r.sigma.dx_px = sigma * std::sqrt(std::max(0.0, cov(0, 0)));
  r.sigma.dy_px = sigma * std::sqrt(std::max(0.0, cov(1, 1)));
  r.sigma.angle_rad = np == 3 ? sigma * std::sqrt(std::max(0.0, cov(2, 2))) / radius_px_ : 0.0;
  return r;
}

void WarpToReference(const cv::Mat& frame, const RigidShift& shift, cv::Mat* out) {
  CheckImage(frame, "frame");
  Require(out != nullptr && out->data != frame.data, "out must be a different image");
  const double cx = 0.5 * (frame.cols - 1), cy = 0.5 * (frame.rows - 1);
  const cv::Matx33d m = WarpMatrix(shift, cx, cy);
  // out(x) = frame(M x): M maps the output's pixels into the frame.
  ResampleCubic(
      frame,
      [&m](int x, int y, double* sx, double* sy) {
        *sx = m(0, 0) * x + m(0, 1) * y + m(0, 2);
        *sy = m(1, 0) * x + m(1, 1) * y + m(1, 2);
      },
      out);
}

void WarpAlongFlow(const cv::Mat& frame, const cv::Mat& u, const cv::Mat& v, double scale,
                   cv::Mat* out) {
  CheckImage(frame, "frame");
  CheckFinite(scale, "scale");
  Require(u.type() == CV_32F && v.type() == CV_32F && u.size() == frame.size() &&
              v.size() == frame.size(),
          "u and v must be float32 with the frame's size");
  Require(out != nullptr && out->data != frame.data, "out must be a different image");
  ResampleCubic(
      frame,
      [&u, &v, scale](int x, int y, double* sx, double* sy) {
        const float du = u.at<float>(y, x), dv = v.at<float>(y, x);
        *sx = x + scale * (std::isfinite(du) ? du : 0.f);
        *sy = y + scale * (std::isfinite(dv) ? dv : 0.f);
      },
      out);
}

}  // namespace qogi
