// The layer scheme shared by the exact and the fast forward models.
//
// The integral form of the radiative transfer equation (thesis eq. 5) is
// solved in contrast form, Delta L = L - B(T_bg), node by node from the
// background (node 0) to the camera. Between two nodes the absorption
// coefficient kappa [1/m] is taken trapezoidal (tau = (k_far + k_near) ds / 2)
// and the source difference D = B(T) - B(T_bg) linear in optical depth, which
// is exact for opaque layers (the camera sees the near node) and, with the
// product-rule correction term below, reduces to the trapezoid rule for
// int D kappa ds in the optically thin limit (spectrally accurate for smooth,
// Gaussian-decaying plumes). Per layer:
//   f = (1 - e^-tau) / tau,  t = 1 - tau f
//   dL <- dL t + D_near tau f + (D_far - D_near)(f - t)
//        + (D_far - D_near)(k_far - k_near) ds f^2 / 4
// The correction carries a factor f^2 so that it vanishes for opaque layers,
// where the camera must see exactly the near node. The scheme is second-order
// accurate; the fast model combines two node spacings (Richardson) for more.
// An isothermal path at T_bg gives D = 0 and therefore exactly zero contrast.
#pragma once

#include <cmath>
#include <cstddef>

namespace qogi {

template <typename S>
inline S LayerEscapeFactor(const S& tau) {
  using std::exp;
  // (1 - exp(-tau)) / tau, with its series below tau = 1e-4 (error < 1e-17).
  if (tau < 1e-4) return 1.0 - tau * (0.5 - tau * (1.0 / 6.0));
  return (1.0 - exp(-tau)) / tau;
}

// One layer for one spectral point.
template <typename S>
inline S MarchLayer(const S& dl, const S& k_far, const S& k_near, const S& d_far, const S& d_near,
                    const S& ds) {
  const S tau = 0.5 * (k_far + k_near) * ds;
  const S f = LayerEscapeFactor(tau);
  const S t = 1.0 - tau * f;
  const S dd = d_far - d_near;
  return dl * t + d_near * (tau * f) + dd * (f - t) + 0.25 * dd * (k_far - k_near) * ds * (f * f);
}

// One layer for n spectral points (a loop the compiler can vectorise for S = double).
inline void MarchLayer(std::size_t n, const double* k_far, const double* k_near,
                       const double* d_far, const double* d_near, double ds, double* dl) {
  for (std::size_t i = 0; i < n; ++i) {
    const double tau = 0.5 * (k_far[i] + k_near[i]) * ds;
    const double e = std::exp(-tau);
    const double f = tau < 1e-4 ? 1.0 - tau * (0.5 - tau * (1.0 / 6.0)) : (1.0 - e) / tau;
    const double t = 1.0 - tau * f;
    const double dd = d_far[i] - d_near[i];
    dl[i] = dl[i] * t + d_near[i] * (tau * f) + dd * (f - t) +
            0.25 * dd * (k_far[i] - k_near[i]) * ds * (f * f);
  }
}

}  // namespace qogi
