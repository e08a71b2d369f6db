#include "engine/camera/noise.h"

#include <cmath>
#include <string>

#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

constexpr std::uint64_t kGamma = 0x9E3779B97F4A7C15ULL;

// SplitMix64's output function (Steele, Lea & Flood, OOPSLA 2014).
inline std::uint64_t Mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// The stream keyed by `seed`: output j is Mix(key + (j + 1) gamma).
inline std::uint64_t Key(std::uint64_t seed) { return Mix(seed + kGamma); }
inline std::uint64_t Output(std::uint64_t key, std::uint64_t j) {
  return Mix(key + (j + 1) * kGamma);
}

// Box-Muller on outputs (2p, 2p + 1): draws 2p (cosine) and 2p + 1 (sine).
inline void NormalPair(std::uint64_t key, std::uint64_t p, double* z0, double* z1) {
  // u1 in (0, 1], u2 in [0, 1), 53-bit resolution.
  const double u1 = (static_cast<double>(Output(key, 2 * p) >> 11) + 1.0) * 0x1.0p-53;
  const double u2 = static_cast<double>(Output(key, 2 * p + 1) >> 11) * 0x1.0p-53;
  const double r = std::sqrt(-2.0 * std::log(u1));
  const double a = 2.0 * constants::kPi * u2;
  *z0 = r * std::cos(a);
  *z1 = r * std::sin(a);
}

}  // namespace

double NetdRadianceSigma(const SpectralResponse& channel, double netd_K,
                         double background_temperature_K) {
  CheckPositive(netd_K, "netd_K", "K");
  CheckPositive(background_temperature_K, "background_temperature_K", "K");
  return netd_K * channel.BandRadianceDerivative(background_temperature_K);
}

double StandardNormalDraw(std::uint64_t seed, std::uint64_t index) {
  double z0, z1;
  NormalPair(Key(seed), index / 2, &z0, &z1);
  return index % 2 == 0 ? z0 : z1;
}

void AddGaussianNoise(float* frames, std::size_t num_frames, std::size_t pixels_per_frame,
                      const std::vector<double>& sigma_L, std::uint64_t seed, std::uint64_t offset,
                      int num_threads, const RunControl* control) {
  Require(!sigma_L.empty(), "sigma_L must have one value per channel; got none");
  Require(pixels_per_frame > 0, "pixels_per_frame must be > 0");
  for (std::size_t c = 0; c < sigma_L.size(); ++c)
    Require(std::isfinite(sigma_L[c]) && sigma_L[c] >= 0,
            "sigma_L[" + std::to_string(c) + "] must be finite and >= 0 W/(m2 sr); got " +
                FormatNumber(sigma_L[c]));
  const std::size_t nc = sigma_L.size();
  const std::size_t n = num_frames * nc * pixels_per_frame;
  if (n == 0) return;
  const std::uint64_t key = Key(seed);
  // Chunks start on even global indices so that pairs never straddle chunks.
  const std::size_t chunk = 1 << 15;
  const std::size_t lead = offset % 2;  // first element is the sine of its pair
  ParallelFor((n + lead + chunk - 1) / chunk, 1,
              [&](std::size_t cb, std::size_t ce) {
                for (std::size_t ck = cb; ck < ce; ++ck) {
                  // Local indices [b, e) of this chunk in the caller's array.
                  const std::size_t gb = ck * chunk, ge = std::min(n + lead, gb + chunk);
                  std::size_t i = gb > lead ? gb - lead : 0;
                  const std::size_t e = ge - lead;
                  while (i < e) {
                    const std::uint64_t g = offset + i;  // global draw index
                    double z0, z1;
                    NormalPair(key, g / 2, &z0, &z1);
                    const std::size_t c = (i / pixels_per_frame) % nc;
                    if (g % 2 == 0) {
                      frames[i] += static_cast<float>(sigma_L[c] * z0);
                      if (i + 1 < e) {
                        const std::size_t c1 = ((i + 1) / pixels_per_frame) % nc;
                        frames[i + 1] += static_cast<float>(sigma_L[c1] * z1);
                      }
                      i += 2;
                    } else {
                      frames[i] += static_cast<float>(sigma_L[c] * z1);
                      i += 1;
                    }
                  }
                }
              },
              num_threads, control);
}

}  // namespace qogi
