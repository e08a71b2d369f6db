// The flux level of a 2-D velocity field taken from the transport flux: per
// line across the axis, the factor that makes the flow's time-averaged flux
// equal the transport's (smoothed along the axis, only where the flow
// measures the transport at all), or, on the lines that carry the transport
// where it does not, the transport's own line velocity in place of the flow.
#pragma once

#include <cstddef>
#include <vector>

#include "engine/flux/transport_flux.h"
#include "engine/util/parallel.h"

namespace qogi {

struct FluxLevelOptions {
  // Direction of the plume's transport in the image.
  FluxAxis axis = FluxAxis::kUp;
  // Gaussian sigma [lines] of the factors' smoothing along the axis
  // (default 2; 0 = none).
  double smooth_px = 2.0;
  // Lines carrying less than this fraction of the largest flux get the
  // factor of the nearest line that does (default 0.05, in (0, 1)).
  double min_fraction = 0.05;
  // A line's factor is used within [1 / max_factor, max_factor] only
  // (default 2.5, > 1).
  double max_factor = 2.5;
  // A line's factor is used only when at most this fraction of the flow's
  // frame-by-frame flux through it (sum over frames of |flux|) runs against
  // the transport: a flow that reverses for stretches of the record (lost a
  // crosswind of ~20 px per frame for 50 of 150 frames) does not measure
  // the transport there, even when its time average happens to land within
  // max_factor. The lab plumes' flows read 0-0.06 per line (90th
  // percentile), flows that lost the outdoor crosswind 0.21-0.27 (median;
  // docs/velocimetry.md). Default 0.1, in (0, 1].
  double max_reversed = 0.1;
  // Worker threads (0 = all cores).
  int num_threads = 0;

  void Check() const;
};

struct FluxLevel {
  // Factor per line (rows for kUp/kDown, columns otherwise). NaN on the
  // lines whose velocity is the transport's own: the lines carrying the
  // transport flux whose factor is unusable (beyond max_factor, or a flow
  // reversing there: near a source the fluid flow ramps up from zero while
  // the gas crosses at the wind's speed, and a neighbour's factor read a
  // crosswind 60 % low there); every line when the flow was not used.
  std::vector<float> scale;
  // False when fewer than half of the lines carrying the transport flux had a
  // usable factor: the transport's line velocity replaces the flow.
  bool flow_used = false;
};

// The factors for velocities (u, v) [px/frame] at the times of the T frames
// (each (T, H, W) row-major) against `transport` (one value per line). Does
// not modify its inputs. Throws std::invalid_argument when no line carries a
// flux along the axis.
FluxLevel FlowFluxLevel(const float* frames, const float* u, const float* v, std::size_t T,
                        std::size_t H, std::size_t W, const TransportFluxResult& transport,
                        const FluxLevelOptions& options = {}, const RunControl* control = nullptr);

// Applies a flux level to u and v (T, H, W) in place, line by line along
// the transport's axis: a line with a finite `scale` is multiplied by it; a
// line whose scale is NaN takes the transport's time-averaged line velocity
// along the axis at every pixel and frame [px/frame] (extended to lines
// without one from the nearest line that has one), the other component 0.
void ApplyFluxLevel(const TransportFluxResult& transport, const std::vector<float>& scale,
                    std::size_t T, std::size_t H, std::size_t W, float* u, float* v,
                    int num_threads = 0);

// The transport's line velocity at every line (ApplyFluxLevel with every
// scale NaN).
void TransportVelocity(const TransportFluxResult& transport, std::size_t T, std::size_t H,
                       std::size_t W, float* u, float* v);

// FlowFluxLevel, then ApplyFluxLevel on u and v in place.
FluxLevel CalibrateFluxLevel(const float* frames, float* u, float* v, std::size_t T, std::size_t H,
                             std::size_t W, const TransportFluxResult& transport,
                             const FluxLevelOptions& options = {},
                             const RunControl* control = nullptr);

}  // namespace qogi
