#include "engine/flux/surface_flux.h"

#include <cmath>
#include <limits>
#include <numeric>

#include "engine/util/check.h"

namespace qogi {

void SurfaceFluxOptions::Check() const {
  CheckNonNegative(molar_mass_kg_mol, "molar_mass_kg_mol", "kg/mol");
}

double SurfaceRate::column_variance() const {
  return std::accumulate(rate_variance.begin(), rate_variance.end(), 0.0);
}

SurfaceRate SurfaceFluxRate(const double* column, const double* column_sigma,
                            const double* normal_velocity, const double* length_m,
                            std::size_t frames, std::size_t samples,
                            const SurfaceFluxOptions& options) {
  options.Check();
  Require(frames == 0 || samples == 0 || (column && normal_velocity && length_m),
          "column, normal_velocity and length_m must not be null");
  const double m = options.molar_mass_kg_mol > 0 ? options.molar_mass_kg_mol : 1.0;
  SurfaceRate out;
  out.rate.assign(frames, 0.0);
  out.samples.assign(frames, 0);
  out.rate_variance.assign(frames, 0.0);
  for (std::size_t t = 0; t < frames; ++t) {
    const double* c = column + t * samples;
    const double* v = normal_velocity + t * samples;
    double rate = 0.0, var = 0.0;
    int good = 0;
    for (std::size_t i = 0; i < samples; ++i) {
      const bool finite = std::isfinite(c[i]);
      good += finite;
      // 0 x a non-finite velocity is NaN: such a frame's rate is unknown.
      rate += (finite ? c[i] * m : 0.0) * v[i] * length_m[i];
      if (column_sigma) {
        const double vs =
            (std::isfinite(v[i]) ? v[i] : 0.0) * column_sigma[t * samples + i] * m * length_m[i];
        var += vs * vs;
      }
    }
    out.rate[t] = good ? rate : std::numeric_limits<double>::quiet_NaN();
    out.samples[t] = good;
    out.rate_variance[t] = var;
  }
  return out;
}

}  // namespace qogi
