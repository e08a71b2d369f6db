// Particle-image-velocimetry-style windowed cross-correlation (own
// implementation on OpenCV's FFT).
//
// Multi-pass window-deformation PIV after Scarano, "Iterative image
// deformation methods in PIV", Meas. Sci. Technol. 13, R1-R19 (2002), and
// OpenPIV: interrogation windows of the first frame are correlated with the
// same windows of the second by FFT (zero-mean, normalised to a correlation
// coefficient), the correlation peak is located to sub-pixel precision by a
// three-point Gaussian fit in x and y, and the vectors are validated by the
// normalised median test (Westerweel & Scarano, Exp. Fluids 39, 1096, 2005),
// outliers replaced by the median of their valid neighbours. The passes start
// with initial_window_size and halve it down to window_size, then repeat at
// window_size (final_passes). From the second pass on, both frames are
// deformed by half of the interpolated displacement field (central
// differences: frame 1 at x - w/2, frame 2 at x + w/2), so each pass measures
// a small residual displacement at the windows' centre time.
//
// The vectors (one per window, spacing window_size * (1 - overlap)) are
// interpolated bilinearly to every pixel and converted from the midpoint
// displacement to the forward map of the interface (w(x) = w_mid(x + w/2)).
// Spatial resolution is about one final window.
//
// Use it for: strongly textured plumes, large displacements (up to about a
// quarter of the initial window per pass; more with a warm start), and when a
// per-vector correlation quality is wanted. Like the optical-flow methods it
// tracks texture, not mass; flow gradients within one window are smoothed.
//
// quality: correlation coefficient of the final peak, in [0, 1].
// valid: vectors with a peak above min_correlation that passed the median
// test, within the vector grid, inside the gas mask, x + w in the frame.
#pragma once

#include "engine/velocimetry/flow.h"

#include <vector>

namespace qogi {

struct PivOptions {
  // Final interrogation window [px], even. [8, 256]. Default 16.
  int window_size = 16;
  // First-pass window [px], even, >= window_size; halved each pass down to
  // window_size. The first pass recovers up to ~1/4 of it. [8, 512].
  // Default 64.
  int initial_window_size = 64;
  // Overlap of neighbouring windows, as a fraction of the window. [0, 0.9].
  // Default 0.5.
  double overlap = 0.5;
  // Passes at the final window size. [1, 20]. Default 3.
  int final_passes = 3;
  // Deform both frames by the interpolated displacement between passes
  // (true) or only offset the windows by the integer displacement (false).
  // Default true.
  bool deform = true;
  // Normalised median test threshold between passes. > 0. Default 2.
  double median_threshold = 2.0;
  // Normalised median test noise level [px]. > 0. Default 0.1.
  double median_epsilon = 0.1;
  // Smallest correlation coefficient of a valid peak. [0, 1]. Default 0.2.
  double min_correlation = 0.2;
  // Smallest share of a window's pixels inside the gas mask for the window to
  // be evaluated (with a mask). [0, 1]. Default 0.25.
  double min_mask_fraction = 0.25;

  void Check() const;
};

class PivFlow : public OpticalFlow {
 public:
  explicit PivFlow(const PivOptions& options = {});
  FlowMethod method() const override { return FlowMethod::kPiv; }
  const PivOptions& options() const { return options_; }

 protected:
  void CalcChecked(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask, bool warm,
                   FlowField& flow) override;

 private:
  struct Grid {
    int n = 0, step = 0, nx = 0, ny = 0;
    double x0 = 0, y0 = 0;  // centre of the first window [px]
    cv::Mat u, v, corr;     // CV_32F, ny x nx
    cv::Mat ok;             // CV_8U: peak found and accepted
  };
  void Pass(int n, bool deform, const cv::Mat& mask);
  void ToDense(const Grid& g, cv::Mat& u, cv::Mat& v) const;

  PivOptions options_;
  cv::Mat i0n_, i1n_, d0_, d1_, pu_, pv_, hu_, hv_, maskf_, mask_integral_;
  Grid grid_;
};

}  // namespace qogi
