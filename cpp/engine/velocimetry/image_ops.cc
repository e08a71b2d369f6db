#include "engine/velocimetry/image_ops.h"

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "engine/util/check.h"
#include "engine/util/interpolation.h"
#include "engine/util/portability.h"

namespace qogi {
namespace flow_ops {

void ParallelRows(int rows, int cols, const std::function<void(int, int)>& body) {
  if (rows <= 0) return;
  const long long pixels = static_cast<long long>(rows) * cols;
  const int threads = cv::getNumThreads();
  // Below ~16k pixels a thread hand-off costs more than it saves.
  if (threads <= 1 || pixels < 16384 || rows < 8) {
    body(0, rows);
    return;
  }
  const int stripes = std::min(rows, threads * 4);
  cv::parallel_for_(
      cv::Range(0, stripes),
      [&](const cv::Range& r) {
        const int b = static_cast<int>(static_cast<long long>(r.start) * rows / stripes);
        const int e = static_cast<int>(static_cast<long long>(r.end) * rows / stripes);
        if (e > b) body(b, e);
      },
      stripes);
}

int NumStripes(int rows, int cols) {
  // ~4096 pixels per stripe at least: small images run as one stripe.
  const long long by_size = static_cast<long long>(rows) * cols / 4096;
  return static_cast<int>(std::max<long long>(
      1, std::min<long long>({by_size, static_cast<long long>(rows), kMaxStripes})));
}

void ParallelStripes(int rows, int cols, const std::function<void(int, int, int)>& body) {
  if (rows <= 0) return;
  const int stripes = NumStripes(rows, cols);
  if (stripes == 1) {
    body(0, 0, rows);
    return;
  }
  auto run = [&](int s) {
    const int b = static_cast<int>(static_cast<long long>(s) * rows / stripes);
    const int e = static_cast<int>(static_cast<long long>(s + 1) * rows / stripes);
    if (e > b) body(s, b, e);
  };
  const long long pixels = static_cast<long long>(rows) * cols;
  if (cv::getNumThreads() <= 1 || pixels < 16384) {
    for (int s = 0; s < stripes; ++s) run(s);
    return;
  }
  cv::parallel_for_(
      cv::Range(0, stripes),
      [&](const cv::Range& r) {
        for (int s = r.start; s < r.end; ++s) run(s);
      },
      stripes);
}

double PairStdDev(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  bool use_mask = !mask.empty() && cv::countNonZero(mask) >= 16;
  double s = 0, s2 = 0;
  long long n = 0;
  for (const cv::Mat* m : {&a, &b}) {
    for (int y = 0; y < m->rows; ++y) {
      const float* p = m->ptr<float>(y);
      // Per-row float sums (vectorised), accumulated in double.
      float rs = 0.f, rs2 = 0.f;
      if (use_mask) {
        const uchar* k = mask.ptr<uchar>(y);
        for (int x = 0; x < m->cols; ++x) {
          const float keep = k[x] ? 1.f : 0.f;
          rs += keep * p[x];
          rs2 += keep * p[x] * p[x];
          n += k[x] ? 1 : 0;
        }
      } else {
        for (int x = 0; x < m->cols; ++x) {
          rs += p[x];
          rs2 += p[x] * p[x];
        }
        n += m->cols;
      }
      s += rs;
      s2 += rs2;
    }
  }
  if (n < 2) return 0.0;
  const double mean = s / n;
  const double var = std::max(0.0, s2 / n - mean * mean);
  return std::sqrt(var);
}

bool NormalisePair(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, cv::Mat& i0,
                   cv::Mat& i1, FlowField& flow, double* mean_out) {
  const double sd = PairStdDev(prev, next, mask);
  if (!(sd > 0)) {
    flow.quality.setTo(0);
    flow.valid.setTo(0);
    return false;
  }
  prev.convertTo(i0, CV_32F, 1.0 / sd);
  next.convertTo(i1, CV_32F, 1.0 / sd);
  if (mean_out) *mean_out = 0.5 * (cv::mean(i0)[0] + cv::mean(i1)[0]);
  return true;
}

void CheckPatchGrid(int patch_size, int patch_stride, const std::string& type) {
  CheckInRange(patch_size, 4, 64, (type + ".patch_size").c_str(), "px");
  CheckInRange(patch_stride, 1, 63, (type + ".patch_stride").c_str(), "px");
  Require(patch_stride < patch_size, type + ".patch_stride must be < patch_size; got " +
                                         std::to_string(patch_stride) +
                                         " >= " + std::to_string(patch_size));
}

void StartFlow(const FlowField& flow, bool warm, cv::Size size, cv::Mat& u, cv::Mat& v) {
  if (warm) {
    flow.u.copyTo(u);
    flow.v.copyTo(v);
  } else {
    u = cv::Mat::zeros(size, CV_32FC1);
    v = cv::Mat::zeros(size, CV_32FC1);
  }
}

int NumLevels(cv::Size size, int max_levels, int min_size) {
  int levels = 1;
  int w = size.width, h = size.height;
  while (levels < max_levels) {
    w = (w + 1) / 2;
    h = (h + 1) / 2;
    if (std::min(w, h) < min_size) break;
    ++levels;
  }
  return levels;
}

void BuildPyramid(const cv::Mat& img, int levels, std::vector<cv::Mat>& pyr) {
  pyr.resize(levels);
  pyr[0] = img;
  for (int l = 1; l < levels; ++l) cv::pyrDown(pyr[l - 1], pyr[l]);
}

namespace {

// Samples of the padded source beyond the frame on each side: enough for the
// bicubic's 4 x 4 taps around a position clamped to 2 px outside the frame.
constexpr int kWarpPad = 4;

// One row of Warp: base points at the padded source's pixel (-kWarpPad,
// -kWarpPad), step is its row stride in floats. Branch-free (the padding
// replicates the border) and with int offsets, so that it vectorises with
// gathers.
QOGI_VELOCIMETRY_KERNEL
void WarpRow(int W, int y, const float* QOGI_RESTRICT base, int step, const float* QOGI_RESTRICT pu,
             const float* QOGI_RESTRICT pv, float wmax, float hmax, float* QOGI_RESTRICT pd,
             uchar* QOGI_RESTRICT pin) {
  const float fy = static_cast<float>(y);
  for (int x = 0; x < W; ++x) {
    float px = static_cast<float>(x) + pu[x], py = fy + pv[x];
    pin[x] = (px >= 0.f && px <= wmax && py >= 0.f && py <= hmax) ? 1 : 0;
    px = px > -2.f ? px : -2.f;  // also maps NaN to the border
    py = py > -2.f ? py : -2.f;
    px = px < wmax + 2.f ? px : wmax + 2.f;
    py = py < hmax + 2.f ? py : hmax + 2.f;
    // floor by truncation of a positive number (px, py >= -2): without
    // SSE4.1 std::floor is a library call.
    const int ix = static_cast<int>(px + 2.f) - 2, iy = static_cast<int>(py + 2.f) - 2;
    float wx[4], wy[4];
    CubicWeights(px - static_cast<float>(ix), wx);
    CubicWeights(py - static_cast<float>(iy), wy);
    const int o = (iy - 1 + kWarpPad) * step + (ix - 1 + kWarpPad);
    float acc = 0.f;
    for (int j = 0; j < 4; ++j) {
      const int oj = o + j * step;
      acc += wy[j] * (wx[0] * base[oj] + wx[1] * base[oj + 1] + wx[2] * base[oj + 2] +
                      wx[3] * base[oj + 3]);
    }
    pd[x] = acc;
  }
}

}  // namespace

void Warp(const cv::Mat& src, const cv::Mat& u, const cv::Mat& v, cv::Mat& dst, cv::Mat* inside) {
  CV_Assert(src.type() == CV_32FC1 && u.size() == src.size() && v.size() == src.size());
  dst.create(src.size(), CV_32FC1);
  // The kernel always writes the inside flags (no branch in its loop).
  thread_local cv::Mat unused_inside;
  cv::Mat& in = inside ? *inside : unused_inside;
  in.create(src.size(), CV_8UC1);
  const int W = src.cols, H = src.rows;
  const float wmax = static_cast<float>(W - 1), hmax = static_cast<float>(H - 1);
  // The source with its border replicated kWarpPad px out (the same samples
  // as clamping each tap's index), kept between calls.
  thread_local cv::Mat padded;
  cv::copyMakeBorder(src, padded, kWarpPad, kWarpPad, kWarpPad, kWarpPad, cv::BORDER_REPLICATE);
  CV_Assert(padded.isContinuous() && padded.total() < (1u << 31));
  const float* base = padded.ptr<float>(0);
  const int step = padded.cols;
  ParallelRows(H, W, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      WarpRow(W, y, base, step, u.ptr<float>(y), v.ptr<float>(y), wmax, hmax, dst.ptr<float>(y),
              in.ptr<uchar>(y));
  });
}

void CentralGradient(const cv::Mat& src, cv::Mat& gx, cv::Mat& gy) {
  CV_Assert(src.type() == CV_32FC1);
  gx.create(src.size(), CV_32FC1);
  gy.create(src.size(), CV_32FC1);
  const int W = src.cols, H = src.rows;
  ParallelRows(H, W, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* p = src.ptr<float>(y);
      const float* pn = src.ptr<float>(std::min(y + 1, H - 1));
      const float* pp = src.ptr<float>(std::max(y - 1, 0));
      const float sy = (y == 0 || y == H - 1) ? 1.f : 0.5f;
      float* ox = gx.ptr<float>(y);
      float* oy = gy.ptr<float>(y);
      ox[0] = W > 1 ? p[1] - p[0] : 0.f;
      for (int x = 1; x < W - 1; ++x) ox[x] = 0.5f * (p[x + 1] - p[x - 1]);
      if (W > 1) ox[W - 1] = p[W - 1] - p[W - 2];
      for (int x = 0; x < W; ++x) oy[x] = H > 1 ? sy * (pn[x] - pp[x]) : 0.f;
    }
  });
}

void FivePointGradient(const cv::Mat& src, cv::Mat& gx, cv::Mat& gy) {
  CV_Assert(src.type() == CV_32FC1);
  CentralGradient(src, gx, gy);
  const int W = src.cols, H = src.rows;
  const float k = 1.f / 12.f;
  ParallelRows(H, W, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* p = src.ptr<float>(y);
      float* ox = gx.ptr<float>(y);
      for (int x = 2; x < W - 2; ++x)
        ox[x] = k * (p[x - 2] - 8.f * p[x - 1] + 8.f * p[x + 1] - p[x + 2]);
      if (y >= 2 && y < H - 2) {
        const float* a = src.ptr<float>(y - 2);
        const float* b = src.ptr<float>(y - 1);
        const float* c = src.ptr<float>(y + 1);
        const float* d = src.ptr<float>(y + 2);
        float* oy = gy.ptr<float>(y);
        for (int x = 0; x < W; ++x) oy[x] = k * (a[x] - 8.f * b[x] + 8.f * c[x] - d[x]);
      }
    }
  });
}

void ResampleFlow(const cv::Mat& u, const cv::Mat& v, cv::Size size, double scale, cv::Mat& u_out,
                  cv::Mat& v_out) {
  CV_Assert(u.type() == CV_32FC1 && v.type() == CV_32FC1 && u.size() == v.size());
  CV_Assert(&u != &u_out && &v != &v_out);
  u_out.create(size, CV_32FC1);
  v_out.create(size, CV_32FC1);
  const int Ws = u.cols, Hs = u.rows;
  if (scale == 2.0 && (size.width + 1) / 2 == Ws && (size.height + 1) / 2 == Hs) {
    // One pyramid level up: even pixels copy a source sample, odd ones
    // average two (or four); the last odd row/column repeats the border.
    // Rows first (one source row, or the mean of two, times 2), then
    // columns: the same bilinear weights as sampling each pixel directly.
    ParallelRows(size.height, size.width, [&](int y0, int y1) {
      std::vector<float> col(Ws);
      for (int y = y0; y < y1; ++y) {
        const int iy = y / 2, iy1 = std::min(iy + (y & 1), Hs - 1);
        const float wy = (y & 1) && iy1 != iy ? 1.f : 2.f;  // 2 x weight of row iy
        for (int c = 0; c < 2; ++c) {
          const cv::Mat& src = c == 0 ? u : v;
          float* out = (c == 0 ? u_out : v_out).ptr<float>(y);
          const float* r0 = src.ptr<float>(iy);
          const float* r1 = src.ptr<float>(iy1);
          for (int i = 0; i < Ws; ++i) col[i] = wy * r0[i] + (2.f - wy) * r1[i];
          const int pairs = size.width / 2;  // full (even, odd) output pairs
          for (int i = 0; i < pairs; ++i) {
            out[2 * i] = col[i];
            out[2 * i + 1] = 0.5f * (col[i] + col[std::min(i + 1, Ws - 1)]);
          }
          if (size.width & 1) out[size.width - 1] = col[Ws - 1];
        }
      }
    });
    return;
  }
  const float inv = static_cast<float>(1.0 / scale), s = static_cast<float>(scale);
  ParallelRows(size.height, size.width, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      float sy = std::min(std::max(y * inv, 0.f), static_cast<float>(Hs - 1));
      int iy = std::min(static_cast<int>(sy), std::max(Hs - 2, 0));
      float ty = sy - iy;
      const int iy1 = std::min(iy + 1, Hs - 1);
      const float *u0 = u.ptr<float>(iy), *u1 = u.ptr<float>(iy1);
      const float *v0 = v.ptr<float>(iy), *v1 = v.ptr<float>(iy1);
      float* ou = u_out.ptr<float>(y);
      float* ov = v_out.ptr<float>(y);
      for (int x = 0; x < size.width; ++x) {
        float sx = std::min(std::max(x * inv, 0.f), static_cast<float>(Ws - 1));
        int ix = std::min(static_cast<int>(sx), std::max(Ws - 2, 0));
        float tx = sx - ix;
        const int ix1 = std::min(ix + 1, Ws - 1);
        const float a = (1 - tx) * (1 - ty), b = tx * (1 - ty), c = (1 - tx) * ty, d = tx * ty;
        ou[x] = s * (a * u0[ix] + b * u0[ix1] + c * u1[ix] + d * u1[ix1]);
        ov[x] = s * (a * v0[ix] + b * v0[ix1] + c * v1[ix] + d * v1[ix1]);
      }
    }
  });
}

namespace {

// The k-th smallest of `values` (what std::nth_element puts at position k),
// reordering them. For non-negative finite values (a residual's magnitude)
// a histogram of the float bits' top 12 (exponent and 3 mantissa bits,
// monotonic in the value) first finds the bucket holding it, so that the
// selection runs on that bucket only: a fifth of the time on 20000 values.
float KthSmallest(std::vector<float>& values, std::size_t k) {
  constexpr int kShift = 20;
  constexpr std::uint32_t kFirstNonFinite = 0x7f800000u >> kShift;  // inf, NaN
  std::vector<std::uint32_t> count(std::size_t{1} << (32 - kShift), 0);
  bool plain = false;
  for (const float v : values) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    const std::uint32_t bucket = bits >> kShift;
    plain |= bucket >= kFirstNonFinite;  // negative, infinite or NaN
    ++count[bucket];
  }
  if (!plain) {
    std::size_t below = 0;
    std::uint32_t b = 0;
    while (below + count[b] <= k) below += count[b++];
    std::size_t n = 0;
    for (const float v : values) {
      std::uint32_t bits;
      std::memcpy(&bits, &v, sizeof bits);
      if ((bits >> kShift) == b) values[n++] = v;  // n <= index of v: in place
    }
    auto kth = values.begin() + static_cast<std::ptrdiff_t>(k - below);
    std::nth_element(values.begin(), kth, values.begin() + static_cast<std::ptrdiff_t>(n));
    return *kth;
  }
  auto kth = values.begin() + static_cast<std::ptrdiff_t>(k);
  std::nth_element(values.begin(), kth, values.end());
  return *kth;
}

}  // namespace

void QualityFromResidual(const cv::Mat& residual, const cv::Mat& valid, cv::Mat& quality) {
  CV_Assert(residual.type() == CV_32FC1);
  cv::Mat r = cv::abs(residual);
  cv::blur(r, r, cv::Size(3, 3), cv::Point(-1, -1), cv::BORDER_REPLICATE);
  // Median of r over valid pixels, on a subsample of at most ~20000 values.
  const long long n = static_cast<long long>(r.total());
  const int step = static_cast<int>(std::max<long long>(1, n / 20000));
  std::vector<float> samples;
  samples.reserve(static_cast<std::size_t>(n / step + 1));
  // Every step-th pixel in row-major order (x, y kept incrementally: an
  // integer division per sample cost more than the selection).
  for (int y = 0, x = 0; y < r.rows;) {
    if (valid.empty() || valid.at<uchar>(y, x)) samples.push_back(r.at<float>(y, x));
    x += step;
    while (x >= r.cols && y < r.rows) {
      x -= r.cols;
      ++y;
    }
  }
  double s = 0.0;
  if (!samples.empty()) s = 1.4826 * KthSmallest(samples, samples.size() / 2);
  quality.create(r.size(), CV_32FC1);
  const float inv2s2 = s > 0 ? static_cast<float>(0.5 / (s * s)) : 0.f;
  const bool perfect = !(s > 0);
  for (int y = 0; y < r.rows; ++y) {
    const float* pr = r.ptr<float>(y);
    float* pq = quality.ptr<float>(y);
    for (int x = 0; x < r.cols; ++x) {
      if (perfect)
        pq[x] = pr[x] > 0 ? 0.f : 1.f;
      else
        pq[x] = std::exp(-pr[x] * pr[x] * inv2s2);
    }
  }
}

void FinishWithBrightnessResidual(const cv::Mat& i0, const cv::Mat& i1, FlowField& flow) {
  cv::Mat warped, inside;
  Warp(i1, flow.u, flow.v, warped, &inside);
  cv::Mat residual = warped - i0;
  double after = 0, before = 0;
  for (int y = 0; y < i0.rows; ++y) {
    const float* p0 = i0.ptr<float>(y);
    const float* p1 = i1.ptr<float>(y);
    const float* pr = residual.ptr<float>(y);
    const uchar* pin = inside.ptr<uchar>(y);
    uchar* pv = flow.valid.ptr<uchar>(y);
    for (int x = 0; x < i0.cols; ++x) {
      pv[x] = (pv[x] && pin[x]) ? 1 : 0;
      if (pv[x]) {
        after += std::abs(pr[x]);
        before += std::abs(p1[x] - p0[x]);
      }
    }
  }
  flow.residual_ratio = before > 0 ? after / before : std::numeric_limits<double>::quiet_NaN();
  QualityFromResidual(residual, flow.valid, flow.quality);
}

namespace {

// valid &= mask (when kMask) and u, v finite, on one row.
template <bool kMask>
QOGI_ALWAYS_INLINE void ApplyMaskRowBody(int n, const uchar* QOGI_RESTRICT pm,
                                         const float* QOGI_RESTRICT pu,
                                         const float* QOGI_RESTRICT pw, uchar* QOGI_RESTRICT pv) {
  constexpr float kMax = std::numeric_limits<float>::max();
  for (int x = 0; x < n; ++x) {
    // |u| <= max is false for NaN and the infinities (std::isfinite does
    // not vectorise).
    const bool keep = (!kMask || pm[x] != 0) && std::abs(pu[x]) <= kMax && std::abs(pw[x]) <= kMax;
    pv[x] = (pv[x] != 0 && keep) ? 1 : 0;
  }
}

// ApplyMaskRowBody with or without a mask (a non-template for clang's
// target_clones).
QOGI_VELOCIMETRY_KERNEL
void ApplyMaskRow(bool use_mask, int n, const uchar* QOGI_RESTRICT pm,
                  const float* QOGI_RESTRICT pu, const float* QOGI_RESTRICT pw,
                  uchar* QOGI_RESTRICT pv) {
  if (use_mask)
    ApplyMaskRowBody<true>(n, pm, pu, pw, pv);
  else
    ApplyMaskRowBody<false>(n, pm, pu, pw, pv);
}

}  // namespace

void ApplyMask(const cv::Mat& mask, const cv::Mat& u, const cv::Mat& v, cv::Mat& valid) {
  for (int y = 0; y < valid.rows; ++y)
    ApplyMaskRow(!mask.empty(), valid.cols, mask.empty() ? nullptr : mask.ptr<uchar>(y),
                 u.ptr<float>(y), v.ptr<float>(y), valid.ptr<uchar>(y));
}

}  // namespace flow_ops
}  // namespace qogi
