// Velocimetry: one interface for every optical-flow / cross-correlation method.
//
// A method estimates, from two consecutive frames `prev` (time t) and `next`
// (time t + 1 frame), the forward displacement map
//
//   w(x) = (u(x), v(x))   [px/frame]      such that the gas at pixel x of
//                                          `prev` is at x + w(x) in `next`,
//
// for every pixel x of `prev` (x right, y down, origin at the top-left pixel
// centre). Frames are one channel: band radiance (better: radiance contrast
// against the background) or column density [kg/m2]; any linear unit works,
// every method normalises its input internally. The optional gas mask marks the
// pixels with detected gas; vectors outside it are reported invalid.
//
// Usage (after OpenCV's DIS and OpenPIV):
//   qogi::FluidFlow flow(qogi::FluidFlowOptions{});
//   qogi::FlowField f;                  // empty: starts from zero motion
//   flow.Calc(rho0, rho1, f);           // f.u, f.v, f.quality, f.valid
//   flow.Calc(rho1, rho2, f);           // warm start from the last result
//
// Conversion to m/s: MetresPerSecondPerPixelPerFrame().
#pragma once

#include <opencv2/core.hpp>

#include <memory>
#include <string>

namespace qogi {

enum class FlowMethod {
  kHornSchunck,  // variational, brightness constancy (HornSchunckFlow)
  kLucasKanade,  // local least squares in a Gaussian window (LucasKanadeFlow)
  kFarneback,    // OpenCV polynomial expansion (FarnebackFlow)
  kDis,          // OpenCV dense inverse search (DisFlow)
  kPiv,          // windowed FFT cross-correlation (PivFlow)
  kFluid,        // variational, continuity equation on column density (FluidFlow)
};

// "horn_schunck", "lucas_kanade", "farneback", "dis", "piv", "fluid".
const char* FlowMethodName(FlowMethod method);
// Inverse of FlowMethodName; throws std::invalid_argument listing the names.
FlowMethod ParseFlowMethod(const std::string& name);

// The result of one frame pair. All maps have the frame's size.
struct FlowField {
  cv::Mat u;        // CV_32F, displacement to the right [px/frame]
  cv::Mat v;        // CV_32F, displacement downwards [px/frame]
  cv::Mat quality;  // CV_32F in [0, 1], per vector; its meaning is the
                    // method's (see each method's header), 1 = best
  cv::Mat valid;    // CV_8U, 1 where the vector is an estimate the method
                    // stands by (inside the gas mask, supported by data), else 0
  // Frame-level quality: mean |data residual| after the flow divided by the
  // mean |data residual| at zero motion, over the valid vectors (0 = the
  // motion explains every change between the frames, >= 1 = it explains
  // nothing). The residual is the method's own data term for HornSchunck
  // and FluidFlow (brightness, mass conservation), brightness for the others.
  // NaN when there is nothing to explain (identical frames).
  double residual_ratio = 0.0;

  // True when u and v are CV_32F of `size` (usable as a warm start).
  bool HasSize(cv::Size size) const;
  // (Re)allocates all four maps at `size`, zero motion, quality 0, invalid.
  void Reset(cv::Size size);
};

// Base of every method. Not thread-safe: one instance per thread (instances
// keep buffers between calls to avoid reallocations).
class OpticalFlow {
 public:
  virtual ~OpticalFlow() = default;
  virtual FlowMethod method() const = 0;

  // Estimates the motion from `prev` to `next`.
  //   prev, next: CV_32FC1, same size, at least 16 x 16 px, finite.
  //   flow: in: a warm start when flow.HasSize(prev.size()) and its u, v are
  //         finite (e.g. the previous pair's result), otherwise zero motion;
  //         out: the result.
  //   mask: empty (all pixels) or CV_8UC1 of the frame's size, nonzero = gas.
  // Throws std::invalid_argument for bad input (naming what and why).
  void Calc(const cv::Mat& prev, const cv::Mat& next, FlowField& flow,
            const cv::Mat& mask = cv::Mat());

 protected:
  // Called by Calc with checked input; `warm` tells whether flow.u/v hold a
  // warm start (otherwise they are allocated and zero).
  virtual void CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                           FlowField& flow) = 0;
};

// Factor from px/frame to m/s for a camera at `distance_m` from the plume with
// one pixel's angular size `ifov_rad`, recording at `frame_rate_hz`:
//   speed [m/s] = displacement [px/frame] * distance_m * ifov_rad * frame_rate_hz
// (thesis eq. 7-11: the projected velocity in the plume plane). Checks that
// every argument is finite and > 0.
double MetresPerSecondPerPixelPerFrame(double distance_m, double ifov_rad, double frame_rate_hz);

}  // namespace qogi
