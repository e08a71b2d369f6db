#include "engine/rte/render.h"

#include <string>

#include "engine/util/check.h"

namespace qogi {

void RenderContrast(const BinnedModel& model, const RayBatch& rays, double t_amb,
                    const double* t_bg, std::size_t bg_stride, float* out, int num_threads,
                    const RunControl* control) {
  const std::size_t ns = model.num_species();
  Require(rays.fraction.size() == ns, "RenderContrast: the rays carry " +
                                          std::to_string(rays.fraction.size()) +
                                          " species; the model has " + std::to_string(ns));
  ParallelFor(
      rays.num_rays, 256,
      [&](std::size_t b, std::size_t e) {
        model.RenderRays(b, e, rays.offset, rays.step_m, rays.temperature_K, rays.fraction, t_amb,
                         t_bg, bg_stride, out);
      },
      num_threads, control);
}

}  // namespace qogi
