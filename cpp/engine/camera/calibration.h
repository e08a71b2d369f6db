// Radiometric calibration of a camera channel from blackbody frames (thesis
// section 2.5): raw counts -> band radiance [W/(m2 sr)] -> radiometric
// temperature [K].
//
// Model. A pixel p integrating for t seconds while viewing a scene of channel
// band radiance L reads
//
//   c_p = t (g_p L + o_p) [+ small nonlinearity]
//
// counts: the photo-current (g_p L) and the offset current (o_p: dark current
// and the camera's own stray emission) both integrate over t. So the flux
// f_p = c_p / t [counts/s] does not depend on the integration time.
//
// 1. Non-uniformity correction (two-point, per pixel). From the temporal mean
//    fluxes m1_p, m2_p of two uniform blackbody scenes (default: the coldest
//    and the hottest calibration scene) and their means over good pixels M1,
//    M2, every pixel is mapped onto the array-mean pixel:
//
//      f'_p = a_p f_p + b_p,   a_p = (M2 - M1) / (m2_p - m1_p),
//                              b_p = M1 - a_p m1_p.
//
//    Pixels whose responsivity (m2_p - m1_p) strays from the median by more
//    than a tolerance, whose temporal noise is far above the median, or that
//    are out of range (saturated) in any calibration frame are bad pixels:
//    flagged, and on output replaced by the mean of their good 3x3
//    neighbours (or NaN).
//
// 2. Counts-flux curve (per channel). The array-mean corrected flux F_k of
//    each calibration scene k is fitted by least squares against the band
//    radiance of its blackbody, L_k = eps L(T_k) + (1 - eps) L(T_amb)
//    (eps: source emissivity; T_amb: the surroundings it reflects):
//
//      F = G L + O            (linear: >= 3 temperatures)
//      F = G L + O + Q L^2    (quadratic: >= 4 temperatures)
//
//    G [counts/s per W/(m2 sr)] is the responsivity, O [counts/s] the offset
//    flux. Residuals are reported per scene, in counts/s and in kelvin.
//
// 3. Conversions: counts -> radiance L = F^-1((a_p c / t) + b_p), and back;
//    radiance <-> radiometric temperature through the channel response
//    (RadiometricTable).
//
// Assumption stated: all offsets scale with t (an electronic offset that does
// not is either subtracted by the camera or negligible). Calibrating with
// scenes at several integration times tests it: the residuals show it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/optics/spectral_response.h"
#include "engine/util/parallel.h"

namespace qogi {

struct CalibrationOptions {
  bool quadratic = false;  // fit the quadratic term Q L^2 (needs >= 4 temperatures); default false
  double saturation_counts = 65535.0;  // raw counts >= this are saturated [counts]; default 65535
  double min_valid_counts = 0.0;  // raw counts <= this are under range (dead) [counts]; default 0
  // A pixel whose NUC responsivity m2_p - m1_p differs from the median by more
  // than this fraction of it is bad [-]; default 0.3, within (0, 1).
  double bad_response_tolerance = 0.3;
  // A pixel whose temporal noise (std over frames, worst NUC scene) exceeds
  // this multiple of the median is bad [-]; default 6, >= 1. Needs >= 2
  // frames per NUC scene (otherwise not applied).
  double bad_noise_factor = 6.0;
  double max_bad_fraction =
      0.05;  // more bad pixels than this fraction is an error [-]; default 0.05
  int nuc_cold_scene = -1;  // index of the cold NUC scene; default -1 = the coldest
  int nuc_hot_scene = -1;  // index of the hot NUC scene; default -1 = the hottest
  double blackbody_emissivity = 1.0;  // emissivity of the calibration source [-]; default 1, (0, 1]
  // Temperature of the surroundings reflected by the source [K]; default 0 =
  // none (only needed when blackbody_emissivity < 1).
  double ambient_temperature_K = 0.0;
  int num_threads = 0;  // worker threads; default 0 = all cores
  void Check() const;
};

// One uniform blackbody scene: num_frames raw frames of height x width counts
// (row-major, frame after frame) at one integration time.
struct CalibrationScene {
  double blackbody_temperature_K = 0;  // source temperature [K]
  double integration_time_s = 0;  // integration (exposure) time [s]
  const float* frames = nullptr;  // raw counts, num_frames x height x width
  std::size_t num_frames = 0;
};

// F(L) = G L + O + Q L^2 [counts/s] of band radiance L [W/(m2 sr)].
struct CountsFluxCurve {
  double gain = 0;  // G [counts/s per W/(m2 sr)]
  double offset = 0;  // O [counts/s]
  double quadratic = 0;  // Q [counts/s per (W/(m2 sr))^2]
  double Flux(double radiance) const { return (quadratic * radiance + gain) * radiance + offset; }
  double Slope(double radiance) const { return 2.0 * quadratic * radiance + gain; }
  // Inverse on the increasing branch; NaN where F has no such preimage.
  double Radiance(double flux) const;
};

// Per-scene fit diagnostics.
struct CalibrationPoint {
  double blackbody_temperature_K = 0;  // [K]
  double integration_time_s = 0;  // [s]
  double radiance = 0;  // L_k of the source [W/(m2 sr)]
  double mean_flux = 0;  // F_k, corrected, over good pixels [counts/s]
  double residual_flux = 0;  // F_k - F(L_k) [counts/s]
  double residual_K = 0;  // the residual as a temperature [K]
  double spatial_noise_K = 0;  // std over good pixels of the corrected flux [K]
};

// Counts of pixels affected by one conversion.
struct ApplyStats {
  std::size_t out_of_range = 0;  // values saturated or under range: NaN
  std::size_t replaced = 0;  // bad-pixel values replaced by neighbours
  std::size_t unreplaced = 0;  // bad-pixel values without a good neighbour: NaN
};

class ChannelCalibration {
 public:
  // From stored parts (e.g. a saved calibration). Maps are height x width,
  // row-major; bad_pixels nonzero = bad. Throws std::invalid_argument for
  // inconsistent parts.
  ChannelCalibration(SpectralResponse channel, int height, int width, std::vector<double> nuc_gain,
                     std::vector<double> nuc_offset, std::vector<std::uint8_t> bad_pixels,
                     CountsFluxCurve curve, std::vector<CalibrationPoint> points,
                     double saturation_counts, double min_valid_counts);

  const SpectralResponse& channel() const { return channel_[0]; }
  int height() const { return height_; }
  int width() const { return width_; }
  const std::vector<double>& nuc_gain() const { return gain_; }
  const std::vector<double>& nuc_offset() const { return offset_; }
  const std::vector<std::uint8_t>& bad_pixels() const { return bad_; }
  std::size_t num_bad_pixels() const;
  const CountsFluxCurve& curve() const { return curve_; }
  const std::vector<CalibrationPoint>& points() const { return points_; }
  double saturation_counts() const { return saturation_; }
  double min_valid_counts() const { return min_valid_; }
  // Root mean square of the fit residuals [K].
  double rms_residual_K() const;
  // Band radiance range of the calibration sources [W/(m2 sr)].
  double min_radiance() const;
  double max_radiance() const;

  // Raw counts of `num_frames` frames of this channel (height x width each,
  // frame j starting at raw + j * frame_stride; 0 = height x width) -> band
  // radiance [W/(m2 sr)], written with the same layout into `out` (which may
  // alias `raw`). integration_time_s: one value per frame (size num_frames) or
  // a single value for all. Out-of-range counts give NaN; bad pixels are
  // replaced by the mean of their good 3x3 neighbours (replace_bad_pixels) or
  // NaN.
  ApplyStats CountsToRadiance(const float* raw, std::size_t num_frames,
                              const std::vector<double>& integration_time_s, float* out,
                              bool replace_bad_pixels = true, std::size_t frame_stride = 0,
                              int num_threads = 0, const RunControl* control = nullptr) const;
  // The inverse for good pixels: band radiance -> the raw counts this pixel
  // reads at integration time t. Bad pixels give NaN. Same layout rules.
  void RadianceToCounts(const float* radiance, std::size_t num_frames,
                        const std::vector<double>& integration_time_s, float* out,
                        std::size_t frame_stride = 0, int num_threads = 0,
                        const RunControl* control = nullptr) const;

 private:
  std::vector<SpectralResponse> channel_;  // exactly one (no default constructor)
  int height_ = 0, width_ = 0;
  std::vector<double> gain_, offset_;
  std::vector<std::uint8_t> bad_;
  CountsFluxCurve curve_;
  std::vector<CalibrationPoint> points_;
  double saturation_ = 0, min_valid_ = 0;
};

// A camera's raw frame stack (num_frames, C, height, width), C =
// channels.size(), row-major -> band radiance, channel by channel, into `out`
// (same layout; may alias `raw`). integration_time_s: C values (one per
// channel) or num_frames x C values. Returns the summed counts.
ApplyStats CountsToRadiance(const std::vector<ChannelCalibration>& channels, const float* raw,
                            std::size_t num_frames, const std::vector<double>& integration_time_s,
                            float* out, bool replace_bad_pixels = true, int num_threads = 0,
                            const RunControl* control = nullptr);

// Fits one channel's calibration from its uniform blackbody scenes (all
// height x width). Throws std::invalid_argument naming the problem: too few
// distinct temperatures, shapes or sizes that disagree, non-positive
// integration times, non-finite counts, saturated scenes, too many bad
// pixels, a non-monotonic counts-flux relation.
ChannelCalibration FitChannelCalibration(const SpectralResponse& channel, int height, int width,
                                         const std::vector<CalibrationScene>& scenes,
                                         const CalibrationOptions& options = {},
                                         const RunControl* control = nullptr);

}  // namespace qogi
