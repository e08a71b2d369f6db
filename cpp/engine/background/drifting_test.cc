// A drifting layer (clouds) over a static textured layer, with noise and a
// fast plume: the drift's velocity and the background recovered to within
// what the noise allows.
#include "engine/background/drifting.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace qogi {
namespace {

// A smooth random field (plane waves of periods 20-60 px), evaluated exactly
// at any point: the clouds (in their own frame) or the static texture.
struct Field {
  std::vector<double> kx, ky, phase, amp;
  Field(unsigned seed, double period_lo, double period_hi, double size) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (int i = 0; i < 40; ++i) {
      const double period = period_lo + (period_hi - period_lo) * u(rng), dir = 2 * M_PI * u(rng);
      kx.push_back(2 * M_PI / period * std::cos(dir));
      ky.push_back(2 * M_PI / period * std::sin(dir));
      phase.push_back(2 * M_PI * u(rng));
      amp.push_back(size * (0.5 + u(rng)) / 6.0);
    }
  }
  double operator()(double x, double y) const {
    double s = 0;
    for (std::size_t i = 0; i < kx.size(); ++i)
      s += amp[i] * std::cos(kx[i] * x + ky[i] * y + phase[i]);
    return s;
  }
};

constexpr int kW = 120, kH = 90, kFrames = 90;
constexpr double kRate = 15.0, kNoise = 1.0;
constexpr double kVx = 8.0, kVy = 1.0;  // px/s

struct Scene {
  std::vector<cv::Mat> frames, truth;
  std::vector<double> times;
};

// Static: a vertical gradient and a 3-noise texture of short periods;
// drifting: a field of ~40 noise, positive parts only (broken clouds); gas:
// a band of 30 noise moving right at 20 px per frame, in a quarter of the frames'
// pixels at any time.
Scene MakeScene(unsigned seed, double vx, double vy, bool plume) {
  const Field texture(seed, 4, 10, 3.0), clouds(seed + 7, 25, 60, 40.0);
  std::mt19937 rng(seed + 11);
  std::normal_distribution<float> noise(0, static_cast<float>(kNoise));
  std::uniform_real_distribution<double> u(0, 1);
  Scene s;
  for (int i = 0; i < kFrames; ++i) {
    const double t = i / kRate;
    cv::Mat bg(kH, kW, CV_32F), f(kH, kW, CV_32F);
    const double puff = u(rng) * kW;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const double c = std::max(0.0, clouds(x - vx * t, y - vy * t));
        const double b = 0.5 * y + texture(x, y) + c;
        bg.at<float>(y, x) = static_cast<float>(b);
        double g = 0;
        if (plume && y > 35 && y < 55) {
          const double d = std::fmod(x - puff + kW, static_cast<double>(kW));
          if (d < 30) g = 30.0;
        }
        f.at<float>(y, x) = static_cast<float>(b + g) + noise(rng);
      }
    s.frames.push_back(f);
    s.truth.push_back(bg);
    s.times.push_back(t);
  }
  return s;
}

TEST(MeasureDrift, RecoversTheCloudsVelocityPastTheStaticLayerAndTheGas) {
  const Scene s = MakeScene(1, kVx, kVy, true);
  const DriftResult d = MeasureDrift(s.frames, s.times, DriftOptions{});
  ASSERT_TRUE(d.measured);
  EXPECT_NEAR(d.vx_px_s, kVx, 0.05);
  EXPECT_NEAR(d.vy_px_s, kVy, 0.05);
  EXPECT_GE(d.converged * 2, d.pairs);
}

TEST(DriftingBackground, FollowsTheCloudsThroughEachPixelAndLeavesTheGasOut) {
  const Scene s = MakeScene(2, kVx, kVy, true);
  const DriftResult d = MeasureDrift(s.frames, s.times, DriftOptions{});
  ASSERT_TRUE(d.measured);
  DriftingBackgroundOptions running;
  running.window_s = 4.0;  // 6 s of frames: a running estimate over three knots
  const DriftingBackground bg(s.frames, s.times, d.vx_px_s, d.vy_px_s, +1.0, running);
  EXPECT_GE(bg.knots(), 2);
  // Away from the borders (where the clouds enter and leave the frame, one
  // side of the window sees them), over frames spread through the run.
  double sum = 0, sum2 = 0;
  std::vector<double> abs_err;
  int n = 0;
  for (int i = 5; i < kFrames; i += 10) {
    cv::Mat b;
    bg.At(s.times[i], &b);
    for (int y = 6; y < kH - 6; ++y)
      for (int x = 10; x < kW - 10; ++x) {
        const double e = b.at<float>(y, x) - s.truth[i].at<float>(y, x);
        sum += e;
        sum2 += e * e;
        abs_err.push_back(std::abs(e));
        ++n;
      }
  }
  const double mean = sum / n, rms = std::sqrt(sum2 / n - mean * mean);
  // A low 5th percentile sits ~1.6 noise below the truth (~1.2 on bilinearly
  // sampled points); its scatter about a noise; the clouds span 40 noise and
  // the static texture 3, the gas 30.
  EXPECT_LT(mean, 0.0);
  EXPECT_GT(mean, -2.5 * kNoise);
  EXPECT_LT(rms, 1.2 * kNoise);
  std::sort(abs_err.begin(), abs_err.end());
  EXPECT_LT(abs_err[abs_err.size() * 99 / 100], 5.0 * kNoise);  // the 99th percentile
  // The same frames with the clouds held still in the background estimate
  // (v = 0, a plain running percentile): the clouds' motion within the window
  // leaves errors of their contrast.
  const DriftingBackground still(s.frames, s.times, 0.0, 0.0, +1.0, running);
  double still2 = 0;
  int m = 0;
  for (int i = 5; i < kFrames; i += 10) {
    cv::Mat b;
    still.At(s.times[i], &b);
    for (int y = 6; y < kH - 6; ++y)
      for (int x = 10; x < kW - 10; ++x, ++m) {
        const double e = b.at<float>(y, x) - s.truth[i].at<float>(y, x);
        still2 += e * e;
      }
  }
  EXPECT_GT(std::sqrt(still2 / m), 3.0 * std::sqrt(sum2 / n));
}

TEST(DriftingBackground, WithoutDriftIsTheStaticPercentile) {
  const Scene s = MakeScene(3, 0.0, 0.0, true);
  DriftingBackgroundOptions o;
  o.window_s = 100.0;  // one knot over the whole run
  const DriftingBackground bg(s.frames, s.times, 0.0, 0.0, +1.0, o);
  ASSERT_EQ(bg.knots(), 1);
  cv::Mat b;
  bg.At(s.times[0], &b);
  double sum2 = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const double e = b.at<float>(y, x) - s.truth[0].at<float>(y, x) + 1.645 * kNoise;
      sum2 += e * e;
    }
  EXPECT_LT(std::sqrt(sum2 / (kW * kH)), 0.7 * kNoise);
}

TEST(DriftingBackground, RejectsBadInput) {
  const Scene s = MakeScene(4, kVx, kVy, false);
  DriftingBackgroundOptions o;
  o.percentile = 60.0;
  EXPECT_THROW(DriftingBackground(s.frames, s.times, 0, 0, 1.0, o), std::invalid_argument);
  std::vector<double> back(s.times.rbegin(), s.times.rend());
  EXPECT_THROW(DriftingBackground(s.frames, back, 0, 0, 1.0, DriftingBackgroundOptions{}),
               std::invalid_argument);
  EXPECT_THROW(DriftingBackground(s.frames, s.times, 0, 0, 0.0, DriftingBackgroundOptions{}),
               std::invalid_argument);
  std::vector<cv::Mat> two(s.frames.begin(), s.frames.begin() + 2);
  std::vector<double> t2(s.times.begin(), s.times.begin() + 2);
  EXPECT_THROW(MeasureDrift(two, t2, DriftOptions{}), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
