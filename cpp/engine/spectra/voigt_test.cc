#include "engine/spectra/voigt.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace qogi {
namespace {

constexpr double kPi = 3.14159265358979323846;

double RelErr(double a, double b) { return std::abs(a / b - 1.0); }

TEST(Faddeeva, ImaginaryAxisIsScaledErfc) {
  // w(iy) = exp(y^2) erfc(y), real.
  for (double y = 1e-4; y <= 20.0; y *= 1.3) {
    const double exact = std::exp(y * y) * std::erfc(y);
    const std::complex<double> w = Faddeeva(0.0, y);
    const double tol = y < kVoigtCentreLimit ? 1e-8 : 5e-5;
    EXPECT_LT(RelErr(w.real(), exact), tol) << y;
    EXPECT_NEAR(w.imag(), 0.0, 1e-12) << y;
  }
}

TEST(Faddeeva, RealAxisRealPartIsGaussian) {
  // Weideman's absolute error is ~1e-14, i.e. ~1e-7 relative at exp(-16).
  for (double x = -4.0; x <= 4.0; x += 0.01)
    EXPECT_LT(RelErr(Faddeeva(x, 0.0).real(), std::exp(-x * x)), 1e-6) << x;
}

TEST(Faddeeva, FarFieldMatchesAsymptoticSeries) {
  // w(z) ~ (i/sqrt(pi)) (1/z + 1/(2 z^3) + 3/(4 z^5) + 15/(8 z^7)) for |z| >> 1.
  for (double x : {-1e4, -300.0, 100.0, 250.0, 1e4})
    for (double y : {1e-4, 1e-2, 1.0, 30.0, 1e3}) {
      const std::complex<double> z(x, y);
      const std::complex<double> s =
          1.0 / z + 0.5 / std::pow(z, 3) + 0.75 / std::pow(z, 5) + 1.875 / std::pow(z, 7);
      const std::complex<double> ref = std::complex<double>(0, 1) * s / std::sqrt(kPi);
      EXPECT_LT(RelErr(Faddeeva(x, y).real(), ref.real()), 1e-6) << x << " " << y;
    }
}

TEST(Faddeeva, RegionsAgreeOnTheirBoundaries) {
  // Either side of s = |x| + y = 6 and s = 20 the approximations agree.
  for (double y : {1e-4, 1e-2, 0.5, 2.0, 5.0}) {
    const double x6 = kVoigtCentreLimit - y;
    EXPECT_LT(RelErr(FaddeevaContinuedFraction4(x6, y).real(), FaddeevaWeideman32(x6, y).real()),
              5e-5)
        << y;
  }
  for (double y : {1e-4, 1e-2, 1.0, 10.0, 19.0}) {
    const double x20 = kVoigtFarLimit - y;
    EXPECT_LT(RelErr(FaddeevaContinuedFraction2(x20, y).real(), FaddeevaWeideman32(x20, y).real()),
              5e-5)
        << y;
    EXPECT_LT(RelErr(FaddeevaContinuedFraction4(x20, y).real(), FaddeevaWeideman32(x20, y).real()),
              1e-6)
        << y;
  }
  EXPECT_THROW(Faddeeva(1.0, -1e-3), std::invalid_argument);
  EXPECT_THROW(Faddeeva(std::nan(""), 1.0), std::invalid_argument);
}

TEST(VoigtProfile, DopplerAndLorentzLimits) {
  const double gd = 0.005, gl_small = gd * 1e-7;
  for (double d = -2 * gd; d <= 2 * gd; d += gd / 20) {
    const double gauss =
        std::sqrt(std::log(2.0) / kPi) / gd * std::exp(-std::log(2.0) * d * d / (gd * gd));
    EXPECT_LT(RelErr(VoigtProfile(d, gd, gl_small), gauss), 1e-5) << d;
  }
  const double gl = 0.1, gd_small = gl * 1e-4;
  for (double d = -3.0; d <= 3.0; d += 0.01) {
    const double lorentz = gl / (kPi * (d * d + gl * gl));
    EXPECT_LT(RelErr(VoigtProfile(d, gd_small, gl), lorentz), 1e-6) << d;
  }
}

TEST(VoigtProfile, UnitAreaUpToTheLorentzTail) {
  const double gd = 0.005, gl = 0.05, r = 50.0, h = 2.5e-4;
  std::vector<double> nu;
  for (double d = -r; d <= r + h / 2; d += h) nu.push_back(d);
  std::vector<double> v(nu.size(), 0.0);
  // The cross-section's kernels, each over its own region, summed.
  const double alpha = gd / std::sqrt(std::log(2.0));
  const double y = gl / alpha;
  const double rf = (kVoigtFarLimit - y) * alpha, rm = (kVoigtCentreLimit - y) * alpha;
  for (std::size_t j = 0; j < nu.size(); ++j) {
    const double a = std::abs(nu[j]);
    if (a >= rf)
      AddVoigtFarWing(&nu[j], 1, 0.0, alpha, gl, 1.0, &v[j]);
    else if (a >= rm)
      AddVoigtContinuedFraction4(&nu[j], 1, 0.0, alpha, gl, 1.0, &v[j]);
    else
      AddVoigtWeideman(&nu[j], 1, 0.0, alpha, gl, 1.0, &v[j]);
  }
  double sum = 0.0;
  for (std::size_t j = 0; j < v.size(); ++j)
    sum += v[j] * h * ((j == 0 || j + 1 == v.size()) ? 0.5 : 1.0);
  // Beyond |d| = r only the Lorentz tail is left: 1 - (2/pi) atan(r / gl).
  EXPECT_NEAR(sum, 2.0 / kPi * std::atan(r / gl), 2e-6);
}

TEST(VoigtProfile, KernelsEqualTheProfile) {
  const double gd = 0.004, gl = 0.03, alpha = gd / std::sqrt(std::log(2.0)), s = 2.5;
  std::vector<double> nu;
  for (double d = -3.0; d <= 3.0; d += 0.0137) nu.push_back(3000.0 + d);
  std::vector<double> a(nu.size());
  std::vector<double> b(nu.size());
  std::vector<double> c(nu.size());
  AddVoigtWeideman(nu.data(), nu.size(), 3000.0, alpha, gl, s, a.data());
  AddVoigtContinuedFraction4(nu.data(), nu.size(), 3000.0, alpha, gl, s, b.data());
  AddVoigtFarWing(nu.data(), nu.size(), 3000.0, alpha, gl, s, c.data());
  for (std::size_t j = 0; j < nu.size(); ++j) {
    const double x = (nu[j] - 3000.0) / alpha, y = gl / alpha;
    const double k = s / (alpha * std::sqrt(kPi));
    EXPECT_LT(RelErr(a[j], k * FaddeevaWeideman32(x, y).real()), 1e-12);
    EXPECT_LT(RelErr(b[j], k * FaddeevaContinuedFraction4(x, y).real()), 1e-12);
    EXPECT_LT(RelErr(c[j], k * FaddeevaContinuedFraction2(x, y).real()), 1e-12);
    if (std::abs(x) + y >= kVoigtFarLimit) {
      EXPECT_LT(RelErr(c[j], s * VoigtProfile(nu[j] - 3000.0, gd, gl)), 1e-12);
    }
  }
}

}  // namespace
}  // namespace qogi
