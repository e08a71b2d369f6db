#include "engine/camera/noise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "engine/camera/camera.h"
#include "engine/camera/radiometric_table.h"

namespace qogi {
namespace {

// dL/dT by central differences of the exact band radiance (independent of
// the analytic derivative the noise model uses).
double Slope(const SpectralResponse& ch, double t) {
  const double h = 0.01;
  return (ch.BandRadiance(t + h) - ch.BandRadiance(t - h)) / (2 * h);
}

TEST(NetdNoise, SigmaIsNetdTimesTheBandSlope) {
  const CameraModel cam = CameraPreset("fast-m150");
  for (const auto& ch : cam.channels)
    for (double t : {260.0, 288.15, 330.0})
      EXPECT_NEAR(NetdRadianceSigma(ch, 0.017, t), 0.017 * Slope(ch, t),
                  1e-7 * 0.017 * Slope(ch, t));
  EXPECT_THROW(NetdRadianceSigma(cam.channels[0], 0.0, 300.0), std::invalid_argument);
  EXPECT_THROW(NetdRadianceSigma(cam.channels[0], 0.017, -1.0), std::invalid_argument);
}

// A uniform scene at the background temperature, noised, converted back to
// radiometric temperature: its standard deviation is the NETD.
TEST(NetdNoise, MeasuredTemperatureNoiseIsTheNetd) {
  const CameraModel cam = CameraPreset("fast-m150");
  const double t_bg = 288.15, netd = cam.netd_K;
  const std::size_t npix = 1 << 20;  // 1 048 576 draws per channel
  std::vector<double> sigma;
  std::vector<float> frames;
  for (const auto& ch : cam.channels) {
    sigma.push_back(NetdRadianceSigma(ch, netd, t_bg));
    frames.insert(frames.end(), npix, static_cast<float>(ch.BandRadiance(t_bg)));
  }
  AddGaussianNoise(frames.data(), 1, npix, sigma, 20220101);
  for (std::size_t c = 0; c < cam.channels.size(); ++c) {
    const RadiometricTable table(cam.channels[c], 250.0, 330.0, 256);
    double s = 0, s2 = 0, within1 = 0, within2 = 0;
    for (std::size_t i = 0; i < npix; ++i) {
      const double d = table.Temperature(frames[c * npix + i]) - t_bg;
      s += d;
      s2 += d * d;
      within1 += std::abs(d) < netd;
      within2 += std::abs(d) < 2 * netd;
    }
    const double n = static_cast<double>(npix);
    const double mean = s / n, sd = std::sqrt(s2 / n - mean * mean);
    // Standard errors: mean sigma/sqrt(n); std sigma/sqrt(2n); a fraction
    // sqrt(p(1-p)/n). 5 standard errors.
    EXPECT_NEAR(mean, 0.0, 5 * netd / std::sqrt(n)) << cam.channels[c].name();
    EXPECT_NEAR(sd / netd, 1.0, 5 / std::sqrt(2 * n)) << cam.channels[c].name();
    const double p1 = 0.6826894921370859, p2 = 0.9544997361036416;
    EXPECT_NEAR(within1 / n, p1, 5 * std::sqrt(p1 * (1 - p1) / n));
    EXPECT_NEAR(within2 / n, p2, 5 * std::sqrt(p2 * (1 - p2) / n));
  }
}

TEST(NetdNoise, ReproducibleAcrossThreadsAndSplitCalls) {
  const std::size_t frames_n = 3, npix = 10007;
  const std::vector<double> sigma = {1.0, 2.0};
  const std::size_t n = frames_n * sigma.size() * npix;
  std::vector<float> a(n, 0.0f), b(n, 0.0f), c(n, 0.0f), d(n, 0.0f);
  AddGaussianNoise(a.data(), frames_n, npix, sigma, 7, 0, 1);
  AddGaussianNoise(b.data(), frames_n, npix, sigma, 7, 0, 2);
  EXPECT_EQ(a, b);
  // Frame by frame, with the stream offset, from an odd split point too.
  const std::size_t per_frame = sigma.size() * npix;
  for (std::size_t f = 0; f < frames_n; ++f)
    AddGaussianNoise(c.data() + f * per_frame, 1, npix, sigma, 7, f * per_frame);
  EXPECT_EQ(a, c);
  // Draw by draw through the public stream.
  for (std::size_t i = 0; i < n; i += 997) {
    const double s = sigma[(i / npix) % sigma.size()];
    EXPECT_EQ(a[i], static_cast<float>(s * StandardNormalDraw(7, i)));
  }
  // Another seed: uncorrelated.
  AddGaussianNoise(d.data(), frames_n, npix, sigma, 8);
  double sab = 0, saa = 0, sbb = 0, lag = 0;
  for (std::size_t i = 0; i < n; ++i) {
    sab += a[i] * d[i];
    saa += a[i] * a[i];
    sbb += d[i] * d[i];
    if (i + 1 < n) lag += a[i] * a[i + 1];
  }
  EXPECT_LT(std::abs(sab / std::sqrt(saa * sbb)), 5 / std::sqrt(double(n)));
  EXPECT_LT(std::abs(lag / saa), 5 / std::sqrt(double(n)));  // neighbours independent
  // Channel c gets sigma[c].
  double s0 = 0, s1 = 0;
  for (std::size_t f = 0; f < frames_n; ++f)
    for (std::size_t p = 0; p < npix; ++p) {
      s0 += std::pow(a[f * per_frame + p], 2);
      s1 += std::pow(a[f * per_frame + npix + p], 2);
    }
  EXPECT_NEAR(std::sqrt(s1 / s0), 2.0, 0.06);  // ~5 standard errors
}

TEST(NetdNoise, RejectsBadSigmas) {
  std::vector<float> f(10, 0.0f);
  EXPECT_THROW(AddGaussianNoise(f.data(), 1, 10, {}, 1), std::invalid_argument);
  EXPECT_THROW(AddGaussianNoise(f.data(), 1, 10, {-1.0}, 1), std::invalid_argument);
  EXPECT_THROW(AddGaussianNoise(f.data(), 1, 10, {std::nan("")}, 1), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
