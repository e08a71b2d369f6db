#include "engine/camera/calibration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "engine/camera/camera.h"
#include "engine/camera/radiometric_table.h"

namespace qogi {
namespace {

// A synthetic focal plane with known truth: pixel p reads
//   c = t (g_p N(L) + o_p) + noise,   N(L) = L + kappa L^2 / L_ref,
// with per-pixel gains and offsets, and a few planted bad pixels.
struct SyntheticCamera {
  int h = 24, w = 32;
  SpectralResponse channel = CameraPreset("gf320").channels[0];
  double gain = 1.5e8;    // counts/s per W/(m2 sr): 42 000 counts at 360 K, 1 ms
  double offset = 3.0e6;  // counts/s
  double kappa = 0.0;
  double l_ref = 0.26;  // ~L(360 K): kappa is the relative nonlinearity there
  double noise_counts = 0.0;  // temporal noise, counts
  std::vector<double> g, o, extra_noise;
  std::vector<int> planted;

  explicit SyntheticCamera(unsigned seed = 1) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> n01(0.0, 1.0);
    for (int p = 0; p < h * w; ++p) {
      g.push_back(gain * (1.0 + 0.05 * n01(rng)));
      o.push_back(offset * (1.0 + 0.1 * n01(rng)));
      extra_noise.push_back(0.0);
    }
  }
  std::size_t npix() const { return static_cast<std::size_t>(h) * w; }
  void PlantBadPixels() {
    g[5] = 0.0;                    // dead: no response
    g[100] = 0.5 * gain;           // weak
    extra_noise[200] = 300.0;      // noisy (counts)
    o[300] = 6.0e7;                // hot: saturates at 1 ms
    planted = {5, 100, 200, 300};
  }
  double Radiance(double t_k) const { return channel.BandRadiance(t_k); }
  std::vector<float> Frames(double radiance, double t_int, int n, unsigned seed) const {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> n01(0.0, 1.0);
    const double nl = radiance + kappa * radiance * radiance / l_ref;
    std::vector<float> out;
    for (int j = 0; j < n; ++j)
      for (std::size_t p = 0; p < npix(); ++p) {
        double c = t_int * (g[p] * nl + o[p]);
        c += (noise_counts + extra_noise[p]) * n01(rng);
        out.push_back(static_cast<float>(std::min(c, 65535.0)));
      }
    return out;
  }
};

struct Data {
  std::vector<std::vector<float>> frames;
  std::vector<CalibrationScene> scenes;
};

Data MakeScenes(const SyntheticCamera& cam, const std::vector<double>& temps,
                const std::vector<double>& t_int, int n_frames = 8) {
  Data d;
  for (std::size_t k = 0; k < temps.size(); ++k)
    d.frames.push_back(
        cam.Frames(cam.Radiance(temps[k]), t_int[k % t_int.size()], n_frames, 100 + k));
  for (std::size_t k = 0; k < temps.size(); ++k)
    d.scenes.push_back({temps[k], t_int[k % t_int.size()], d.frames[k].data(),
                        static_cast<std::size_t>(n_frames)});
  return d;
}

const std::vector<double> kTemps = {280.0, 300.0, 320.0, 340.0, 360.0};

TEST(Calibration, NoiseFreeLinearCameraIsRecoveredExactly) {
  SyntheticCamera cam;
  const Data d = MakeScenes(cam, kTemps, {1e-3});
  const ChannelCalibration cal = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes);
  EXPECT_EQ(cal.num_bad_pixels(), 0u);
  EXPECT_LT(cal.rms_residual_K(), 1e-4);
  // The curve is the mean pixel's: G = mean g, O = mean o.
  double mg = 0, mo = 0;
  for (std::size_t p = 0; p < cam.npix(); ++p) {
    mg += cam.g[p] / cam.npix();
    mo += cam.o[p] / cam.npix();
  }
  EXPECT_NEAR(cal.curve().gain / mg, 1.0, 1e-5);
  EXPECT_NEAR(cal.curve().offset / mo, 1.0, 1e-5);
  // A temperature not used in the fit, at another integration time.
  const RadiometricTable table(cam.channel, 200.0, 500.0, 128);
  for (double t_int : {1e-3, 2.5e-4}) {
    const double l = cam.Radiance(311.0);
    std::vector<float> raw = cam.Frames(l, t_int, 2, 9), out(raw.size());
    const ApplyStats st = cal.CountsToRadiance(raw.data(), 2, {t_int}, out.data());
    EXPECT_EQ(st.out_of_range + st.replaced + st.unreplaced, 0u);
    for (float v : out) {
      EXPECT_NEAR(v, l, 2e-6 * l);
      EXPECT_NEAR(table.Temperature(v), 311.0, 2e-3);
    }
    // And back to counts.
    std::vector<float> counts(raw.size());
    cal.RadianceToCounts(out.data(), 2, {t_int}, counts.data());
    for (std::size_t i = 0; i < raw.size(); ++i) EXPECT_NEAR(counts[i], raw[i], 1e-5 * raw[i]);
  }
}

TEST(Calibration, NoisyCalibrationErrorsAreWhatTheNoiseJustifies) {
  SyntheticCamera cam(2);
  cam.noise_counts = 3.0;
  const int n_frames = 8;
  const Data d = MakeScenes(cam, kTemps, {1e-3}, n_frames);
  const ChannelCalibration cal = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes);
  EXPECT_EQ(cal.num_bad_pixels(), 0u);
  // Expected per-pixel error: the NUC means carry noise/sqrt(n_frames) counts
  // at both ends; in kelvin through dcounts/dT = t g dL/dT.
  const double t_test = 320.0;
  const double counts_per_K = 1e-3 * cam.gain * cam.channel.BandRadianceDerivative(t_test);
  const double sigma_nuc_K = cam.noise_counts / std::sqrt(double(n_frames)) / counts_per_K;
  // The two-point correction interpolates the end errors with weight w.
  const double w = (cam.Radiance(t_test) - cam.Radiance(kTemps.front())) /
                   (cam.Radiance(kTemps.back()) - cam.Radiance(kTemps.front()));
  const double expected_rms = sigma_nuc_K * std::sqrt((1 - w) * (1 - w) + w * w);
  // Noise-free test frames isolate the calibration's own error.
  SyntheticCamera clean = cam;
  clean.noise_counts = 0.0;
  std::vector<float> raw = clean.Frames(clean.Radiance(t_test), 1e-3, 1, 3), out(raw.size());
  cal.CountsToRadiance(raw.data(), 1, {1e-3}, out.data());
  const RadiometricTable table(cam.channel, 200.0, 500.0, 128);
  double s = 0, s2 = 0;
  for (float v : out) {
    const double e = table.Temperature(v) - t_test;
    s += e;
    s2 += e * e;
  }
  const double n = static_cast<double>(out.size());
  const double mean = s / n, rms = std::sqrt(s2 / n);
  // 768 pixels: the rms is known to ~3 %; the pixel gains spread 5 %.
  EXPECT_NEAR(rms / expected_rms, 1.0, 0.15);
  EXPECT_LT(std::abs(mean), 5 * sigma_nuc_K / std::sqrt(n));
  // The fit residuals are of the size of the scene means' noise.
  EXPECT_LT(cal.rms_residual_K(), 5 * sigma_nuc_K / std::sqrt(n));
}

TEST(Calibration, QuadraticResponseNeedsTheQuadraticTerm) {
  SyntheticCamera cam;
  cam.kappa = 0.02;
  const Data d = MakeScenes(cam, kTemps, {1e-3});
  const ChannelCalibration lin = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes);
  CalibrationOptions opt;
  opt.quadratic = true;
  const ChannelCalibration quad = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes, opt);
  EXPECT_GT(lin.rms_residual_K(), 0.05);  // the linear model misses the curvature
  EXPECT_LT(quad.rms_residual_K(), 1e-4);
  double mg = 0;
  for (double v : cam.g) mg += v / cam.npix();
  EXPECT_NEAR(quad.curve().quadratic / (mg * cam.kappa / cam.l_ref), 1.0, 1e-4);
  const double l = cam.Radiance(333.0);
  std::vector<float> raw = cam.Frames(l, 1e-3, 1, 4), out(raw.size());
  quad.CountsToRadiance(raw.data(), 1, {1e-3}, out.data());
  for (float v : out) EXPECT_NEAR(v, l, 5e-6 * l);
}

TEST(Calibration, MixedIntegrationTimesAndAGreySource) {
  SyntheticCamera cam;
  const double eps = 0.95, t_amb = 296.0;
  CalibrationOptions opt;
  opt.blackbody_emissivity = eps;
  opt.ambient_temperature_K = t_amb;
  Data d;
  const std::vector<double> t_int = {2e-3, 1e-3, 1e-3, 5e-4, 5e-4};
  for (std::size_t k = 0; k < kTemps.size(); ++k) {
    const double l = eps * cam.Radiance(kTemps[k]) + (1 - eps) * cam.Radiance(t_amb);
    d.frames.push_back(cam.Frames(l, t_int[k], 4, 50 + k));
  }
  for (std::size_t k = 0; k < kTemps.size(); ++k)
    d.scenes.push_back({kTemps[k], t_int[k], d.frames[k].data(), 4});
  const ChannelCalibration cal = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes, opt);
  EXPECT_LT(cal.rms_residual_K(), 1e-4);
  for (const auto& p : cal.points()) EXPECT_LT(std::abs(p.spatial_noise_K), 1e-3);
  // A blackbody scene is read right; ignoring the source's emissivity would
  // misread it (a grey source is still linear in L(T), so only the scale
  // and offset betray it).
  const ChannelCalibration naive = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes);
  const RadiometricTable table(cam.channel, 200.0, 500.0, 128);
  const double l = cam.Radiance(330.0);
  std::vector<float> raw = cam.Frames(l, 1e-3, 1, 6), out(raw.size()), out_naive(raw.size());
  cal.CountsToRadiance(raw.data(), 1, {1e-3}, out.data());
  naive.CountsToRadiance(raw.data(), 1, {1e-3}, out_naive.data());
  for (std::size_t p = 0; p < raw.size(); ++p) {
    EXPECT_NEAR(table.Temperature(out[p]), 330.0, 2e-3);
    EXPECT_GT(std::abs(table.Temperature(out_naive[p]) - 330.0), 0.3);
  }
}

TEST(Calibration, BadPixelsAreFoundAndReplaced) {
  SyntheticCamera cam(3);
  cam.noise_counts = 2.0;
  cam.PlantBadPixels();
  const Data d = MakeScenes(cam, kTemps, {1e-3});
  const ChannelCalibration cal = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes);
  std::vector<int> found;
  for (std::size_t p = 0; p < cam.npix(); ++p)
    if (cal.bad_pixels()[p]) found.push_back(static_cast<int>(p));
  EXPECT_EQ(found, cam.planted);
  SyntheticCamera clean = cam;
  clean.noise_counts = 0.0;
  clean.extra_noise.assign(cam.npix(), 0.0);
  const double l = cam.Radiance(305.0);
  std::vector<float> raw = clean.Frames(l, 1e-3, 1, 5), out(raw.size());
  const ApplyStats st = cal.CountsToRadiance(raw.data(), 1, {1e-3}, out.data());
  EXPECT_EQ(st.replaced, 4u);
  // Each bad pixel reads the mean of its good 3x3 neighbours, which carry
  // the calibration's own per-pixel noise (noise / sqrt(8 frames) counts).
  const double sigma_l = cam.noise_counts / std::sqrt(8.0) / (1e-3 * cam.gain);
  for (int p : cam.planted) {
    double sum = 0;
    int n = 0;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int y = p / cam.w + dy, x = p % cam.w + dx;
        if ((dy == 0 && dx == 0) || y < 0 || x < 0 || y >= cam.h || x >= cam.w) continue;
        if (cal.bad_pixels()[y * cam.w + x]) continue;
        sum += out[y * cam.w + x];
        ++n;
      }
    EXPECT_NEAR(out[p], sum / n, 1e-6 * l);
    EXPECT_NEAR(out[p], l, 5 * sigma_l);
  }
  cal.CountsToRadiance(raw.data(), 1, {1e-3}, out.data(), /*replace_bad_pixels=*/false);
  for (int p : cam.planted) EXPECT_TRUE(std::isnan(out[p]));
  // A saturated value in use is flagged, not clamped.
  raw[7] = 65535.0f;
  const ApplyStats st2 = cal.CountsToRadiance(raw.data(), 1, {1e-3}, out.data());
  EXPECT_EQ(st2.out_of_range, 1u);
  EXPECT_TRUE(std::isnan(out[7]));
}

TEST(Calibration, ThreadCountDoesNotChangeTheResult) {
  SyntheticCamera cam(4);
  cam.noise_counts = 2.0;
  const Data d = MakeScenes(cam, kTemps, {1e-3});
  CalibrationOptions o1, o2;
  o1.num_threads = 1;
  o2.num_threads = 2;
  const ChannelCalibration a = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes, o1);
  const ChannelCalibration b = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes, o2);
  EXPECT_EQ(a.nuc_gain(), b.nuc_gain());
  EXPECT_EQ(a.curve().gain, b.curve().gain);
}

TEST(Calibration, CameraStacksAreConvertedChannelByChannel) {
  // Two channels (the gf320 filter and the fast-m150 CH4 filter), frames
  // interleaved as (T, C, H, W) with per-frame, per-channel integration times.
  SyntheticCamera a(5), b(6);
  b.channel = CameraPreset("fast-m150").channels[2];
  b.gain = 3.0e7;
  const Data da = MakeScenes(a, kTemps, {1e-3}), db = MakeScenes(b, kTemps, {1e-3});
  const std::vector<ChannelCalibration> cals = {
      FitChannelCalibration(a.channel, a.h, a.w, da.scenes),
      FitChannelCalibration(b.channel, b.h, b.w, db.scenes)};
  const std::size_t npix = a.npix();
  const std::vector<double> times = {1e-3, 2e-3, 5e-4, 1e-3};  // (frame, channel)
  std::vector<float> stack;
  for (int j = 0; j < 2; ++j) {
    const std::vector<float> fa = a.Frames(a.Radiance(300.0 + j), times[2 * j], 1, 7);
    const std::vector<float> fb = b.Frames(b.Radiance(300.0 + j), times[2 * j + 1], 1, 8);
    stack.insert(stack.end(), fa.begin(), fa.end());
    stack.insert(stack.end(), fb.begin(), fb.end());
  }
  std::vector<float> out(stack.size());
  CountsToRadiance(cals, stack.data(), 2, times, out.data());
  for (int j = 0; j < 2; ++j)
    for (std::size_t p = 0; p < npix; ++p) {
      EXPECT_NEAR(out[(2 * j) * npix + p], a.Radiance(300.0 + j), 2e-6 * a.Radiance(300.0 + j));
      EXPECT_NEAR(out[(2 * j + 1) * npix + p], b.Radiance(300.0 + j), 2e-6 * b.Radiance(300.0 + j));
    }
  // In place, with one time per channel.
  std::vector<float> f0(stack.begin(), stack.begin() + 2 * npix);
  CountsToRadiance(cals, f0.data(), 1, {times[0], times[1]}, f0.data());
  for (std::size_t i = 0; i < f0.size(); ++i) EXPECT_EQ(f0[i], out[i]);
  EXPECT_THROW(CountsToRadiance(cals, stack.data(), 2, {1e-3, 1e-3, 1e-3}, out.data()),
               std::invalid_argument);
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Calibration, BadInputIsRefusedWithAClearMessage) {
  SyntheticCamera cam;
  const Data d = MakeScenes(cam, kTemps, {1e-3}, 2);
  const auto fit = [&](std::vector<CalibrationScene> s, CalibrationOptions o = {}) {
    return [=] { FitChannelCalibration(cam.channel, cam.h, cam.w, s, o); };
  };
  // Too few temperatures.
  std::vector<CalibrationScene> two = {d.scenes[0], d.scenes[4]};
  EXPECT_NE(ErrorOf(fit(two)).find("at least 3 distinct blackbody temperatures"),
            std::string::npos);
  std::vector<CalibrationScene> three = {d.scenes[0], d.scenes[2], d.scenes[4]};
  CalibrationOptions quad;
  quad.quadratic = true;
  EXPECT_NE(ErrorOf(fit(three, quad)).find("at least 4"), std::string::npos);
  // Same temperature twice does not count twice.
  std::vector<CalibrationScene> dup = {d.scenes[0], d.scenes[0], d.scenes[4]};
  EXPECT_NE(ErrorOf(fit(dup)).find("got 2"), std::string::npos);
  // Frames labelled with the wrong temperatures: not monotonic.
  std::vector<CalibrationScene> swapped = d.scenes;
  std::swap(swapped[1].blackbody_temperature_K, swapped[3].blackbody_temperature_K);
  EXPECT_NE(ErrorOf(fit(swapped)).find("not monotonic"), std::string::npos);
  // Saturated.
  CalibrationOptions sat;
  sat.saturation_counts = 10000.0;
  EXPECT_NE(ErrorOf(fit(d.scenes, sat)).find("saturated"), std::string::npos);
  // Non-finite counts, non-positive integration time, empty scene.
  std::vector<float> nan_frames = d.frames[2];
  nan_frames[17] = std::nanf("");
  std::vector<CalibrationScene> with_nan = d.scenes;
  with_nan[2].frames = nan_frames.data();
  EXPECT_NE(ErrorOf(fit(with_nan)).find("non-finite"), std::string::npos);
  std::vector<CalibrationScene> zero_t = d.scenes;
  zero_t[1].integration_time_s = 0.0;
  EXPECT_NE(ErrorOf(fit(zero_t)).find("integration_time_s"), std::string::npos);
  std::vector<CalibrationScene> empty = d.scenes;
  empty[1].num_frames = 0;
  EXPECT_NE(ErrorOf(fit(empty)).find("no frames"), std::string::npos);
  // A grey source needs its surroundings.
  CalibrationOptions grey;
  grey.blackbody_emissivity = 0.9;
  EXPECT_NE(ErrorOf(fit(d.scenes, grey)).find("ambient_temperature_K"), std::string::npos);
  // Inconsistent stored parts.
  EXPECT_THROW(ChannelCalibration(cam.channel, 2, 2, {1, 1, 1}, {0, 0, 0, 0}, {0, 0, 0, 0},
                                  {1.0, 0.0, 0.0}, {}, 65535, 0),
               std::invalid_argument);
  // Integration times that do not match the frames.
  const ChannelCalibration cal = FitChannelCalibration(cam.channel, cam.h, cam.w, d.scenes);
  std::vector<float> out(d.frames[0].size());
  EXPECT_THROW(cal.CountsToRadiance(d.frames[0].data(), 2, {1e-3, 1e-3, 1e-3}, out.data()),
               std::invalid_argument);
}

}  // namespace
}  // namespace qogi
