// Catmull-Rom cubic interpolation weights, shared by the image warps of the
// registration and the velocimetry modules.
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

}  // namespace qogi
