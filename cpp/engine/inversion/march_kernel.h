// The layer scheme of march.h for many bins at once, as the per-scene table
// needs it: the emission march (source D = Bbar(T(s))) and the absorptance
// march (D = 1) share each layer's optical depth, so they advance together.
//
// The loop is compiled for AVX2/FMA and for plain x86-64 (GCC function
// multiversioning picks at run time) with an exponential that vectorises
// (Cody-Waite reduction and a degree-12 Taylor polynomial, within 2 ulp of
// std::exp; tested), so that the table builds in seconds.
#pragma once

#include <cstddef>

namespace qogi {

// exp(-x) for x >= 0 (any x > 708 gives 0), within 2 ulp of std::exp.
double ExpNegative(double x);

// One layer for n bins: optical depth tau = u (k_far + k_near) ds / 2 and
//   de <- de t + d_near tau f + (d_far - d_near)(f - t)
//         + (d_far - d_near)(u k_far - u k_near) ds f^2 / 4,
//   da <- da t + tau f,
// with f = (1 - e^-tau) / tau (its series below tau = 1e-4) and t = 1 - tau f,
// exactly the arithmetic of MarchLayer (march.h) with kappa = u k.
void MarchLayerPair(std::size_t n, const double* k_far, const double* k_near, const double* d_far,
                    const double* d_near, double u, double ds, double* de, double* da);

// The same layer, marched over the first half of a path that is symmetric
// about its middle (a Gaussian plume's line of sight), also accumulating
// what the mirrored second half contributes: with p the transmittance of
// the layers already marched (1 at the start),
//   eb <- eb + p (d_far tau f - (d_far - d_near)(f - t)
//                 + (d_far - d_near)(u k_far - u k_near) ds f^2 / 4),
//   ab <- ab + p tau f,   p <- p t,
// (the mirrored layer's emission towards the observer is this layer's with
// its ends swapped). After the half: emission = de p + eb, absorptance =
// da p + ab, equal to marching the whole path to rounding, at half the
// layers.
void MarchLayerPairSymmetric(std::size_t n, const double* k_far, const double* k_near,
                             const double* d_far, const double* d_near, double u, double ds,
                             double* de, double* da, double* p, double* eb, double* ab);

}  // namespace qogi
