// Synthetic moving textures with exact motion, for the velocimetry tests.
//
// A band-limited random texture T is an analytic sum of cosines, so it can be
// evaluated at any real position: the next frame is the texture resampled
// exactly through the inverse of a known displacement map phi(x) = x + w(x),
//   brightness:  I1(X) = I0(phi^-1(X))
//   continuity:  rho1(X) = rho0(phi^-1(X)) / det D phi(phi^-1(X))
// (exact mass conservation for the map). The truth is w(x) at every pixel x
// of the first frame. Seeded; double precision throughout.
#pragma once

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

namespace qogi {
namespace testing_scenes {

struct Texture {
  std::vector<double> kx, ky, phase;
  double amp = 0;

  // Zero-mean, unit-variance sum of `n` cosines with random directions and
  // wavelengths uniform in [lambda_min, lambda_max] px.
  static Texture Make(unsigned seed, int n = 64, double lambda_min = 6.0,
                      double lambda_max = 24.0) {
    Texture t;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const double pi = 3.14159265358979323846;
    for (int i = 0; i < n; ++i) {
      const double lam = lambda_min + (lambda_max - lambda_min) * uni(rng);
      const double dir = 2 * pi * uni(rng);
      t.kx.push_back(2 * pi / lam * std::cos(dir));
      t.ky.push_back(2 * pi / lam * std::sin(dir));
      t.phase.push_back(2 * pi * uni(rng));
    }
    t.amp = std::sqrt(2.0 / n);
    return t;
  }
  double operator()(double x, double y) const {
    double s = 0;
    for (std::size_t i = 0; i < kx.size(); ++i) s += std::cos(kx[i] * x + ky[i] * y + phase[i]);
    return amp * s;
  }
};

// A displacement map x -> x + w(x) with w given analytically.
struct Motion {
  std::function<void(double, double, double&, double&)> w;

  void Forward(double x, double y, double& X, double& Y) const {
    double u, v;
    w(x, y, u, v);
    X = x + u;
    Y = y + v;
  }
  // det(D phi) by central differences (h = 1e-4 px).
  double Jacobian(double x, double y) const {
    const double h = 1e-4;
    double xp, yp, xm, ym, xq, yq, xn, yn;
    Forward(x + h, y, xp, yp);
    Forward(x - h, y, xm, ym);
    Forward(x, y + h, xq, yq);
    Forward(x, y - h, xn, yn);
    const double a = (xp - xm) / (2 * h), b = (xq - xn) / (2 * h);
    const double c = (yp - ym) / (2 * h), d = (yq - yn) / (2 * h);
    return a * d - b * c;
  }
  // phi^-1(X) by Newton iterations from X - w(X).
  void Inverse(double X, double Y, double& x, double& y) const {
    double u, v;
    w(X, Y, u, v);
    x = X - u;
    y = Y - v;
    const double h = 1e-5;
    for (int it = 0; it < 30; ++it) {
      double fx, fy;
      Forward(x, y, fx, fy);
      const double ex = fx - X, ey = fy - Y;
      if (std::abs(ex) + std::abs(ey) < 1e-12) break;
      double xp, yp, xq, yq;
      Forward(x + h, y, xp, yp);
      Forward(x, y + h, xq, yq);
      const double a = (xp - fx) / h, b = (xq - fx) / h;
      const double c = (yp - fy) / h, d = (yq - fy) / h;
      const double det = a * d - b * c;
      x -= (d * ex - b * ey) / det;
      y -= (-c * ex + a * ey) / det;
    }
  }

  static Motion Translation(double tx, double ty) {
    return {[=](double, double, double& u, double& v) {
      u = tx;
      v = ty;
    }};
  }
  // Rotation by `angle` rad (positive = clockwise on screen, y down) about c.
  static Motion Rotation(double angle, double cx, double cy) {
    const double c = std::cos(angle), s = std::sin(angle);
    return {[=](double x, double y, double& u, double& v) {
      const double dx = x - cx, dy = y - cy;
      u = c * dx - s * dy - dx;
      v = s * dx + c * dy - dy;
    }};
  }
  // A jet-like shear layer: u = peak exp(-(y - cy)^2 / 2 sigma^2), v = 0.
  static Motion JetShear(double peak, double cy, double sigma) {
    return {[=](double, double y, double& u, double& v) {
      u = peak * std::exp(-(y - cy) * (y - cy) / (2 * sigma * sigma));
      v = 0;
    }};
  }
  // Radial spreading about c: w = rate (x - c) (divergence 2 rate per frame).
  static Motion Spreading(double rate, double cx, double cy) {
    return {[=](double x, double y, double& u, double& v) {
      u = rate * (x - cx);
      v = rate * (y - cy);
    }};
  }
  // A localised source: w = rate (x - c) exp(-|x - c|^2 / 2 sigma^2) plus a
  // uniform drift (dx, dy): compressible, with divergence varying in space.
  static Motion DriftingSource(double rate, double cx, double cy, double sigma, double dx,
                               double dy) {
    return {[=](double x, double y, double& u, double& v) {
      const double rx = x - cx, ry = y - cy;
      const double g = std::exp(-(rx * rx + ry * ry) / (2 * sigma * sigma));
      u = dx + rate * rx * g;
      v = dy + rate * ry * g;
    }};
  }
  // A divergence-free field from the stream function
  // psi = peak sigma exp(-|x - c|^2 / 2 sigma^2) (a vortex) plus a drift.
  static Motion DriftingVortex(double peak, double cx, double cy, double sigma, double dx,
                               double dy) {
    return {[=](double x, double y, double& u, double& v) {
      const double rx = x - cx, ry = y - cy;
      const double g = std::exp(-(rx * rx + ry * ry) / (2 * sigma * sigma));
      // u = d psi / dy, v = -d psi / dx
      u = dx - peak * ry / sigma * g;
      v = dy + peak * rx / sigma * g;
    }};
  }
};

struct Scene {
  cv::Mat prev, next;      // CV_32F
  cv::Mat true_u, true_v;  // CV_32F, truth at each pixel of prev
};

// A scene of `size` whose four images are allocated (CV_32F), not filled.
inline Scene NewScene(cv::Size size) {
  Scene s;
  s.prev.create(size, CV_32F);
  s.next.create(size, CV_32F);
  s.true_u.create(size, CV_32F);
  s.true_v.create(size, CV_32F);
  return s;
}

// Adds seeded white noise of standard deviation sigma to both frames (the
// same stream: prev's draws first).
inline void AddPairNoise(Scene& s, double sigma, unsigned seed) {
  cv::RNG rng(seed);
  cv::Mat n(s.prev.size(), CV_32F);
  rng.fill(n, cv::RNG::NORMAL, 0.0, sigma);
  s.prev += n;
  rng.fill(n, cv::RNG::NORMAL, 0.0, sigma);
  s.next += n;
}

// Noise relative to the first frame's peak (density frames).
inline void AddPeakRelativeNoise(Scene& s, double noise, unsigned seed) {
  if (!(noise > 0)) return;
  double peak;
  cv::minMaxLoc(s.prev, nullptr, &peak);
  AddPairNoise(s, noise * peak, seed);
}

// Brightness-constancy pair: I = offset + gain * f(T) with f = exp(0.4 T)
// (positive, skewed like plume intermittency), plus seeded white noise of
// standard deviation noise * std(I).
inline Scene RenderTexture(cv::Size size, const Texture& t, const Motion& m, double noise = 0.0,
                           unsigned noise_seed = 1) {
  Scene s = NewScene(size);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      s.prev.at<float>(y, x) = static_cast<float>(std::exp(0.4 * t(x, y)));
      double x0, y0;
      m.Inverse(x, y, x0, y0);
      s.next.at<float>(y, x) = static_cast<float>(std::exp(0.4 * t(x0, y0)));
      double u, v;
      m.w(x, y, u, v);
      s.true_u.at<float>(y, x) = static_cast<float>(u);
      s.true_v.at<float>(y, x) = static_cast<float>(v);
    }
  if (noise > 0) {
    cv::Scalar mean, sd;
    cv::meanStdDev(s.prev, mean, sd);
    AddPairNoise(s, noise * sd[0], noise_seed);
  }
  return s;
}

// Column-density pair advected by the continuity equation: rho0 = envelope x
// exp(contrast T) with a Gaussian envelope (centre c, width sigma_env; sigma_env
// <= 0 = uniform), rho1 by exact mass conservation through the map.
inline Scene RenderDensity(cv::Size size, const Texture& t, const Motion& m, double cx, double cy,
                           double sigma_env, double noise = 0.0, unsigned noise_seed = 1,
                           double contrast = 0.4) {
  auto rho0 = [&](double x, double y) {
    double env = 1.0;
    if (sigma_env > 0)
      env = std::exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (2 * sigma_env * sigma_env));
    return env * std::exp(contrast * t(x, y));
  };
  Scene s = NewScene(size);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      s.prev.at<float>(y, x) = static_cast<float>(rho0(x, y));
      double x0, y0;
      m.Inverse(x, y, x0, y0);
      s.next.at<float>(y, x) = static_cast<float>(rho0(x0, y0) / m.Jacobian(x0, y0));
      double u, v;
      m.w(x, y, u, v);
      s.true_u.at<float>(y, x) = static_cast<float>(u);
      s.true_v.at<float>(y, x) = static_cast<float>(v);
    }
  AddPeakRelativeNoise(s, noise, noise_seed);
  return s;
}

// A steady, decelerating plume column leaving an exit at row exit_y (gas
// only above it), with a featureless base and turbulent texture only on gas
// that left the exit before t = -texture_age. Exact solution of the continuity
// equation for the vertical velocity dz/dt = U(z) = u0 - decel z (z = exit_y -
// y, upwards): rho = E(x) (u0 / U(z)) m(x, t - tau(z)), tau(z) = travel time
// from the exit, m = 1 + contrast T for old parcels (the label a parcel
// carries), E a Gaussian profile of width sigma_x. In the featureless base
// rho is steady and the mass flux rho U is constant along the column; the
// displacement over one frame is Delta z = (u0/decel - z)(1 - exp(-decel)).
// Renders frames t0 and t0 + 1 (the flow is steady: the truth does not
// depend on t0).
inline Scene RenderSteadyColumn(cv::Size size, const Texture& t, double exit_y, double cx,
                                double sigma_x, double u0, double decel, double texture_age,
                                double contrast, double noise = 0.0, unsigned noise_seed = 1,
                                double t0 = 0.0) {
  auto tau = [&](double z) { return -std::log(1.0 - decel * z / u0) / decel; };
  auto rho = [&](double x, double y, double time) {
    const double z = exit_y - y;
    if (z < 0) return 0.0;
    const double born = time - tau(z);  // when the parcel left the exit
    // Only gas that left the exit before t = -texture_age carries texture
    // (fading in over 4 frames): the younger gas forms the featureless base,
    // which grows as the labels are advected.
    const double age = -born;
    const double w = std::min(1.0, std::max(0.0, (age - texture_age) / 4.0));
    const double m = 1.0 + contrast * w * t(x, born * u0);
    const double e = std::exp(-(x - cx) * (x - cx) / (2 * sigma_x * sigma_x));
    return e * (u0 / (u0 - decel * z)) * m;
  };
  Scene s;
  s.prev.create(size, CV_32F);
  s.next.create(size, CV_32F);
  s.true_u = cv::Mat::zeros(size, CV_32F);
  s.true_v = cv::Mat::zeros(size, CV_32F);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      s.prev.at<float>(y, x) = static_cast<float>(rho(x, y, t0));
      s.next.at<float>(y, x) = static_cast<float>(rho(x, y, t0 + 1.0));
      const double z = exit_y - y;
      if (z >= 0)
        s.true_v.at<float>(y, x) = static_cast<float>(-(u0 / decel - z) * (1.0 - std::exp(-decel)));
    }
  AddPeakRelativeNoise(s, noise, noise_seed);
  return s;
}

// Mean end-point error |w - w_true| [px] over the pixels at least `margin`
// px from the border where `region` (optional, CV_8U) and flow.valid are set;
// *valid_fraction receives the share of those pixels that are valid.
inline double MeanEndPointError(const cv::Mat& u, const cv::Mat& v, const cv::Mat& valid,
                                const Scene& s, int margin, double* valid_fraction = nullptr,
                                const cv::Mat& region = cv::Mat()) {
  double sum = 0;
  long long n = 0, total = 0;
  for (int y = margin; y < u.rows - margin; ++y)
    for (int x = margin; x < u.cols - margin; ++x) {
      if (!region.empty() && !region.at<uchar>(y, x)) continue;
      ++total;
      if (!valid.empty() && !valid.at<uchar>(y, x)) continue;
      const double du = u.at<float>(y, x) - s.true_u.at<float>(y, x);
      const double dv = v.at<float>(y, x) - s.true_v.at<float>(y, x);
      sum += std::sqrt(du * du + dv * dv);
      ++n;
    }
  if (valid_fraction) *valid_fraction = total ? static_cast<double>(n) / total : 0.0;
  return n ? sum / n : 1e9;
}

}  // namespace testing_scenes
}  // namespace qogi
