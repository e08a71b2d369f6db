// Temporal detector noise from a camera's NETD, in radiance units.
//
// The noise-equivalent temperature difference (NETD) is the scene temperature
// change that gives a signal equal to the temporal noise. Around a scene whose
// channel-c band radiance is that of a blackbody at T_bg,c, the additive
// Gaussian noise on the band radiance therefore has the standard deviation
//
//   sigma_L,c = NETD_c x dL_c/dT (T_bg,c)          [W/(m2 sr)]
//
// with L_c(T) = integral r_c(nu) B(nu, T) dnu (thesis eq. 14). Each value of a
// frame stack gets an independent N(0, sigma_L,c) draw.
//
// Reproducibility: draw i of a stack comes from a counter-based generator (the
// SplitMix64 output at position i of the stream keyed by the seed, paired by
// Box-Muller), so the noise depends only on (seed, element index): not on the
// number of threads or on how the stack is split into calls (see `offset`).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/optics/spectral_response.h"
#include "engine/util/parallel.h"

namespace qogi {

// sigma_L [W/(m2 sr)] of one channel: NETD [K] (> 0) x dL/dT at
// background_temperature_K (> 0).
double NetdRadianceSigma(const SpectralResponse& channel, double netd_K,
                         double background_temperature_K);

// Adds N(0, sigma_L[c]) noise in place to frames laid out (T, C, H, W),
// row-major, with C = sigma_L.size() and pixels_per_frame = H x W.
// sigma_L: per-channel standard deviations [W/(m2 sr)], finite and >= 0.
// offset: index of frames[0] in the seed's stream, so that noising a long
// stack in pieces (offset = elements already done) gives the same noise as one
// call. NaN values stay NaN.
void AddGaussianNoise(float* frames, std::size_t num_frames, std::size_t pixels_per_frame,
                      const std::vector<double>& sigma_L, std::uint64_t seed,
                      std::uint64_t offset = 0, int num_threads = 0,
                      const RunControl* control = nullptr);

// The standard normal draw number `index` of the stream keyed by `seed`
// (what AddGaussianNoise adds, divided by sigma).
double StandardNormalDraw(std::uint64_t seed, std::uint64_t index);

}  // namespace qogi
