// Interpolation weights: Keys' cubic (the image warps of the registration
// and the velocimetry modules) and Lagrange's with their derivatives (the
// cross-section tables' temperature stencils).
#pragma once

namespace qogi {

// Keys' cubic convolution (Catmull-Rom, a = -0.5, exact for quadratics)
// weights w[0..3] of the four taps x0 - 1 .. x0 + 2 at fraction t = x - x0
// in [0, 1) (R. Keys, "Cubic convolution interpolation for digital image
// processing", IEEE Trans. ASSP 29, 1981). T is float or double; the
// arithmetic is T's.
template <typename T>
inline void CubicWeights(T t, T w[4]) {
  const T t2 = t * t, t3 = t2 * t;
  w[0] = T(-0.5) * t3 + t2 - T(0.5) * t;
  w[1] = T(1.5) * t3 - T(2.5) * t2 + T(1.0);
  w[2] = T(-1.5) * t3 + T(2.0) * t2 + T(0.5) * t;
  w[3] = T(0.5) * t3 - T(0.5) * t2;
}

// Lagrange weights w[k] of the `count` nodes x[0..count-1] at t (sum_k w[k]
// f(x[k]) is the polynomial through the nodes at t) and their derivatives
// dw[k] = dw[k]/dt, accumulated by the product rule.
inline void LagrangeWeights(const double* x, int count, double t, double* w, double* dw) {
  for (int k = 0; k < count; ++k) {
    const double xk = x[k];
    double wk = 1.0, dwk = 0.0;
    for (int m = 0; m < count; ++m) {
      if (m == k) continue;
      const double xm = x[m];
      const double f = (t - xm) / (xk - xm);
      dwk = dwk * f + wk / (xk - xm);
      wk *= f;
    }
    w[k] = wk;
    dw[k] = dwk;
  }
}

}  // namespace qogi
