#include "engine/camera/calibration.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

#include "engine/util/check.h"

namespace qogi {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string SceneName(const std::vector<CalibrationScene>& scenes, std::size_t k) {
  return "calibration scene " + std::to_string(k) + " (" +
         FormatNumber(scenes[k].blackbody_temperature_K) + " K, " +
         FormatNumber(scenes[k].integration_time_s) + " s)";
}

std::string Percent(double fraction) { return FormatNumber(100.0 * fraction) + " %"; }

double Median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + m, v.end());
  double med = v[m];
  if (v.size() % 2 == 0) med = 0.5 * (med + *std::max_element(v.begin(), v.begin() + m));
  return med;
}

// Per-pixel temporal statistics of one scene.
struct SceneStats {
  std::vector<double> mean_counts, std_counts;
  std::vector<std::uint8_t> saturated, under;  // any frame out of range
  std::size_t num_saturated = 0, num_under = 0;
};

SceneStats ComputeStats(const CalibrationScene& s, std::size_t k, std::size_t npix,
                        const CalibrationOptions& opt, const RunControl* control) {
  SceneStats st;
  st.mean_counts.assign(npix, 0.0);
  st.std_counts.assign(npix, 0.0);
  st.saturated.assign(npix, 0);
  st.under.assign(npix, 0);
  const std::size_t nf = s.num_frames;
  ParallelFor(
      npix, 4096,
      [&](std::size_t b, std::size_t e) {
        const std::size_t n = e - b;
        // Branch-free accumulation (shifted by the first frame against
        // cancellation); a non-finite count shows up in the sums.
        std::vector<double> shift(n), sum(n, 0.0), sum2(n, 0.0);
        std::vector<float> lo(n), hi(n);
        for (std::size_t i = 0; i < n; ++i) {
          shift[i] = s.frames[b + i];
          lo[i] = hi[i] = s.frames[b + i];
        }
        for (std::size_t j = 0; j < nf; ++j) {
          const float* row = s.frames + j * npix + b;
          for (std::size_t i = 0; i < n; ++i) {
            const double d = row[i] - shift[i];
            sum[i] += d;
            sum2[i] += d * d;
            lo[i] = std::min(lo[i], row[i]);
            hi[i] = std::max(hi[i], row[i]);
          }
        }
        for (std::size_t i = 0; i < n; ++i) {
          if (!std::isfinite(sum2[i])) {
            for (std::size_t j = 0; j < nf; ++j) {
              const float c = s.frames[j * npix + b + i];
              if (!std::isfinite(c))
                throw std::invalid_argument("calibration scene " + std::to_string(k) + ": frame " +
                                            std::to_string(j) +
                                            " has a non-finite count at pixel " +
                                            std::to_string(b + i) + "; got " + FormatNumber(c));
            }
          }
          const std::size_t p = b + i;
          st.saturated[p] = hi[i] >= opt.saturation_counts;
          st.under[p] = lo[i] <= opt.min_valid_counts;
          const double m = sum[i] / nf;
          st.mean_counts[p] = shift[i] + m;
          st.std_counts[p] =
              nf > 1 ? std::sqrt(std::max(0.0, (sum2[i] - nf * m * m) / (nf - 1))) : 0.0;
        }
      },
      opt.num_threads, control);
  for (std::size_t p = 0; p < npix; ++p) {
    st.num_saturated += st.saturated[p];
    st.num_under += st.under[p];
  }
  return st;
}

// Least squares F = p0 + p1 x + p2 x^2 (p2 only if quadratic) by normal
// equations on a centred, scaled abscissa. Returns p in the caller's x.
void FitPolynomial(const std::vector<double>& x, const std::vector<double>& y, bool quadratic,
                   double* p0, double* p1, double* p2) {
  const std::size_t n = x.size(), m = quadratic ? 3 : 2;
  const double xc = std::accumulate(x.begin(), x.end(), 0.0) / n;
  double xs = 0;
  for (double v : x) xs = std::max(xs, std::abs(v - xc));
  if (xs == 0) xs = 1;
  double a[3][4] = {{0}};
  for (std::size_t i = 0; i < n; ++i) {
    const double z = (x[i] - xc) / xs;
    const double phi[3] = {1.0, z, z * z};
    for (std::size_t r = 0; r < m; ++r) {
      for (std::size_t c = 0; c < m; ++c) a[r][c] += phi[r] * phi[c];
      a[r][3] += phi[r] * y[i];
    }
  }
  // Gaussian elimination with partial pivoting on the m x m system.
  for (std::size_t c = 0; c < m; ++c) {
    std::size_t piv = c;
    for (std::size_t r = c + 1; r < m; ++r)
      if (std::abs(a[r][c]) > std::abs(a[piv][c])) piv = r;
    for (std::size_t k = 0; k < 4; ++k) std::swap(a[c][k], a[piv][k]);
    Require(a[c][c] != 0, "counts-flux fit is singular (the calibration radiances coincide)");
    for (std::size_t r = c + 1; r < m; ++r) {
      const double f = a[r][c] / a[c][c];
      for (std::size_t k = c; k < 4; ++k) a[r][k] -= f * a[c][k];
    }
  }
  double q[3] = {0, 0, 0};
  for (std::size_t c = m; c-- > 0;) {
    double s = a[c][3];
    for (std::size_t k = c + 1; k < m; ++k) s -= a[c][k] * q[k];
    q[c] = s / a[c][c];
  }
  // F = q0 + q1 z + q2 z^2 with z = (x - xc) / xs.
  const double c1 = q[1] / xs, c2 = q[2] / (xs * xs);
  *p2 = c2;
  *p1 = c1 - 2.0 * c2 * xc;
  *p0 = q[0] - c1 * xc + c2 * xc * xc;
}

}  // namespace

void CalibrationOptions::Check() const {
  Require(std::isfinite(saturation_counts) && std::isfinite(min_valid_counts) &&
              saturation_counts > min_valid_counts,
          "saturation_counts must be finite and above min_valid_counts; got " +
              FormatNumber(saturation_counts) + " and " + FormatNumber(min_valid_counts));
  Require(
      std::isfinite(bad_response_tolerance) && bad_response_tolerance > 0 &&
          bad_response_tolerance < 1,
      "bad_response_tolerance must be within (0, 1); got " + FormatNumber(bad_response_tolerance));
  Require(std::isfinite(bad_noise_factor) && bad_noise_factor >= 1,
          "bad_noise_factor must be finite and >= 1; got " + FormatNumber(bad_noise_factor));
  Require(std::isfinite(max_bad_fraction) && max_bad_fraction >= 0 && max_bad_fraction < 1,
          "max_bad_fraction must be within [0, 1); got " + FormatNumber(max_bad_fraction));
  Require(nuc_cold_scene >= -1 && nuc_hot_scene >= -1,
          "nuc_cold_scene and nuc_hot_scene must be scene indices or -1 (automatic); got " +
              std::to_string(nuc_cold_scene) + " and " + std::to_string(nuc_hot_scene));
  Require(
      std::isfinite(blackbody_emissivity) && blackbody_emissivity > 0 && blackbody_emissivity <= 1,
      "blackbody_emissivity must be within (0, 1]; got " + FormatNumber(blackbody_emissivity));
  CheckNonNegative(ambient_temperature_K, "ambient_temperature_K", "K");
  Require(blackbody_emissivity == 1.0 || ambient_temperature_K > 0,
          "ambient_temperature_K must be given (> 0 K) when blackbody_emissivity < 1: the "
          "source reflects its surroundings; got " +
              FormatNumber(ambient_temperature_K));
  Require(num_threads >= 0,
          "num_threads must be >= 0 (0 = all cores); got " + std::to_string(num_threads));
}

double CountsFluxCurve::Radiance(double flux) const {
  const double d = flux - offset;
  if (quadratic == 0.0) return d / gain;
  const double disc = gain * gain + 4.0 * quadratic * d;
  if (!(disc >= 0)) return kNaN;
  return 2.0 * d / (gain + std::sqrt(disc));
}

ChannelCalibration::ChannelCalibration(SpectralResponse channel, int height, int width,
                                       std::vector<double> nuc_gain, std::vector<double> nuc_offset,
                                       std::vector<std::uint8_t> bad_pixels, CountsFluxCurve curve,
                                       std::vector<CalibrationPoint> points,
                                       double saturation_counts, double min_valid_counts)
    : height_(height),
      width_(width),
      gain_(std::move(nuc_gain)),
      offset_(std::move(nuc_offset)),
      bad_(std::move(bad_pixels)),
      curve_(curve),
      points_(std::move(points)),
      saturation_(saturation_counts),
      min_valid_(min_valid_counts) {
  channel_.push_back(std::move(channel));
  Require(height > 0 && width > 0, "calibration frame size must be positive; got " +
                                       std::to_string(height) + "x" + std::to_string(width));
  const std::size_t npix = static_cast<std::size_t>(height) * width;
  CheckSameLength(gain_.size(), npix, "nuc_gain", "height x width");
  CheckSameLength(offset_.size(), npix, "nuc_offset", "height x width");
  CheckSameLength(bad_.size(), npix, "bad_pixels", "height x width");
  for (std::size_t p = 0; p < npix; ++p) {
    if (bad_[p]) continue;
    Require(std::isfinite(gain_[p]) && gain_[p] > 0 && std::isfinite(offset_[p]),
            "nuc_gain must be finite and > 0 and nuc_offset finite at good pixels; pixel " +
                std::to_string(p) + " has " + FormatNumber(gain_[p]) + " and " +
                FormatNumber(offset_[p]));
  }
  Require(std::isfinite(curve_.gain) && std::isfinite(curve_.offset) &&
              std::isfinite(curve_.quadratic) && curve_.gain > 0,
          "counts-flux curve gain must be finite and > 0; got G = " + FormatNumber(curve_.gain) +
              ", O = " + FormatNumber(curve_.offset) + ", Q = " + FormatNumber(curve_.quadratic));
  Require(std::isfinite(saturation_) && std::isfinite(min_valid_) && saturation_ > min_valid_,
          "saturation_counts must be finite and above min_valid_counts; got " +
              FormatNumber(saturation_) + " and " + FormatNumber(min_valid_));
  if (!points_.empty())
    Require(curve_.Slope(min_radiance()) > 0 && curve_.Slope(max_radiance()) > 0,
            "counts-flux curve must increase over the calibrated radiances " +
                FormatNumber(min_radiance()) + "-" + FormatNumber(max_radiance()) + " W/(m2 sr)");
}

std::size_t ChannelCalibration::num_bad_pixels() const {
  return static_cast<std::size_t>(
      std::count_if(bad_.begin(), bad_.end(), [](std::uint8_t b) { return b != 0; }));
}

double ChannelCalibration::rms_residual_K() const {
  if (points_.empty()) return kNaN;
  double s = 0;
  for (const auto& p : points_) s += p.residual_K * p.residual_K;
  return std::sqrt(s / points_.size());
}

double ChannelCalibration::min_radiance() const {
  double v = kNaN;
  for (const auto& p : points_) v = std::isnan(v) ? p.radiance : std::min(v, p.radiance);
  return v;
}

double ChannelCalibration::max_radiance() const {
  double v = kNaN;
  for (const auto& p : points_) v = std::isnan(v) ? p.radiance : std::max(v, p.radiance);
  return v;
}

namespace {
std::vector<double> FrameTimes(const std::vector<double>& t, std::size_t num_frames) {
  Require(t.size() == 1 || t.size() == num_frames,
          "integration_time_s must have one value or one per frame (" + std::to_string(num_frames) +
              "); got " + std::to_string(t.size()));
  for (std::size_t j = 0; j < t.size(); ++j)
    Require(std::isfinite(t[j]) && t[j] > 0,
            "integration_time_s must be finite and > 0 s; integration_time_s[" + std::to_string(j) +
                "] = " + FormatNumber(t[j]));
  return t.size() == 1 ? std::vector<double>(num_frames, t[0]) : t;
}
}  // namespace

ApplyStats ChannelCalibration::CountsToRadiance(const float* raw, std::size_t num_frames,
                                                const std::vector<double>& integration_time_s,
                                                float* out, bool replace_bad_pixels,
                                                std::size_t frame_stride, int num_threads,
                                                const RunControl* control) const {
  const std::vector<double> times = FrameTimes(integration_time_s, num_frames);
  const std::size_t h = height_, w = width_, npix = h * w;
  const std::size_t stride = frame_stride == 0 ? npix : frame_stride;
  Require(stride >= npix, "frame_stride must be >= height x width (" + std::to_string(npix) +
                              "); got " + std::to_string(stride));
  std::atomic<std::size_t> out_of_range{0}, replaced{0}, unreplaced{0};
  std::vector<std::size_t> bad_list;
  for (std::size_t p = 0; p < npix; ++p)
    if (bad_[p]) bad_list.push_back(p);
  // Rows of all frames, then bad pixels frame by frame (they read good
  // neighbours' radiances written by the first pass).
  ParallelFor(
      num_frames * h, 8,
      [&](std::size_t b, std::size_t e) {
        std::size_t local = 0;
        for (std::size_t r = b; r < e; ++r) {
          const std::size_t j = r / h;
          const double inv_t = 1.0 / times[j];
          const std::size_t pix0 = (r % h) * w, base = j * stride + pix0;
          for (std::size_t x = 0; x < w; ++x) {
            const std::size_t p = pix0 + x;
            if (bad_[p]) continue;
            const double c = raw[base + x];
            if (!(c < saturation_ && c > min_valid_)) {
              out[base + x] = std::numeric_limits<float>::quiet_NaN();
              ++local;
              continue;
            }
            out[base + x] = static_cast<float>(curve_.Radiance(gain_[p] * c * inv_t + offset_[p]));
          }
        }
        out_of_range += local;
      },
      num_threads, control);
  if (bad_list.empty()) return {out_of_range.load(), 0, 0};
  ParallelFor(
      num_frames, 1,
      [&](std::size_t b, std::size_t e) {
        std::size_t rep = 0, unrep = 0;
        for (std::size_t j = b; j < e; ++j) {
          float* frame = out + j * stride;
          for (std::size_t p : bad_list) {
            if (!replace_bad_pixels) {
              frame[p] = std::numeric_limits<float>::quiet_NaN();
              ++unrep;
              continue;
            }
            const std::ptrdiff_t y = p / w, x = p % w;
            double sum = 0;
            int n = 0;
            for (std::ptrdiff_t dy = -1; dy <= 1; ++dy)
              for (std::ptrdiff_t dx = -1; dx <= 1; ++dx) {
                const std::ptrdiff_t yy = y + dy, xx = x + dx;
                if ((dy == 0 && dx == 0) || yy < 0 || xx < 0 ||
                    yy >= static_cast<std::ptrdiff_t>(h) || xx >= static_cast<std::ptrdiff_t>(w))
                  continue;
                const std::size_t q = yy * w + xx;
                if (bad_[q] || !std::isfinite(frame[q])) continue;
                sum += frame[q];
                ++n;
              }
            if (n > 0) {
              frame[p] = static_cast<float>(sum / n);
              ++rep;
            } else {
              frame[p] = std::numeric_limits<float>::quiet_NaN();
              ++unrep;
            }
          }
        }
        replaced += rep;
        unreplaced += unrep;
      },
      num_threads, control);
  return {out_of_range.load(), replaced.load(), unreplaced.load()};
}

void ChannelCalibration::RadianceToCounts(const float* radiance, std::size_t num_frames,
                                          const std::vector<double>& integration_time_s, float* out,
                                          std::size_t frame_stride, int num_threads,
                                          const RunControl* control) const {
  const std::vector<double> times = FrameTimes(integration_time_s, num_frames);
  const std::size_t npix = static_cast<std::size_t>(height_) * width_;
  const std::size_t stride = frame_stride == 0 ? npix : frame_stride;
  Require(stride >= npix, "frame_stride must be >= height x width (" + std::to_string(npix) +
                              "); got " + std::to_string(stride));
  ParallelFor(
      num_frames * npix, 16384,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t k = b; k < e; ++k) {
          const std::size_t j = k / npix, p = k % npix, i = j * stride + p;
          if (bad_[p]) {
            out[i] = std::numeric_limits<float>::quiet_NaN();
            continue;
          }
          const double f = (curve_.Flux(radiance[i]) - offset_[p]) / gain_[p];
          out[i] = static_cast<float>(f * times[j]);
        }
      },
      num_threads, control);
}

ApplyStats CountsToRadiance(const std::vector<ChannelCalibration>& channels, const float* raw,
                            std::size_t num_frames, const std::vector<double>& integration_time_s,
                            float* out, bool replace_bad_pixels, int num_threads,
                            const RunControl* control) {
  Require(!channels.empty(), "CountsToRadiance needs at least one channel calibration");
  const std::size_t nc = channels.size();
  const std::size_t npix = static_cast<std::size_t>(channels[0].height()) * channels[0].width();
  for (std::size_t c = 1; c < nc; ++c)
    Require(
        channels[c].height() == channels[0].height() && channels[c].width() == channels[0].width(),
        "channel calibrations must share one frame size; channel " + std::to_string(c) + " is " +
            std::to_string(channels[c].height()) + "x" + std::to_string(channels[c].width()) +
            ", channel 0 " + std::to_string(channels[0].height()) + "x" +
            std::to_string(channels[0].width()));
  Require(integration_time_s.size() == nc || integration_time_s.size() == num_frames * nc,
          "integration_time_s must have one value per channel (" + std::to_string(nc) +
              ") or per frame and channel (" + std::to_string(num_frames * nc) + "); got " +
              std::to_string(integration_time_s.size()));
  ApplyStats total;
  for (std::size_t c = 0; c < nc; ++c) {
    std::vector<double> times;
    if (integration_time_s.size() == nc) {
      times = {integration_time_s[c]};
    } else {
      for (std::size_t j = 0; j < num_frames; ++j) times.push_back(integration_time_s[j * nc + c]);
    }
    const ApplyStats s =
        channels[c].CountsToRadiance(raw + c * npix, num_frames, times, out + c * npix,
                                     replace_bad_pixels, nc * npix, num_threads, control);
    total.out_of_range += s.out_of_range;
    total.replaced += s.replaced;
    total.unreplaced += s.unreplaced;
  }
  return total;
}

ChannelCalibration FitChannelCalibration(const SpectralResponse& channel, int height, int width,
                                         const std::vector<CalibrationScene>& scenes,
                                         const CalibrationOptions& opt, const RunControl* control) {
  opt.Check();
  Require(height > 0 && width > 0, "calibration frame size must be positive; got " +
                                       std::to_string(height) + "x" + std::to_string(width));
  const std::size_t npix = static_cast<std::size_t>(height) * width;
  const std::size_t ns = scenes.size();
  const std::size_t num_params = opt.quadratic ? 3 : 2;
  for (std::size_t k = 0; k < ns; ++k) {
    const CalibrationScene& s = scenes[k];
    CheckPositive(s.blackbody_temperature_K,
                  ("scenes[" + std::to_string(k) + "].blackbody_temperature_K").c_str(), "K");
    CheckPositive(s.integration_time_s,
                  ("scenes[" + std::to_string(k) + "].integration_time_s").c_str(), "s");
    Require(s.frames != nullptr && s.num_frames > 0,
            "calibration scene " + std::to_string(k) + " has no frames");
  }
  // Distinct temperatures (the fit needs one more than it has parameters).
  std::vector<double> temps;
  for (const auto& s : scenes) temps.push_back(s.blackbody_temperature_K);
  std::sort(temps.begin(), temps.end());
  temps.erase(std::unique(temps.begin(), temps.end(),
                          [](double a, double b) { return std::abs(a - b) <= 1e-9 * b; }),
              temps.end());
  if (temps.size() < num_params + 1) {
    std::string list;
    for (double t : temps) list += (list.empty() ? "" : ", ") + FormatNumber(t) + " K";
    throw std::invalid_argument(
        "calibration needs at least " + std::to_string(num_params + 1) +
        " distinct blackbody temperatures for a " + (opt.quadratic ? "quadratic" : "linear") +
        " counts-flux fit (" + std::to_string(num_params) +
        " parameters + 1 to measure residuals); got " + std::to_string(temps.size()) +
        (list.empty() ? "" : " (" + list + ")"));
  }
  // NUC scenes.
  std::size_t cold = 0, hot = 0;
  for (std::size_t k = 1; k < ns; ++k) {
    if (scenes[k].blackbody_temperature_K < scenes[cold].blackbody_temperature_K) cold = k;
    if (scenes[k].blackbody_temperature_K > scenes[hot].blackbody_temperature_K) hot = k;
  }
  if (opt.nuc_cold_scene >= 0) cold = opt.nuc_cold_scene;
  if (opt.nuc_hot_scene >= 0) hot = opt.nuc_hot_scene;
  Require(cold < ns && hot < ns, "nuc_cold_scene and nuc_hot_scene must index the " +
                                     std::to_string(ns) + " scenes; got " +
                                     std::to_string(opt.nuc_cold_scene) + " and " +
                                     std::to_string(opt.nuc_hot_scene));
  Require(scenes[hot].blackbody_temperature_K > scenes[cold].blackbody_temperature_K,
          "the hot NUC scene must be warmer than the cold one; got " + SceneName(scenes, hot) +
              " and " + SceneName(scenes, cold));

  // Per-pixel statistics and out-of-range checks.
  std::vector<SceneStats> stats;
  std::vector<std::uint8_t> out_of_range(npix, 0);
  for (std::size_t k = 0; k < ns; ++k) {
    stats.push_back(ComputeStats(scenes[k], k, npix, opt, control));
    const SceneStats& st = stats.back();
    const double fs = static_cast<double>(st.num_saturated) / npix;
    const double fu = static_cast<double>(st.num_under) / npix;
    Require(fs <= opt.max_bad_fraction,
            SceneName(scenes, k) + " is saturated: " + Percent(fs) +
                " of pixels reach saturation_counts = " + FormatNumber(opt.saturation_counts) +
                " (at most " + Percent(opt.max_bad_fraction) +
                " may); lower the integration time or the blackbody temperature, or set "
                "saturation_counts to the camera's full scale");
    Require(fu <= opt.max_bad_fraction,
            SceneName(scenes, k) + " is under range: " + Percent(fu) +
                " of pixels read <= min_valid_counts = " + FormatNumber(opt.min_valid_counts) +
                " (at most " + Percent(opt.max_bad_fraction) +
                " may); check the frames and min_valid_counts");
    for (std::size_t p = 0; p < npix; ++p)
      out_of_range[p] |= static_cast<std::uint8_t>(st.saturated[p] | st.under[p]);
  }
  auto flux = [&](std::size_t k, std::size_t p) {
    return stats[k].mean_counts[p] / scenes[k].integration_time_s;
  };

  // Bad pixels: out of range, off responsivity, noisy.
  std::vector<std::uint8_t> bad = out_of_range;
  std::vector<double> resp(npix), noise(npix);
  std::vector<double> resp_ok, noise_ok;
  for (std::size_t p = 0; p < npix; ++p) {
    resp[p] = flux(hot, p) - flux(cold, p);
    noise[p] = std::max(stats[hot].std_counts[p] / scenes[hot].integration_time_s,
                        stats[cold].std_counts[p] / scenes[cold].integration_time_s);
    if (!out_of_range[p]) {
      resp_ok.push_back(resp[p]);
      noise_ok.push_back(noise[p]);
    }
  }
  Require(!resp_ok.empty(), "every pixel is out of range in some calibration scene");
  const double med_resp = Median(resp_ok);
  Require(med_resp > 0, "the hot NUC " + SceneName(scenes, hot) +
                            " does not read more counts/s than the "
                            "cold NUC " +
                            SceneName(scenes, cold) + " (median responsivity " +
                            FormatNumber(med_resp) +
                            " counts/s); check the blackbody temperatures and the scene order");
  const bool noise_test = scenes[hot].num_frames > 1 && scenes[cold].num_frames > 1;
  const double med_noise = noise_test ? Median(noise_ok) : 0.0;
  std::size_t n_resp = 0, n_noise = 0, n_range = 0;
  for (std::size_t p = 0; p < npix; ++p) {
    if (out_of_range[p]) {
      ++n_range;
      continue;
    }
    if (!(std::abs(resp[p] / med_resp - 1.0) <= opt.bad_response_tolerance)) {
      bad[p] = 1;
      ++n_resp;
    } else if (med_noise > 0 && noise[p] > opt.bad_noise_factor * med_noise) {
      bad[p] = 1;
      ++n_noise;
    }
  }
  const std::size_t n_bad = n_resp + n_noise + n_range;
  Require(static_cast<double>(n_bad) <= opt.max_bad_fraction * npix,
          "too many bad pixels: " + std::to_string(n_bad) + " of " + std::to_string(npix) + " (" +
              Percent(static_cast<double>(n_bad) / npix) + "; at most " +
              Percent(opt.max_bad_fraction) + "): " + std::to_string(n_resp) +
              " with responsivity off the median by > " + Percent(opt.bad_response_tolerance) +
              ", " + std::to_string(n_noise) + " with temporal noise > " +
              FormatNumber(opt.bad_noise_factor) + " x the median, " + std::to_string(n_range) +
              " out of range; check the NUC scenes are uniform and unsaturated");

  // Two-point NUC onto the mean good pixel.
  double m1 = 0, m2 = 0;
  std::size_t n_good = 0;
  for (std::size_t p = 0; p < npix; ++p) {
    if (bad[p]) continue;
    m1 += flux(cold, p);
    m2 += flux(hot, p);
    ++n_good;
  }
  m1 /= n_good;
  m2 /= n_good;
  std::vector<double> gain(npix, 0.0), offset(npix, 0.0);
  for (std::size_t p = 0; p < npix; ++p) {
    if (bad[p]) continue;
    gain[p] = (m2 - m1) / resp[p];
    offset[p] = m1 - gain[p] * flux(cold, p);
  }

  // Corrected array-mean flux and residual fixed pattern of each scene.
  std::vector<double> mean_flux(ns), spread(ns), radiance(ns), slope_t(ns);
  const double eps = opt.blackbody_emissivity;
  const double l_amb = (eps < 1.0 && opt.ambient_temperature_K > 0)
                           ? channel.BandRadiance(opt.ambient_temperature_K)
                           : 0.0;
  for (std::size_t k = 0; k < ns; ++k) {
    double s = 0, s2 = 0;
    for (std::size_t p = 0; p < npix; ++p) {
      if (bad[p]) continue;
      const double f = gain[p] * flux(k, p) + offset[p];
      s += f;
      s2 += f * f;
    }
    mean_flux[k] = s / n_good;
    spread[k] = std::sqrt(std::max(0.0, s2 / n_good - mean_flux[k] * mean_flux[k]));
    const double t = scenes[k].blackbody_temperature_K;
    radiance[k] = eps * channel.BandRadiance(t) + (1.0 - eps) * l_amb;
    slope_t[k] = eps * channel.BandRadianceDerivative(t);  // dL_k/dT_k
  }

  // Monotonic: a warmer source must read more counts/s.
  std::vector<std::size_t> order(ns);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return radiance[a] < radiance[b]; });
  for (std::size_t i = 1; i < ns; ++i) {
    const std::size_t lo = order[i - 1], hi = order[i];
    if (radiance[hi] <= radiance[lo] * (1.0 + 1e-12)) continue;  // same temperature
    Require(mean_flux[hi] > mean_flux[lo],
            "counts-flux data are not monotonic: " + SceneName(scenes, hi) + " reads " +
                FormatNumber(mean_flux[hi]) + " counts/s, not more than " + SceneName(scenes, lo) +
                " with " + FormatNumber(mean_flux[lo]) +
                " counts/s; check the blackbody temperatures, integration times and "
                "saturation");
  }

  CountsFluxCurve curve;
  FitPolynomial(radiance, mean_flux, opt.quadratic, &curve.offset, &curve.gain, &curve.quadratic);
  const double l_lo = radiance[order.front()], l_hi = radiance[order.back()];
  Require(curve.Slope(l_lo) > 0 && curve.Slope(l_hi) > 0,
          "the fitted counts-flux curve does not increase over the calibrated radiances " +
              FormatNumber(l_lo) + "-" + FormatNumber(l_hi) + " W/(m2 sr) (G = " +
              FormatNumber(curve.gain) + ", Q = " + FormatNumber(curve.quadratic) +
              "); use the linear fit or add calibration temperatures");

  std::vector<CalibrationPoint> points(ns);
  for (std::size_t k = 0; k < ns; ++k) {
    CalibrationPoint& pt = points[k];
    pt.blackbody_temperature_K = scenes[k].blackbody_temperature_K;
    pt.integration_time_s = scenes[k].integration_time_s;
    pt.radiance = radiance[k];
    pt.mean_flux = mean_flux[k];
    pt.residual_flux = mean_flux[k] - curve.Flux(radiance[k]);
    const double df_dt = curve.Slope(radiance[k]) * slope_t[k];
    pt.residual_K = pt.residual_flux / df_dt;
    pt.spatial_noise_K = spread[k] / df_dt;
  }
  return ChannelCalibration(channel, height, width, std::move(gain), std::move(offset),
                            std::move(bad), curve, std::move(points), opt.saturation_counts,
                            opt.min_valid_counts);
}

}  // namespace qogi
