// Image operations shared by the velocimetry methods: row-parallel loops on
// OpenCV's thread pool, input scaling, pyramids, warping, derivatives, flow
// resampling and residual-based quality. float32 throughout; outputs are
// (re)allocated only when their size or type changes.
#pragma once

#include <opencv2/core.hpp>

#include <functional>
#include <string>
#include <vector>

#include "engine/util/portability.h"
#include "engine/velocimetry/flow.h"

// The solvers' per-row kernels: a clone for x86-64-v3 (AVX2 and FMA, 8 floats
// a vector) besides the baseline build, chosen at load time. The clones
// differ only in float rounding (fused multiply-adds, the grouping of
// vectorised reductions): ~2e-5 px on the flow after 80 warm-started pairs.
#define QOGI_VELOCIMETRY_KERNEL QOGI_TARGET_CLONES("arch=x86-64-v3", "default")

namespace qogi {
namespace flow_ops {

// Calls body(row_begin, row_end) over [0, rows) on OpenCV's thread pool
// (cv::setNumThreads sets its size), or serially when the image is small.
void ParallelRows(int rows, int cols, const std::function<void(int, int)>& body);

// Fixed row bands for deterministic reductions: body(stripe, row_begin,
// row_end) for stripe in [0, NumStripes(rows, cols)), bands that depend on the
// image size only, whatever the number of threads (so sums of per-stripe
// partials are reproducible).
constexpr int kMaxStripes = 16;
int NumStripes(int rows, int cols);
void ParallelStripes(int rows, int cols, const std::function<void(int, int, int)>& body);

// Standard deviation of the pixels of `a` and `b` together, over the mask's
// nonzero pixels when `mask` is non-empty and covers >= 16 pixels, else over
// all pixels. Returns 0 for constant images.
double PairStdDev(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask);

// prev and next divided by their PairStdDev (over `mask`) into i0 and i1
// (CV_32F), and, when mean_out is given, the mean of the scaled pair. Two
// constant frames carry no information on motion: then every vector of
// `flow` is reported invalid (quality and valid 0; u and v keep their start)
// and the result is false.
bool NormalisePair(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, cv::Mat& i0,
                   cv::Mat& i1, FlowField& flow, double* mean_out = nullptr);

// The range checks of a patch search's grid (DIS and the fluid flow's
// search): patch side in [4, 64] px, stride in [1, 63] px and < the side;
// messages name "<type>.patch_size" and "<type>.patch_stride".
void CheckPatchGrid(int patch_size, int patch_stride, const std::string& type);

// The flow a method starts from at full resolution: a copy of flow's u and
// v when warm-started, else zeros of `size` (CV_32FC1).
void StartFlow(const FlowField& flow, bool warm, cv::Size size, cv::Mat& u, cv::Mat& v);

// Number of pyramid levels (>= 1, level 0 = full resolution) such that the
// coarsest level's smaller side is >= min_size px, at most max_levels.
int NumLevels(cv::Size size, int max_levels, int min_size);

// pyr[0] = img (shared, not copied), pyr[l] = cv::pyrDown(pyr[l-1]): level l
// pixel (i, j) is centred on level-0 pixel (2^l i, 2^l j).
void BuildPyramid(const cv::Mat& img, int levels, std::vector<cv::Mat>& pyr);

// dst(x) = src(x + w(x)) by bicubic (Keys, a = -0.5) interpolation in float
// precision, the source replicated beyond its border; inside(x) = 1 where
// x + w(x) lies within the image, else 0 (skipped when inside == nullptr).
void Warp(const cv::Mat& src, const cv::Mat& u, const cv::Mat& v, cv::Mat& dst,
          cv::Mat* inside = nullptr);

// Central differences (f(x+1) - f(x-1)) / 2, one-sided at the border.
void CentralGradient(const cv::Mat& src, cv::Mat& gx, cv::Mat& gy);
// Five-point derivative (-f(x+2) + 8 f(x+1) - 8 f(x-1) + f(x-2)) / 12,
// falling back to central and one-sided differences near the border.
void FivePointGradient(const cv::Mat& src, cv::Mat& gx, cv::Mat& gy);

// Resamples a flow field given on a pyramid level to another level's size,
// bilinearly under the pyramid's pixel-centre convention (x_dst = x_src *
// scale), and multiplies the vectors by scale = 2^(level_src - level_dst).
void ResampleFlow(const cv::Mat& u, const cv::Mat& v, cv::Size size, double scale, cv::Mat& u_out,
                  cv::Mat& v_out);

// Per-pixel quality from a data residual: q = exp(-r^2 / (2 s^2)) with r the
// 3x3 mean of |residual| and s = 1.4826 x the median of r over the valid
// pixels (a robust scale, so q is an inlier weight relative to the frame).
void QualityFromResidual(const cv::Mat& residual, const cv::Mat& valid, cv::Mat& quality);

// For methods without a data term of their own: the brightness residual
// next(x + w) - prev(x) of the result sets flow.quality (as in
// QualityFromResidual) and flow.residual_ratio, and flow.valid is ANDed with
// "x + w inside the frame". i0, i1 are the frames (any common scale).
void FinishWithBrightnessResidual(const cv::Mat& i0, const cv::Mat& i1, FlowField& flow);

// AND of `valid` (CV_8U 0/1) with `mask` (nonzero = keep) and with the
// finiteness of u and v. Empty mask = no restriction.
void ApplyMask(const cv::Mat& mask, const cv::Mat& u, const cv::Mat& v, cv::Mat& valid);

}  // namespace flow_ops
}  // namespace qogi
