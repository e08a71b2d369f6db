// Registration recovers known rigid motions of an exactly evaluated texture,
// with noise and a moving plume, to within what the noise allows.
#include "engine/registration/registration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace qogi {
namespace {

// A band-limited texture: a sum of random plane waves (periods 6-40 px),
// evaluated exactly at any point.
struct Texture {
  std::vector<double> kx, ky, phase, amp;
  explicit Texture(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (int i = 0; i < 60; ++i) {
      const double period = 10 + 30 * u(rng), dir = 2 * M_PI * u(rng);
      kx.push_back(2 * M_PI / period * std::cos(dir));
      ky.push_back(2 * M_PI / period * std::sin(dir));
      phase.push_back(2 * M_PI * u(rng));
      amp.push_back(0.2 * (0.5 + u(rng)));
    }
  }
  double operator()(double x, double y) const {
    double s = 0;
    for (std::size_t i = 0; i < kx.size(); ++i)
      s += amp[i] * std::cos(kx[i] * x + ky[i] * y + phase[i]);
    return s;
  }
};

constexpr int kW = 160, kH = 120;

cv::Mat Render(const Texture& tex, const RigidShift& p) {
  // The frame's content at W(x) is the reference's at x: frame(y) = tex(W^-1(y)).
  const double cx = 0.5 * (kW - 1), cy = 0.5 * (kH - 1);
  const double c = std::cos(p.angle_rad), s = std::sin(p.angle_rad);
  cv::Mat f(kH, kW, CV_32F);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const double ux = x - cx - p.dx_px, uy = y - cy - p.dy_px;
      f.at<float>(y, x) = static_cast<float>(tex(cx + c * ux + s * uy, cy - s * ux + c * uy));
    }
  return f;
}

void AddNoise(cv::Mat* f, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0, static_cast<float>(sigma));
  for (auto it = f->begin<float>(); it != f->end<float>(); ++it) *it += n(rng);
}

// A bright blob (a plume puff) over about a tenth of the frame.
void AddPlume(cv::Mat* f, double x0, double y0) {
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      f->at<float>(y, x) +=
          static_cast<float>(3.0 * std::exp(-((x - x0) * (x - x0) + (y - y0) * (y - y0)) / 300.0));
}

TEST(Registration, RecoversAShiftAndRotationWithinTheNoisePrecision) {
  const Texture tex(3);
  const cv::Mat ref = Render(tex, {});
  const FrameRegistration reg(ref, cv::Mat(), RegistrationOptions{});
  const double noise = 0.02;
  const RigidShift prec = reg.Precision(noise);
  EXPECT_LT(prec.dx_px, 0.01);
  EXPECT_LT(prec.dy_px, 0.01);
  for (const RigidShift truth : {RigidShift{0.37, -0.52, 0.002}, RigidShift{-1.3, 0.8, -0.004},
                                 RigidShift{0.05, 0.02, 0.0}}) {
    cv::Mat f = Render(tex, truth);
    AddNoise(&f, noise, 11);
    const RegistrationResult r = reg.Register(f);
    EXPECT_TRUE(r.converged);
    // Noise (5 sigma) plus the bicubic resampling's own error on this texture.
    EXPECT_NEAR(r.shift.dx_px, truth.dx_px, 5 * prec.dx_px + 0.01);
    EXPECT_NEAR(r.shift.dy_px, truth.dy_px, 5 * prec.dy_px + 0.01);
    EXPECT_NEAR(r.shift.angle_rad, truth.angle_rad, 5 * prec.angle_rad + 1e-4);
    EXPECT_LT(r.residual_sigma, noise);  // of the smoothed frame: below the raw noise
  }
}

TEST(Registration, RobustWeightsKeepAMovingPlumeOutOfTheEstimate) {
  const Texture tex(5);
  const cv::Mat ref = Render(tex, {});
  const RigidShift truth{0.4, -0.3, 0.0};
  // The gas moves on its own: 6 px between the reference and the frame.
  cv::Mat ref_gas = ref.clone();
  AddPlume(&ref_gas, 60, 50);
  cv::Mat f = Render(tex, truth);
  AddNoise(&f, 0.02, 12);
  AddPlume(&f, 66, 50);
  RegistrationOptions robust;
  robust.rotation = false;
  const RegistrationResult r = FrameRegistration(ref_gas, cv::Mat(), robust).Register(f);
  EXPECT_NEAR(r.shift.dx_px, truth.dx_px, 0.02);
  EXPECT_NEAR(r.shift.dy_px, truth.dy_px, 0.02);
  EXPECT_LT(r.inlier_fraction, 0.97);  // the plume's pixels were left out
  // The same fit with weights that keep every pixel is pulled by the plume.
  RegistrationOptions plain = robust;
  plain.robust_scale = 1e6;
  const RegistrationResult p = FrameRegistration(ref_gas, cv::Mat(), plain).Register(f);
  EXPECT_GT(std::hypot(p.shift.dx_px - truth.dx_px, p.shift.dy_px - truth.dy_px), 0.05);
}

TEST(Registration, ASceneGradedOnlyVerticallyFixesDyButNotDx) {
  cv::Mat ref(kH, kW, CV_32F);
  for (int y = 0; y < kH; ++y) ref.row(y).setTo(0.1 * y);
  const FrameRegistration reg(ref, cv::Mat(), RegistrationOptions{});
  const RigidShift prec = reg.Precision(0.02);
  EXPECT_LT(prec.dy_px, 0.01);
  EXPECT_GT(prec.dx_px, 1e3);
  cv::Mat uniform(kH, kW, CV_32F, cv::Scalar(1.0f));
  const RigidShift none =
      FrameRegistration(uniform, cv::Mat(), RegistrationOptions{}).Precision(0.02);
  EXPECT_GT(none.dx_px, 1e6);
  EXPECT_GT(none.dy_px, 1e6);
}

TEST(Registration, WarpToReferenceUndoesTheMotion) {
  const Texture tex(7);
  const RigidShift truth{0.6, -0.25, 0.003};
  const cv::Mat ref = Render(tex, {}), f = Render(tex, truth);
  cv::Mat back;
  WarpToReference(f, truth, &back);
  const cv::Rect inner(6, 6, kW - 12, kH - 12);
  double worst = 0;
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x)
      worst = std::max(worst, std::abs(double(back.at<float>(y, x)) - ref.at<float>(y, x)));
  EXPECT_LT(worst, 0.03);  // bicubic on a texture of amplitude ~2
}

TEST(Registration, WarpAlongAUniformFlowIsATranslation) {
  const Texture tex(9);
  const cv::Mat f = Render(tex, {});
  const cv::Mat u(kH, kW, CV_32F, cv::Scalar(2.0f)), v(kH, kW, CV_32F, cv::Scalar(-1.0f));
  cv::Mat out;
  WarpAlongFlow(f, u, v, 0.25, &out);  // samples f at x + (0.5, -0.25)
  const cv::Mat expect = Render(tex, RigidShift{-0.5, 0.25, 0.0});
  double worst = 0;
  for (int y = 6; y < kH - 6; ++y)
    for (int x = 6; x < kW - 6; ++x)
      worst = std::max(worst, std::abs(double(out.at<float>(y, x)) - expect.at<float>(y, x)));
  EXPECT_LT(worst, 0.03);
}

TEST(Registration, BadOptionsAndInputsAreRefused) {
  RegistrationOptions o;
  o.max_iterations = 0;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o = RegistrationOptions{};
  o.tolerance_px = -1;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  const cv::Mat ref(kH, kW, CV_32F, cv::Scalar(0.f));
  const FrameRegistration reg(ref, cv::Mat(), RegistrationOptions{});
  EXPECT_THROW(reg.Register(cv::Mat(10, 10, CV_32F, cv::Scalar(0.f))), std::invalid_argument);
  EXPECT_THROW(FrameRegistration(cv::Mat(4, 4, CV_32F), cv::Mat(), RegistrationOptions{}),
               std::invalid_argument);
}

}  // namespace
}  // namespace qogi
