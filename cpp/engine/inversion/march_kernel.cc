#include "engine/inversion/march_kernel.h"

#include <cstdint>
#include <cstring>

#include "engine/util/portability.h"

namespace qogi {
namespace {

// exp(-x), x >= 0: n = round(-x / ln 2), r = -x - n ln 2 in [-ln2/2, ln2/2]
// (ln 2 split in two parts, Cody-Waite), exp(r) by its Taylor series to r^12
// (truncation < 2e-16 relative), times 2^n built in the exponent bits.
QOGI_ALWAYS_INLINE double ExpNeg(double x) {
  const double kLog2e = 1.4426950408889634;
  const double kLn2Hi = 6.93147180369123816490e-01;
  const double kLn2Lo = 1.90821492927058770002e-10;
  const double kShift = 6755399441055744.0;  // 1.5 * 2^52: rounds to an integer
  x = x < 708.0 ? x : 708.0;
  const double t = -x * kLog2e;
  const double shifted = t + kShift;
  const double n = shifted - kShift;
  const double r = (-x - n * kLn2Hi) - n * kLn2Lo;
  double p = 1.0 / 479001600.0;
  p = p * r + 1.0 / 39916800.0;
  p = p * r + 1.0 / 3628800.0;
  p = p * r + 1.0 / 362880.0;
  p = p * r + 1.0 / 40320.0;
  p = p * r + 1.0 / 5040.0;
  p = p * r + 1.0 / 720.0;
  p = p * r + 1.0 / 120.0;
  p = p * r + 1.0 / 24.0;
  p = p * r + 1.0 / 6.0;
  p = p * r + 0.5;
  p = p * r + 1.0;
  p = p * r + 1.0;
  // 2^n: the low bits of `shifted` hold n (two's complement).
  std::int64_t bits;
  std::memcpy(&bits, &shifted, sizeof bits);
  const std::int64_t e = (bits + 1023) << 52;
  double scale;
  std::memcpy(&scale, &e, sizeof scale);
  const double v = p * scale;
  return x < 708.0 ? v : 0.0;
}

// One layer of optical depth tau = (a + b) ds / 2: f = (1 - e^-tau) / tau
// (its series below tau = 1e-4) and the transmittance t = 1 - tau f. Both
// branches are computed (the division is safe), so the select vectorises.
struct Layer {
  double tau, f, t;
};
QOGI_ALWAYS_INLINE Layer LayerOf(double a, double b, double ds) {
  const double tau = 0.5 * (a + b) * ds;
  const double e = ExpNeg(tau);
  const double series = 1.0 - tau * (0.5 - tau * (1.0 / 6.0));
  const double exact = (1.0 - e) / (tau > 1e-300 ? tau : 1e-300);
  const double f = tau < 1e-4 ? series : exact;
  return {tau, f, 1.0 - tau * f};
}

}  // namespace

double ExpNegative(double x) { return ExpNeg(x); }

#define QOGI_MARCH_CLONES QOGI_TARGET_CLONES("arch=x86-64-v4", "arch=x86-64-v3", "default")

QOGI_MARCH_CLONES
void MarchLayerPair(std::size_t n, const double* QOGI_RESTRICT kf, const double* QOGI_RESTRICT kn,
                    const double* QOGI_RESTRICT df, const double* QOGI_RESTRICT dn, double u,
                    double ds, double* QOGI_RESTRICT de, double* QOGI_RESTRICT da) {
  for (std::size_t j = 0; j < n; ++j) {
    const double a = u * kf[j], b = u * kn[j];
    const Layer l = LayerOf(a, b, ds);
    const double f = l.f, t = l.t;
    const double dd = df[j] - dn[j];
    de[j] = de[j] * t + dn[j] * (l.tau * f) + dd * (f - t) + 0.25 * dd * (a - b) * ds * (f * f);
    da[j] = da[j] * t + l.tau * f;
  }
}

QOGI_MARCH_CLONES
void MarchLayerPairSymmetric(std::size_t n, const double* QOGI_RESTRICT kf,
                             const double* QOGI_RESTRICT kn, const double* QOGI_RESTRICT df,
                             const double* QOGI_RESTRICT dn, double u, double ds,
                             double* QOGI_RESTRICT de, double* QOGI_RESTRICT da,
                             double* QOGI_RESTRICT p, double* QOGI_RESTRICT eb,
                             double* QOGI_RESTRICT ab) {
  for (std::size_t j = 0; j < n; ++j) {
    const double a = u * kf[j], b = u * kn[j];
    const Layer l = LayerOf(a, b, ds);
    const double f = l.f, t = l.t;
    const double tf = l.tau * f;
    const double dd = df[j] - dn[j];
    const double q = 0.25 * dd * (a - b) * ds * (f * f);
    de[j] = de[j] * t + dn[j] * tf + dd * (f - t) + q;
    da[j] = da[j] * t + tf;
    const double pj = p[j];
    eb[j] += pj * (df[j] * tf - dd * (f - t) + q);
    ab[j] += pj * tf;
    p[j] = pj * t;
  }
}

}  // namespace qogi
