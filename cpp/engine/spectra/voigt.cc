#include "engine/spectra/voigt.h"

#include <cmath>

#include "engine/util/check.h"
#include "engine/util/portability.h"

// Multiversioned kernels: an AVX2 clone is picked at load time on CPUs that
// have it (the rest of the library keeps the baseline ISA).
#define QOGI_KERNEL QOGI_TARGET_CLONES("avx2", "default")

namespace qogi {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInvSqrtPi = 0.56418958354775628695;  // 1/sqrt(pi)
constexpr int kN = 32;                                 // Weideman's N

// Weideman (1994): w(z) = 2 p(Z) / (L - iz)^2 + pi^(-1/2) / (L - iz),
// Z = (L + iz) / (L - iz), p(Z) = sum_{n=1}^{N} a_n Z^(n-1), where a_n are the
// Fourier coefficients of f(theta) = exp(-t^2) (L^2 + t^2), t = L tan(theta/2),
// computed with the trapezoidal rule on 2M = 4N points, L = sqrt(N / sqrt(2)).
struct Weideman {
  double L;
  double a[kN + 1];
  Weideman() {
    const int M = 2 * kN;
    L = std::sqrt(kN / std::sqrt(2.0));
    for (int n = 0; n <= kN; ++n) {
      double sum = 0.0;
      for (int k = -M + 1; k <= M - 1; ++k) {
        const double theta = k * kPi / M;
        const double t = L * std::tan(0.5 * theta);
        sum += std::exp(-t * t) * (L * L + t * t) * std::cos(n * theta);
      }
      a[n] = sum / (2.0 * M);
    }
  }
};

const Weideman& W() {
  static const Weideman w;
  return w;
}

// Re and Im of the Weideman approximation, in real arithmetic (vectorisable).
inline void WeidemanParts(const Weideman& c, double x, double y, double& re, double& im) {
  const double L = c.L;
  const double lpy = L + y;
  const double inv_d = 1.0 / (lpy * lpy + x * x);
  // Z = (L + iz)/(L - iz) = ((L^2 - x^2 - y^2) + 2 i L x) / ((L + y)^2 + x^2)
  const double zr = (L * L - x * x - y * y) * inv_d;
  const double zi = 2.0 * L * x * inv_d;
  double pr = c.a[kN], pi = 0.0;
  for (int n = kN - 1; n >= 1; --n) {
    const double t = pr * zr - pi * zi + c.a[n];
    pi = pr * zi + pi * zr;
    pr = t;
  }
  // q = 1/(L - iz) = ((L + y) + i x) / ((L + y)^2 + x^2); w = q (2 p q + 1/sqrt(pi))
  const double qr = lpy * inv_d, qi = x * inv_d;
  const double sr = 2.0 * (pr * qr - pi * qi) + kInvSqrtPi;
  const double si = 2.0 * (pr * qi + pi * qr);
  re = qr * sr - qi * si;
  im = qr * si + qi * sr;
}

// Re and Im of i z (z^2 - 5/2) / (sqrt(pi) (z^4 - 3 z^2 + 3/4)).
inline void Cf4Parts(double x, double y, double& re, double& im) {
  const double ar = x * x - y * y, ai = 2.0 * x * y;          // z^2
  const double nr0 = ar - 2.5, ni0 = ai;                      // z^2 - 5/2
  const double nr = x * nr0 - y * ni0, ni = x * ni0 + y * nr0;  // z (z^2 - 5/2)
  const double dr = ar * ar - ai * ai - 3.0 * ar + 0.75;      // z^4 - 3 z^2 + 3/4
  const double di = 2.0 * ar * ai - 3.0 * ai;
  const double inv = kInvSqrtPi / (dr * dr + di * di);
  const double qr = (nr * dr + ni * di) * inv, qi = (ni * dr - nr * di) * inv;
  re = -qi, im = qr;  // i q
}

// Re and Im of i z / (sqrt(pi) (z^2 - 1/2)).
inline void Cf2Parts(double x, double y, double& re, double& im) {
  const double dr = x * x - y * y - 0.5, di = 2.0 * x * y;
  const double inv = kInvSqrtPi / (dr * dr + di * di);
  const double qr = (x * dr + y * di) * inv, qi = (y * dr - x * di) * inv;
  re = -qi, im = qr;
}

}  // namespace

std::complex<double> FaddeevaWeideman32(double x, double y) {
  double re, im;
  WeidemanParts(W(), x, y, re, im);
  return {re, im};
}

std::complex<double> FaddeevaContinuedFraction4(double x, double y) {
  double re, im;
  Cf4Parts(x, y, re, im);
  return {re, im};
}

std::complex<double> FaddeevaContinuedFraction2(double x, double y) {
  double re, im;
  Cf2Parts(x, y, re, im);
  return {re, im};
}

std::complex<double> Faddeeva(double x, double y) {
  CheckFinite(x, "x");
  CheckNonNegative(y, "y");
  const double s = std::abs(x) + y;
  if (s >= kVoigtFarLimit) return FaddeevaContinuedFraction2(x, y);
  if (s >= kVoigtCentreLimit) return FaddeevaContinuedFraction4(x, y);
  return FaddeevaWeideman32(x, y);
}

double VoigtProfile(double dnu_cm1, double gamma_doppler_cm1, double gamma_lorentz_cm1) {
  CheckFinite(dnu_cm1, "dnu_cm1");
  CheckPositive(gamma_doppler_cm1, "gamma_doppler_cm1", "cm-1");
  CheckNonNegative(gamma_lorentz_cm1, "gamma_lorentz_cm1", "cm-1");
  const double alpha = gamma_doppler_cm1 / std::sqrt(std::log(2.0));
  return Faddeeva(dnu_cm1 / alpha, gamma_lorentz_cm1 / alpha).real() * kInvSqrtPi / alpha;
}

QOGI_KERNEL
void AddVoigtWeideman(const double* nu, std::size_t n, double centre, double alpha,
                      double gamma_lorentz, double scale, double* out) {
  const Weideman& c = W();
  const double inv_alpha = 1.0 / alpha;
  const double y = gamma_lorentz * inv_alpha;
  const double k = scale * kInvSqrtPi * inv_alpha;
  for (std::size_t j = 0; j < n; ++j) {
    double re, im;
    WeidemanParts(c, (nu[j] - centre) * inv_alpha, y, re, im);
    out[j] += k * re;
  }
}

QOGI_KERNEL
void AddVoigtContinuedFraction4(const double* nu, std::size_t n, double centre, double alpha,
                                double gamma_lorentz, double scale, double* out) {
  const double inv_alpha = 1.0 / alpha;
  const double y = gamma_lorentz * inv_alpha;
  const double k = scale * kInvSqrtPi * inv_alpha;
  for (std::size_t j = 0; j < n; ++j) {
    double re, im;
    Cf4Parts((nu[j] - centre) * inv_alpha, y, re, im);
    out[j] += k * re;
  }
}

QOGI_KERNEL
void AddVoigtFarWing(const double* nu, std::size_t n, double centre, double alpha,
                     double gamma_lorentz, double scale, double* out) {
  const double g2 = gamma_lorentz * gamma_lorentz;
  const double gh = g2 + 0.5 * alpha * alpha;   // gamma_L^2 + alpha^2/2
  const double four_g2 = 4.0 * g2;
  const double k = scale * gamma_lorentz / kPi;
  for (std::size_t j = 0; j < n; ++j) {
    const double d = nu[j] - centre;
    const double d2 = d * d;
    const double a = d2 - gh;
    out[j] += k * (d2 + gh) / (a * a + four_g2 * d2);
  }
}

}  // namespace qogi
