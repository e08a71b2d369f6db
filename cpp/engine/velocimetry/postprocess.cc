#include "engine/velocimetry/postprocess.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "engine/util/check.h"
#include "engine/util/parallel.h"
#include "engine/velocimetry/image_ops.h"

namespace qogi {

using flow_ops::ParallelRows;

namespace {

std::string SizeText(const cv::Mat& m) {
  return std::to_string(m.cols) + " x " + std::to_string(m.rows);
}

void CheckField(const cv::Mat& u, const cv::Mat& v, const cv::Mat& mask, const char* mask_name) {
  Require(u.type() == CV_32FC1 && v.type() == CV_32FC1,
          "u and v must be float32 single-channel maps (CV_32FC1)");
  Require(u.size() == v.size(),
          "u and v must have the same size; got " + SizeText(u) + " and " + SizeText(v));
  Require(!u.empty(), "u and v must not be empty");
  Require(mask.type() == CV_8UC1,
          std::string(mask_name) + " must be an 8-bit single-channel mask (CV_8UC1)");
  Require(mask.size() == u.size(), std::string(mask_name) + " must have the size of u, " +
                                       SizeText(u) + "; got " + SizeText(mask));
}

// Median of n values (mean of the two middle ones for even n); reorders.
float Median(float* a, int n) {
  std::sort(a, a + n);
  return (n % 2) ? a[n / 2] : 0.5f * (a[n / 2 - 1] + a[n / 2]);
}

}  // namespace

void MedianTestOptions::Check() const {
  CheckPositive(threshold, "MedianTestOptions.threshold");
  CheckPositive(epsilon, "MedianTestOptions.epsilon", "px/frame");
  CheckInRange(radius, 1, 10, "MedianTestOptions.radius", "vectors");
}

cv::Mat NormalisedMedianTest(const cv::Mat& u, const cv::Mat& v, const cv::Mat& valid,
                             const MedianTestOptions& options) {
  options.Check();
  CheckField(u, v, valid, "valid");
  const int W = u.cols, H = u.rows, r = options.radius;
  const float thr = static_cast<float>(options.threshold);
  const float eps = static_cast<float>(options.epsilon);
  cv::Mat outliers = cv::Mat::zeros(u.size(), CV_8UC1);
  ParallelRows(H, W, [&](int y0, int y1) {
    std::vector<float> nu((2 * r + 1) * (2 * r + 1)), nv(nu.size()), res(nu.size());
    for (int y = y0; y < y1; ++y) {
      for (int x = 0; x < W; ++x) {
        if (!valid.at<uchar>(y, x)) continue;
        int n = 0;
        for (int j = std::max(0, y - r); j <= std::min(H - 1, y + r); ++j)
          for (int i = std::max(0, x - r); i <= std::min(W - 1, x + r); ++i) {
            if ((i == x && j == y) || !valid.at<uchar>(j, i)) continue;
            nu[n] = u.at<float>(j, i);
            nv[n] = v.at<float>(j, i);
            ++n;
          }
        if (n < 2) continue;
        bool outlier = false;
        for (int c = 0; c < 2 && !outlier; ++c) {
          float* vals = c == 0 ? nu.data() : nv.data();
          const float centre = c == 0 ? u.at<float>(y, x) : v.at<float>(y, x);
          const float med = Median(vals, n);
          for (int k = 0; k < n; ++k) res[k] = std::abs(vals[k] - med);
          const float rm = Median(res.data(), n);
          outlier = std::abs(centre - med) / (rm + eps) > thr;
        }
        if (outlier) outliers.at<uchar>(y, x) = 1;
      }
    }
  });
  return outliers;
}

void ReplaceVectors(const cv::Mat& u, const cv::Mat& v, const cv::Mat& keep, int max_distance,
                    cv::Mat& u_out, cv::Mat& v_out, cv::Mat& filled) {
  CheckField(u, v, keep, "keep");
  Require(max_distance >= 0,
          "max_distance must be >= 0 (0 = no limit); got " + std::to_string(max_distance));
  const int W = u.cols, H = u.rows;
  cv::Mat cu = u.clone(), cv_ = v.clone();
  cv::Mat known = keep != 0;  // 255 where known
  filled = cv::Mat::zeros(u.size(), CV_8UC1);
  cv::Mat next_known;
  for (int sweep = 0; max_distance == 0 || sweep < max_distance; ++sweep) {
    next_known = known.clone();
    cv::Mat nu = cu.clone(), nv = cv_.clone();
    int changed = 0;
    for (int y = 0; y < H; ++y) {
      for (int x = 0; x < W; ++x) {
        if (known.at<uchar>(y, x)) continue;
        float bu[8], bv[8];
        int n = 0;
        for (int j = std::max(0, y - 1); j <= std::min(H - 1, y + 1); ++j)
          for (int i = std::max(0, x - 1); i <= std::min(W - 1, x + 1); ++i) {
            if ((i == x && j == y) || !known.at<uchar>(j, i)) continue;
            bu[n] = cu.at<float>(j, i);
            bv[n] = cv_.at<float>(j, i);
            ++n;
          }
        if (n == 0) continue;
        nu.at<float>(y, x) = Median(bu, n);
        nv.at<float>(y, x) = Median(bv, n);
        next_known.at<uchar>(y, x) = 255;
        filled.at<uchar>(y, x) = 1;
        ++changed;
      }
    }
    cu = nu;
    cv_ = nv;
    std::swap(known, next_known);
    if (changed == 0) break;
  }
  u_out = cu;
  v_out = cv_;
}

namespace {

// Bilinear samples of u and v at (x, y), the coordinates clamped to the
// image (border replicated); NaN for non-finite coordinates.
inline void SampleReplicate(const cv::Mat& u, const cv::Mat& v, float x, float y, float* su,
                            float* sv) {
  if (!std::isfinite(x) || !std::isfinite(y)) {
    *su = *sv = std::numeric_limits<float>::quiet_NaN();
    return;
  }
  const int W = u.cols, H = u.rows;
  x = std::min(std::max(x, 0.0f), static_cast<float>(W - 1));
  y = std::min(std::max(y, 0.0f), static_cast<float>(H - 1));
  const int x0 = std::min(static_cast<int>(x), W - 1), y0 = std::min(static_cast<int>(y), H - 1);
  const int x1 = std::min(x0 + 1, W - 1), y1 = std::min(y0 + 1, H - 1);
  const float fx = x - x0, fy = y - y0;
  const float w00 = (1 - fx) * (1 - fy), w01 = fx * (1 - fy), w10 = (1 - fx) * fy, w11 = fx * fy;
  const float* a0 = u.ptr<float>(y0);
  const float* a1 = u.ptr<float>(y1);
  const float* b0 = v.ptr<float>(y0);
  const float* b1 = v.ptr<float>(y1);
  *su = w00 * a0[x0] + w01 * a0[x1] + w10 * a1[x0] + w11 * a1[x1];
  *sv = w00 * b0[x0] + w01 * b0[x1] + w10 * b1[x0] + w11 * b1[x1];
}

// The fixed-point inversion on the calling thread, pixel by pixel (each
// pixel's iteration uses only its own vector): at most `iterations` sweeps,
// a pixel stopping once its vector moves by less than 1e-4 px (mean of the
// two components).
void InvertDisplacementSerial(const cv::Mat& u, const cv::Mat& v, int iterations, cv::Mat& bu,
                              cv::Mat& bv) {
  const int W = u.cols, H = u.rows;
  bu.create(u.size(), CV_32FC1);
  bv.create(u.size(), CV_32FC1);
  for (int y = 0; y < H; ++y) {
    const float* su = u.ptr<float>(y);
    const float* sv = v.ptr<float>(y);
    float* du = bu.ptr<float>(y);
    float* dv = bv.ptr<float>(y);
    for (int x = 0; x < W; ++x) {
      // y = x + b; b_new = -w(y) (bilinear, border replicated).
      float bx = -su[x], by = -sv[x];
      for (int it = 0; it < iterations; ++it) {
        float wx, wy;
        SampleReplicate(u, v, x + bx, y + by, &wx, &wy);
        const float change = 0.5f * (std::abs(wx + bx) + std::abs(wy + by));
        bx = -wx;
        by = -wy;
        if (!(change >= 1e-4f)) break;  // converged (or NaN)
      }
      du[x] = bx;
      dv[x] = by;
    }
  }
}

}  // namespace

void InvertDisplacement(const cv::Mat& u, const cv::Mat& v, int iterations, cv::Mat& bu,
                        cv::Mat& bv) {
  Require(u.type() == CV_32FC1 && v.type() == CV_32FC1,
          "u and v must be float32 single-channel maps (CV_32FC1)");
  Require(!u.empty() && u.size() == v.size(),
          "u and v must be non-empty and of one size; got " + SizeText(u) + " and " + SizeText(v));
  Require(iterations >= 1, "iterations must be >= 1; got " + std::to_string(iterations));
  InvertDisplacementSerial(u, v, iterations, bu, bv);
}

void FrameVelocity(const std::vector<cv::Mat>& u, const std::vector<cv::Mat>& v,
                   std::vector<cv::Mat>& u_out, std::vector<cv::Mat>& v_out, int num_threads) {
  Require(!u.empty() && u.size() == v.size(),
          "u and v must hold the same number (>= 1) of pair displacements; got " +
              std::to_string(u.size()) + " and " + std::to_string(v.size()));
  for (std::size_t k = 0; k < u.size(); ++k) {
    Require(u[k].type() == CV_32FC1 && v[k].type() == CV_32FC1,
            "u and v must be float32 single-channel maps (CV_32FC1)");
    Require(u[k].size() == u[0].size() && v[k].size() == u[0].size(),
            "every displacement map must have one size " + SizeText(u[0]) + "; pair " +
                std::to_string(k) + " has " + SizeText(u[k]) + " and " + SizeText(v[k]));
  }
  constexpr int kIterations = 10;
  const std::size_t n = u.size();
  // Outputs already allocated by the caller (e.g. views of a numpy array)
  // are written in place.
  if (u_out.size() != n + 1 || v_out.size() != n + 1) {
    u_out.assign(n + 1, cv::Mat());
    v_out.assign(n + 1, cv::Mat());
  }
  for (std::size_t t = 0; t <= n; ++t) {
    u_out[t].create(u[0].size(), CV_32FC1);
    v_out[t].create(u[0].size(), CV_32FC1);
  }
  u[0].copyTo(u_out[0]);
  v[0].copyTo(v_out[0]);
  // Frames are independent: one per worker at a time.
  ParallelFor(
      n, 1,
      [&](std::size_t b, std::size_t e) {
        cv::Mat bu, bv;
        for (std::size_t t = b + 1; t <= e; ++t) {
          InvertDisplacementSerial(u[t - 1], v[t - 1], kIterations, bu, bv);
          const int H = bu.rows, W = bu.cols;
          for (int y = 0; y < H; ++y) {
            const float* ib = bu.ptr<float>(y);
            const float* jb = bv.ptr<float>(y);
            float* ou = u_out[t].ptr<float>(y);
            float* ov = v_out[t].ptr<float>(y);
            if (t < n) {
              const float* wu = u[t].ptr<float>(y);
              const float* wv = v[t].ptr<float>(y);
              for (int x = 0; x < W; ++x) {
                ou[x] = 0.5f * (wu[x] - ib[x]);
                ov[x] = 0.5f * (wv[x] - jb[x]);
              }
            } else {
              for (int x = 0; x < W; ++x) {
                ou[x] = -ib[x];
                ov[x] = -jb[x];
              }
            }
          }
        }
      },
      num_threads);
}

void TemporalFilterOptions::Check() const {
  CheckInRange(window, 1, 1001, "TemporalFilterOptions.window", "frames");
  Require(window % 2 == 1,
          "TemporalFilterOptions.window must be odd; got " + std::to_string(window));
  CheckInRange(min_valid_fraction, 0, 1, "TemporalFilterOptions.min_valid_fraction");
}

void TemporalFilter(const std::vector<cv::Mat>& u, const std::vector<cv::Mat>& v,
                    const std::vector<cv::Mat>& valid, const TemporalFilterOptions& options,
                    std::vector<cv::Mat>& u_out, std::vector<cv::Mat>& v_out,
                    std::vector<cv::Mat>& valid_out) {
  options.Check();
  const int T = static_cast<int>(u.size());
  Require(T > 0, "the sequence must hold at least one frame");
  Require(v.size() == u.size() && valid.size() == u.size(),
          "u, v and valid must hold the same number of frames; got " + std::to_string(u.size()) +
              ", " + std::to_string(v.size()) + " and " + std::to_string(valid.size()));
  for (int t = 0; t < T; ++t) {
    CheckField(u[t], v[t], valid[t], "valid");
    Require(u[t].size() == u[0].size(), "every frame must have the size of frame 0, " +
                                            SizeText(u[0]) + "; frame " + std::to_string(t) +
                                            " is " + SizeText(u[t]));
  }
  const int W = u[0].cols, H = u[0].rows, h = options.window / 2;
  const bool median = options.statistic == TemporalStatistic::kMedian;
  u_out.assign(T, cv::Mat());
  v_out.assign(T, cv::Mat());
  valid_out.assign(T, cv::Mat());
  for (int t = 0; t < T; ++t) {
    u_out[t].create(H, W, CV_32FC1);
    v_out[t].create(H, W, CV_32FC1);
    valid_out[t].create(H, W, CV_8UC1);
  }
  ParallelRows(H, W, [&](int y0, int y1) {
    std::vector<float> bu(options.window), bv(options.window);
    for (int y = y0; y < y1; ++y)
      for (int t = 0; t < T; ++t) {
        const int a = std::max(0, t - h), b = std::min(T - 1, t + h);
        const int need =
            static_cast<int>(std::ceil(options.min_valid_fraction * (b - a + 1) - 1e-9));
        for (int x = 0; x < W; ++x) {
          int n = 0;
          for (int s = a; s <= b; ++s) {
            if (!valid[s].at<uchar>(y, x)) continue;
            bu[n] = u[s].at<float>(y, x);
            bv[n] = v[s].at<float>(y, x);
            ++n;
          }
          if (n == 0 || n < need) {
            u_out[t].at<float>(y, x) = u[t].at<float>(y, x);
            v_out[t].at<float>(y, x) = v[t].at<float>(y, x);
            valid_out[t].at<uchar>(y, x) = 0;
            continue;
          }
          float mu, mv;
          if (median) {
            mu = Median(bu.data(), n);
            mv = Median(bv.data(), n);
          } else {
            double su = 0, sv = 0;
            for (int k = 0; k < n; ++k) {
              su += bu[k];
              sv += bv[k];
            }
            mu = static_cast<float>(su / n);
            mv = static_cast<float>(sv / n);
          }
          u_out[t].at<float>(y, x) = mu;
          v_out[t].at<float>(y, x) = mv;
          valid_out[t].at<uchar>(y, x) = 1;
        }
      }
  });
}

void PlumeMaskOptions::Check() const {
  CheckNonNegative(threshold, "PlumeMaskOptions.threshold");
  CheckInRange(relative_threshold, 0, 1, "PlumeMaskOptions.relative_threshold");
  CheckInRange(open_radius, 0, 50, "PlumeMaskOptions.open_radius", "px");
  CheckInRange(close_radius, 0, 50, "PlumeMaskOptions.close_radius", "px");
  Require(min_area >= 0,
          "PlumeMaskOptions.min_area must be >= 0 px; got " + std::to_string(min_area));
  CheckInRange(dilate_radius, 0, 50, "PlumeMaskOptions.dilate_radius", "px");
}

cv::Mat PlumeMask(const cv::Mat& density, const PlumeMaskOptions& options) {
  options.Check();
  Require(density.type() == CV_32FC1 && !density.empty(),
          "density must be a non-empty float32 single-channel map (CV_32FC1)");
  Require(cv::checkRange(density), "density contains NaN or infinite values");
  // 99th percentile on a subsample of at most ~20000 values.
  const long long n = static_cast<long long>(density.total());
  const long long step = std::max<long long>(1, n / 20000);
  std::vector<float> samples;
  for (long long i = 0; i < n; i += step)
    samples.push_back(
        density.at<float>(static_cast<int>(i / density.cols), static_cast<int>(i % density.cols)));
  auto p99 = samples.begin() + static_cast<long>(0.99 * (samples.size() - 1));
  std::nth_element(samples.begin(), p99, samples.end());
  const double thr = std::max(options.threshold, options.relative_threshold * *p99);
  cv::Mat mask = density >= thr;  // 255 / 0
  if (!(*p99 > 0) && options.threshold <= 0) mask.setTo(0);  // no gas at all
  auto disk = [](int r) {
    return cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1));
  };
  if (options.open_radius > 0)
    cv::morphologyEx(mask, mask, cv::MORPH_OPEN, disk(options.open_radius));
  if (options.close_radius > 0)
    cv::morphologyEx(mask, mask, cv::MORPH_CLOSE, disk(options.close_radius));
  if (options.min_area > 0) {
    cv::Mat labels, stats, centroids;
    const int count = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
    std::vector<uchar> keep(count, 0);
    for (int i = 1; i < count; ++i)
      keep[i] = stats.at<int>(i, cv::CC_STAT_AREA) >= options.min_area ? 255 : 0;
    for (int y = 0; y < mask.rows; ++y)
      for (int x = 0; x < mask.cols; ++x) mask.at<uchar>(y, x) = keep[labels.at<int>(y, x)];
  }
  if (options.dilate_radius > 0) cv::dilate(mask, mask, disk(options.dilate_radius));
  return mask / 255;
}

}  // namespace qogi
