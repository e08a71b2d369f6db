// Rendering many lines of sight at once (the synthetic camera).
//
// Each ray is a run of gas samples at uniform spacing, ordered from the
// background towards the camera (as qogi::synth::SampleRays produces them);
// the gas-free air around them is at the ambient temperature. A node at the
// ambient state is added one step beyond each end, so the layer scheme
// integrates the samples' optical depth exactly as the midpoint sum the
// ground-truth columns use.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/rte/binned_model.h"
#include "engine/util/parallel.h"

namespace qogi {

struct RayBatch {
  std::size_t num_rays = 0;
  const std::int64_t* offset = nullptr;   // (num_rays + 1) sample ranges
  const float* step_m = nullptr;          // (num_rays) sample spacing [m]
  const float* temperature_K = nullptr;   // (samples) [K]
  std::vector<const float*> fraction;     // per model species: (samples) volume fraction
};

// Contrast Delta L = L - L_bg [W/(m2 sr)] of every ray and channel into
// out[ray * channels + c]. background_temperature_K holds one value per
// channel (stride 0) or per ray and channel (stride = channels).
void RenderContrast(const BinnedModel& model, const RayBatch& rays, double ambient_temperature_K,
                    const double* background_temperature_K, std::size_t background_stride,
                    float* out, int num_threads = 0, const RunControl* control = nullptr);

}  // namespace qogi
