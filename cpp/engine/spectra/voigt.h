// The Voigt line profile through the Faddeeva function w(z) = exp(-z^2) erfc(-iz).
//
// For a line with Doppler HWHM gamma_D and Lorentz HWHM gamma_L, with
// alpha = gamma_D / sqrt(ln 2) (the Doppler 1/e half-width),
//
//   V(dnu) = Re w(x + i y) / (alpha sqrt(pi))   [cm],
//   x = dnu / alpha,  y = gamma_L / alpha,
//
// normalised to unit area over dnu in cm-1. Re w(x, y) is the Voigt function
// K(x, y). w is evaluated piecewise in s = |x| + y (all relative errors of
// Re w measured against scipy.special.wofz over 1e-4 <= y <= 1e3,
// |x| <= 1e4; see voigt_test.cc and tests/python/test_spectra.py):
//
//   s <  kVoigtCentreLimit (6):  Weideman's N = 32 rational approximation
//       (J.A.C. Weideman, "Computation of the complex error function", SIAM J.
//       Numer. Anal. 31 (1994) 1497-1518, eq. 38-39), error < 3e-8;
//   s <  kVoigtFarLimit (20):    the 4th convergent of the Laplace continued
//       fraction, i z (z^2 - 5/2) / (sqrt(pi) (z^4 - 3 z^2 + 3/4)) (Humlicek's
//       region II, J. Humlicek, JQSRT 27 (1982) 437-444), error < 3e-5;
//   s >= kVoigtFarLimit:         its 2nd convergent, i z / (sqrt(pi) (z^2 - 1/2))
//       (Humlicek's region I), error < 3e-5, whose real part in line units is
//       the closed form used for far wings:
//       V = gamma_L (d^2 + gamma_L^2 + alpha^2/2) /
//           (pi ((d^2 - gamma_L^2 - alpha^2/2)^2 + 4 d^2 gamma_L^2)).
#pragma once

#include <complex>
#include <cstddef>

namespace qogi {

constexpr double kVoigtCentreLimit = 6.0;  // s below: Weideman N = 32
constexpr double kVoigtFarLimit = 20.0;    // s at or above: 2nd convergent

// w(x + i y) for y >= 0 (throws std::invalid_argument for y < 0 or NaN).
std::complex<double> Faddeeva(double x, double y);

// The three approximations, unchecked, for tests and inner loops (y >= 0).
std::complex<double> FaddeevaWeideman32(double x, double y);
std::complex<double> FaddeevaContinuedFraction4(double x, double y);
std::complex<double> FaddeevaContinuedFraction2(double x, double y);

// Normalised Voigt profile [cm] at dnu_cm1 from the line centre, for a
// Doppler HWHM gamma_doppler_cm1 > 0 and Lorentz HWHM gamma_lorentz_cm1 >= 0.
double VoigtProfile(double dnu_cm1, double gamma_doppler_cm1, double gamma_lorentz_cm1);

// Adds `scale` x V(nu[j] - centre) to out[j] for j in [0, n); the kernels
// behind the cross-section, exposed for tests. `alpha` = gamma_D/sqrt(ln 2).
// Weideman region:
void AddVoigtWeideman(const double* nu, std::size_t n, double centre, double alpha,
                      double gamma_lorentz, double scale, double* out);
// Continued-fraction (4th convergent) region:
void AddVoigtContinuedFraction4(const double* nu, std::size_t n, double centre, double alpha,
                                double gamma_lorentz, double scale, double* out);
// Far wings (2nd convergent, closed form):
void AddVoigtFarWing(const double* nu, std::size_t n, double centre, double alpha,
                     double gamma_lorentz, double scale, double* out);

}  // namespace qogi
