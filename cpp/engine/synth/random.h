// Counter-based random numbers for the synthetic plume.
//
// Every random quantity is a pure function of (seed, stream, index), so a run
// is reproducible for a given seed regardless of thread count, platform or the
// order in which puffs are processed. The mixer is SplitMix64 (Steele, Lea &
// Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014);
// normals use the Box-Muller transform (std::normal_distribution is
// implementation-defined, hence not used).
#pragma once

#include <cmath>
#include <cstdint>

namespace qogi::synth {

// SplitMix64 finaliser: a bijective 64-bit mixing function.
inline std::uint64_t Mix64(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// 64 random bits for (seed, stream, index).
inline std::uint64_t RandomBits(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) {
  return Mix64(Mix64(Mix64(seed) ^ stream) ^ index);
}

// Uniform in (0, 1), never exactly 0 or 1 (53 random bits).
inline double Uniform(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) {
  return (static_cast<double>(RandomBits(seed, stream, index) >> 11) + 0.5) *
         (1.0 / 9007199254740992.0);
}

// Standard normal for (seed, stream, index) by Box-Muller.
inline double Normal(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) {
  const double u1 = Uniform(seed, stream, 2 * index);
  const double u2 = Uniform(seed, stream, 2 * index + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

}  // namespace qogi::synth
