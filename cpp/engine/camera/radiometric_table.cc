#include "engine/camera/radiometric_table.h"

#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

// L(T) and dL/dT in one pass over the channel's quadrature.
void BandRadianceAndSlope(const SpectralResponse& ch, double t, double* l, double* dl) {
  const auto& nu = ch.quadrature_nu_cm1();
  const auto& w = ch.quadrature_weights();
  double sum = 0, dsum = 0;
  for (std::size_t k = 0; k < nu.size(); ++k) {
    const double x = constants::kC2 * nu[k] / t;
    if (x > 700.0) continue;
    const double em1 = std::expm1(x);
    const double b = constants::kC1 * nu[k] * nu[k] * nu[k] / em1;
    sum += w[k] * b;
    dsum += w[k] * b * x * (em1 + 1.0) / (em1 * t);
  }
  *l = sum;
  *dl = dsum;
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

double RadiometricTable::Cubic::Eval(double x) const {
  double slope;
  return Eval(x, &slope);
}

double RadiometricTable::Cubic::Eval(double x, double* slope) const {
  const double s = (x - x0) / dx;
  const std::size_t n = c.size() / 4;
  double i = std::floor(s);
  if (i < 0) i = 0;
  if (i > static_cast<double>(n - 1)) i = static_cast<double>(n - 1);
  const std::size_t k = static_cast<std::size_t>(i);
  const double f = s - i;
  const double* p = &c[4 * k];
  *slope = ((3.0 * p[3] * f + 2.0 * p[2]) * f + p[1]) / dx;
  return ((p[3] * f + p[2]) * f + p[1]) * f + p[0];
}

RadiometricTable::Cubic RadiometricTable::Hermite(double x0, double dx,
                                                  const std::vector<double>& v,
                                                  const std::vector<double>& slope) {
  Cubic out;
  out.x0 = x0;
  out.dx = dx;
  out.c.resize(4 * (v.size() - 1));
  for (std::size_t i = 0; i + 1 < v.size(); ++i) {
    const double m0 = slope[i] * dx, m1 = slope[i + 1] * dx;
    out.c[4 * i + 0] = v[i];
    out.c[4 * i + 1] = m0;
    out.c[4 * i + 2] = 3.0 * (v[i + 1] - v[i]) - 2.0 * m0 - m1;
    out.c[4 * i + 3] = 2.0 * (v[i] - v[i + 1]) + m0 + m1;
  }
  return out;
}

RadiometricTable::RadiometricTable(SpectralResponse channel, double t_min_K, double t_max_K,
                                   int nodes, int num_threads)
    : channel_(std::move(channel)), t_min_(t_min_K), t_max_(t_max_K) {
  Require(std::isfinite(t_min_K) && std::isfinite(t_max_K) &&
              t_min_K > SpectralResponse::kMinTemperature_K && t_max_K > t_min_K &&
              t_max_K < SpectralResponse::kMaxTemperature_K,
          "RadiometricTable: t_min_K and t_max_K must satisfy 10 < t_min_K < t_max_K < 1e5 K; "
          "got " +
              FormatNumber(t_min_K) + " and " + FormatNumber(t_max_K));
  Require(nodes >= 16, "RadiometricTable: nodes must be >= 16; got " + std::to_string(nodes));
  const std::size_t n = static_cast<std::size_t>(nodes);

  // Forward: y = ln L on a uniform grid in u = 1/T (u0 = 1/t_max).
  const double u0 = 1.0 / t_max_, du = (1.0 / t_min_ - u0) / (n - 1);
  std::vector<double> y(n), dy(n);
  ParallelFor(
      n, 16,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) {
          const double u = u0 + i * du, t = 1.0 / u;
          double l, dl;
          BandRadianceAndSlope(channel_, t, &l, &dl);
          y[i] = std::log(l);
          dy[i] = -(dl / l) * t * t;  // d ln L / du
        }
      },
      num_threads);
  forward_ = Hermite(u0, du, y, dy);
  l_max_ = std::exp(y.front());
  l_min_ = std::exp(y.back());
  l_floor_ = channel_.BandRadiance(SpectralResponse::kMinTemperature_K);
  l_ceil_ = channel_.BandRadiance(SpectralResponse::kMaxTemperature_K);

  // Inverse: u = 1/T on a uniform grid in x = ln L. Node temperatures from
  // the forward table, polished by Newton steps on the exact L(T).
  const double x0 = std::log(l_min_), dx = (std::log(l_max_) - x0) / (n - 1);
  std::vector<double> u(n), du_dx(n);
  ParallelFor(
      n, 16,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) {
          const double x = x0 + i * dx;
          // Invert the forward cubic by bisection on u (monotone), then Newton.
          double lo = u0, hi = u0 + (n - 1) * du;
          for (int k = 0; k < 60; ++k) {
            const double mid = 0.5 * (lo + hi);
            if (forward_.Eval(mid) > x)
              lo = mid;
            else
              hi = mid;
          }
          double t = 2.0 / (lo + hi), l = 0, dl = 1;
          for (int k = 0; k < 3; ++k) {
            BandRadianceAndSlope(channel_, t, &l, &dl);
            t -= (std::log(l) - x) * l / dl;
          }
          BandRadianceAndSlope(channel_, t, &l, &dl);
          u[i] = 1.0 / t;
          du_dx[i] = -(l / dl) / (t * t);  // du/dx = (dT/d ln L) (du/dT)
        }
      },
      num_threads);
  inverse_ = Hermite(x0, dx, u, du_dx);
}

double RadiometricTable::Radiance(double t) const {
  if (!(t > 0)) return kNaN;
  if (t >= t_min_ && t <= t_max_) return std::exp(forward_.Eval(1.0 / t));
  return channel_.BandRadiance(t);
}

double RadiometricTable::Derivative(double t) const {
  double l, dl;
  RadianceAndDerivative(t, &l, &dl);
  return dl;
}

void RadiometricTable::RadianceAndDerivative(double t, double* l, double* dl) const {
  if (!(t > 0)) {
    *l = *dl = kNaN;
  } else if (t >= t_min_ && t <= t_max_) {
    const double u = 1.0 / t;
    double slope;
    *l = std::exp(forward_.Eval(u, &slope));
    *dl = -*l * slope * u * u;
  } else {
    *l = channel_.BandRadiance(t);
    *dl = channel_.BandRadianceDerivative(t);
  }
}

double RadiometricTable::Temperature(double l) const {
  if (!(l >= l_min_ && l <= l_max_)) {
    if (!(l > l_floor_ && l < l_ceil_)) return kNaN;
    return channel_.RadiometricTemperature(l);
  }
  return 1.0 / inverse_.Eval(std::log(l));
}

namespace {

// out[i] = f(in[i]) as float for i < n, in parallel.
template <typename F>
void MapFloats(const float* in, float* out, std::size_t n, int num_threads,
               const RunControl* control, F f) {
  ParallelFor(
      n, 16384,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) out[i] = static_cast<float>(f(in[i]));
      },
      num_threads, control);
}

}  // namespace

void RadiometricTable::Radiance(const float* in, float* out, std::size_t n, int num_threads,
                                const RunControl* control) const {
  MapFloats(in, out, n, num_threads, control, [this](double t) { return Radiance(t); });
}

void RadiometricTable::Temperature(const float* in, float* out, std::size_t n, int num_threads,
                                   const RunControl* control) const {
  MapFloats(in, out, n, num_threads, control, [this](double l) { return Temperature(l); });
}

}  // namespace qogi
