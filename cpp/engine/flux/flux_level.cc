#include "engine/flux/flux_level.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "engine/util/check.h"

namespace qogi {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// For each of n lines, the nearest index i with ok[i] (the lower one on a
// tie); throws when there is none.
std::vector<std::size_t> NearestValid(const std::vector<char>& ok, const char* what) {
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < ok.size(); ++i)
    if (ok[i]) idx.push_back(i);
  Require(!idx.empty(), what);
  std::vector<std::size_t> out(ok.size());
  std::size_t j = 0;
  for (std::size_t i = 0; i < ok.size(); ++i) {
    while (j + 1 < idx.size() && idx[j + 1] <= i) ++j;
    std::size_t best = idx[j];
    if (idx[j] < i && j + 1 < idx.size() && idx[j + 1] - i < i - idx[j]) best = idx[j + 1];
    out[i] = best;
  }
  return out;
}

double NanMax(const std::vector<double>& v) {  // numpy.nanmax (NaN when all are)
  double m = kNaN;
  for (double x : v)
    if (!std::isnan(x) && (std::isnan(m) || x > m)) m = x;
  return m;
}

// Python's max(m, floor): m itself when it is NaN.
double AtLeast(double m, double floor) { return std::isnan(m) ? m : std::max(m, floor); }

}  // namespace

void FluxLevelOptions::Check() const {
  CheckNonNegative(smooth_px, "smooth_px", "lines");
  Require(min_fraction > 0 && min_fraction < 1,
          "min_fraction must be in (0, 1); got " + FormatNumber(min_fraction));
  Require(max_factor > 1, "max_factor must be > 1; got " + FormatNumber(max_factor));
  Require(max_reversed > 0 && max_reversed <= 1,
          "max_reversed must be in (0, 1]; got " + FormatNumber(max_reversed));
}

FluxLevel FlowFluxLevel(const float* frames, const float* u, const float* v, std::size_t T,
                        std::size_t H, std::size_t W, const TransportFluxResult& transport,
                        const FluxLevelOptions& options, const RunControl* control) {
  options.Check();
  const FluxAxis axis = options.axis;
  const bool rows = AlongRows(axis);
  const std::size_t n = rows ? H : W;
  Require(T >= 1 && frames && u && v, "frames, u and v must be non-empty (T, H, W) stacks");
  Require(transport.axis == axis && transport.flux.size() == n,
          std::string("transport must be along '") + FluxAxisName(axis) +
              "' with one value per line of the frames (" + std::to_string(n) + "); got '" +
              FluxAxisName(transport.axis) + "' with " + std::to_string(transport.flux.size()));

  // The flow's time-averaged flux along the axis per line (the products in
  // float, as the frames and velocities are, summed in double).
  const float* comp = rows ? v : u;
  const double sign = axis == FluxAxis::kUp || axis == FluxAxis::kLeft ? -1.0 : 1.0;
  // Per line also the frames' flux against the axis and in all (|flux|
  // summed over frames), for the reversed fraction.
  std::vector<double> flow(n, 0.0), against(n, 0.0), total(n, 0.0);
  ParallelFor(
      n, 8,
      [&](std::size_t l0, std::size_t l1) {
        for (std::size_t t = 0; t < T; ++t) {
          const float* f = frames + t * H * W;
          const float* c = comp + t * H * W;
          for (std::size_t l = l0; l < l1; ++l) {
            double s = 0.0;
            if (rows) {
              for (std::size_t x = 0; x < W; ++x) s += double(f[l * W + x] * c[l * W + x]);
            } else {
              for (std::size_t y = 0; y < H; ++y) s += double(f[y * W + l] * c[y * W + l]);
            }
            flow[l] += s;
            if (std::isfinite(s)) {
              total[l] += std::abs(s);
              if (sign * s < 0) against[l] += -sign * s;
            }
          }
        }
      },
      options.num_threads, control);
  for (double& x : flow) x *= sign / double(T);

  const std::vector<double>& tf = transport.flux;
  double tf_max = 0.0;
  bool any_finite = false;
  for (double x : tf) {
    const double y = std::isfinite(x) ? x : 0.0;
    tf_max = any_finite ? std::max(tf_max, y) : y;
    any_finite = true;
  }
  std::vector<char> carries(n), good(n);
  std::size_t n_carries = 0, n_good = 0;
  std::vector<double> abs_flow(n);
  for (std::size_t l = 0; l < n; ++l) abs_flow[l] = std::abs(flow[l]);
  const double flow_floor = options.min_fraction * AtLeast(NanMax(abs_flow), 1e-300);
  std::vector<double> ratio(n, 0.0);
  for (std::size_t l = 0; l < n; ++l) {
    carries[l] = std::isfinite(tf[l]) && tf[l] > options.min_fraction * std::max(tf_max, 1e-300);
    n_carries += carries[l];
    good[l] = carries[l] && flow[l] > flow_floor;
    if (good[l]) ratio[l] = tf[l] / flow[l];
    good[l] = good[l] && ratio[l] >= 1.0 / options.max_factor && ratio[l] <= options.max_factor;
    // The transport runs along the axis on a carrying line (tf > 0): flux
    // the other way is the flow's.
    good[l] = good[l] && against[l] <= options.max_reversed * total[l];
    if (!good[l]) ratio[l] = 0.0;
    n_good += good[l];
  }
  Require(n_carries > 0,
          "no line carries a flux along the axis in the transport of the frames; check axis "
          "and source_index");
  FluxLevel out;
  if (double(n_good) < 0.5 * double(n_carries)) {
    out.scale.assign(n, std::numeric_limits<float>::quiet_NaN());
    return out;
  }
  std::vector<double> smooth(n, kNaN);
  std::vector<char> finite(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (options.smooth_px > 0) {
      double w = 0.0, s = 0.0;
      for (std::size_t j = 0; j < n; ++j) {
        const double z = (double(i) - double(j)) / options.smooth_px;
        const double k = std::exp(-0.5 * z * z) * double(good[j]);
        w += k;
        s += k * ratio[j];
      }
      if (w > 1e-6) smooth[i] = s / std::max(w, 1e-300);
    } else if (good[i]) {
      smooth[i] = ratio[i];
    }
    finite[i] = std::isfinite(smooth[i]);
  }
  const std::vector<std::size_t> nearest =
      NearestValid(finite, "no line has a finite flux-level factor");
  out.scale.resize(n);
  // A line that carries the transport where the flow does not measure it
  // takes the transport's own velocity (NaN), not a neighbour's factor.
  for (std::size_t i = 0; i < n; ++i)
    out.scale[i] = carries[i] && !good[i] ? std::numeric_limits<float>::quiet_NaN()
                                          : float(smooth[nearest[i]]);
  out.flow_used = true;
  return out;
}

void ApplyFluxLevel(const TransportFluxResult& transport, const std::vector<float>& scale,
                    std::size_t T, std::size_t H, std::size_t W, float* u, float* v,
                    int num_threads) {
  const bool rows = AlongRows(transport.axis);
  const std::size_t n = rows ? H : W;
  Require(scale.size() == n, "scale must hold one factor per line (" + std::to_string(n) +
                                 "); got " + std::to_string(scale.size()));
  std::vector<char> replaced(n);
  bool any = false;
  for (std::size_t i = 0; i < n; ++i) {
    replaced[i] = std::isnan(scale[i]);
    if (replaced[i]) any = true;
  }
  // The transport's velocity along the axis, for the replaced lines.
  std::vector<float> along(n, 0.0f);
  if (any) {
    Require(transport.velocity.size() == n && transport.line_column.size() == n,
            "transport must have one velocity and line column per line of the frames (" +
                std::to_string(n) + "); got " + std::to_string(transport.velocity.size()));
    std::vector<char> ok(n);
    for (std::size_t i = 0; i < n; ++i)
      ok[i] = std::isfinite(transport.velocity[i]) && transport.line_column[i] > 0;
    const std::vector<std::size_t> nearest =
        NearestValid(ok, "the transport has no line with a velocity and gas");
    const double sign =
        transport.axis == FluxAxis::kUp || transport.axis == FluxAxis::kLeft ? -1.0 : 1.0;
    for (std::size_t i = 0; i < n; ++i) along[i] = float(sign * transport.velocity[nearest[i]]);
  }
  float* across_axis = rows ? u : v;
  float* on_axis = rows ? v : u;
  ParallelFor(
      T, 1,
      [&](std::size_t t0, std::size_t t1) {
        for (std::size_t t = t0; t < t1; ++t)
          for (std::size_t y = 0; y < H; ++y)
            for (std::size_t x = 0; x < W; ++x) {
              const std::size_t l = rows ? y : x;
              const std::size_t i = (t * H + y) * W + x;
              if (replaced[l]) {
                across_axis[i] = 0.0f;
                on_axis[i] = along[l];
              } else {
                u[i] *= scale[l];
                v[i] *= scale[l];
              }
            }
      },
      num_threads);
}

void TransportVelocity(const TransportFluxResult& transport, std::size_t T, std::size_t H,
                       std::size_t W, float* u, float* v) {
  const std::size_t n = AlongRows(transport.axis) ? H : W;
  ApplyFluxLevel(transport, std::vector<float>(n, std::numeric_limits<float>::quiet_NaN()), T, H, W,
                 u, v, 1);
}

FluxLevel CalibrateFluxLevel(const float* frames, float* u, float* v, std::size_t T, std::size_t H,
                             std::size_t W, const TransportFluxResult& transport,
                             const FluxLevelOptions& options, const RunControl* control) {
  FluxLevel level = FlowFluxLevel(frames, u, v, T, H, W, transport, options, control);
  ApplyFluxLevel(transport, level.scale, T, H, W, u, v, options.num_threads);
  return level;
}

}  // namespace qogi
