#include "engine/spectra/cross_section.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "engine/spectra/voigt.h"
#include "engine/util/check.h"

namespace qogi {

void WavenumberGrid::Check() const {
  CheckNonNegative(nu0_cm1, "grid nu0_cm1", "cm-1");
  CheckPositive(step_cm1, "grid step_cm1", "cm-1");
  Require(size >= 1, "grid size must be >= 1; got 0");
}

WavenumberGrid WavenumberGrid::FromRange(double nu_min_cm1, double nu_max_cm1, double step_cm1) {
  CheckNonNegative(nu_min_cm1, "nu_min_cm1", "cm-1");
  CheckPositive(step_cm1, "step_cm1", "cm-1");
  CheckFinite(nu_max_cm1, "nu_max_cm1");
  Require(nu_max_cm1 >= nu_min_cm1, "nu_max_cm1 must be >= nu_min_cm1; got " +
                                        FormatNumber(nu_max_cm1) + " < " +
                                        FormatNumber(nu_min_cm1));
  const double span = (nu_max_cm1 - nu_min_cm1) / step_cm1;
  Require(span < 1e9,
          "the grid would have more than 1e9 points (range / step = " + FormatNumber(span) + ")");
  std::size_t n = static_cast<std::size_t>(std::floor(span)) + 1;
  const double last = nu_min_cm1 + step_cm1 * static_cast<double>(n - 1);
  if (std::abs((nu_max_cm1 - last) - step_cm1) < 1e-10) ++n;
  return {nu_min_cm1, step_cm1, n};
}

void CrossSectionOptions::Check() const {
  CheckNonNegative(wing_half_widths, "wing_half_widths");
  CheckNonNegative(wing_cm1, "wing_cm1", "cm-1");
  Require(wing_half_widths > 0 || wing_cm1 > 0,
          "line wings: wing_half_widths or wing_cm1 must be > 0 (HAPI's rule: "
          "wing_half_widths = 50; a fixed cutoff: wing_cm1 > 0); got both 0");
  CheckNonNegative(min_intensity, "min_intensity", "cm/molecule");
}

namespace {

constexpr std::size_t kChunk = 2048;

struct PreparedLine {
  double window_center;  // unshifted position: centre of the wing window [cm-1]
  double window_half;    // W [cm-1]
  double center;         // profile centre (shifted) [cm-1]
  double alpha;          // gamma_D / sqrt(ln 2) [cm-1]
  double gamma_lorentz;  // [cm-1]
  double intensity;      // S(T) [cm/molecule]
};

struct PreparedLines {
  std::vector<PreparedLine> lines;  // sorted by window_center
  double max_half = 0;
};

PreparedLines Prepare(const LineList& lines, const GasConditions& cond,
                      const CrossSectionOptions& opt) {
  opt.Check();
  const LineParameters par = ComputeLineParameters(lines, cond, opt.line_shift);
  const double inv_sqrt_ln2 = 1.0 / std::sqrt(std::log(2.0));
  PreparedLines out;
  out.lines.reserve(par.size());
  for (std::size_t i = 0; i < par.size(); ++i) {
    const double s = par.intensity[i];
    if (s < opt.min_intensity || s == 0.0) continue;
    const double gl = par.gamma_lorentz[i], gd = par.gamma_doppler[i];
    const double w = std::max(opt.wing_cm1, opt.wing_half_widths * std::max(gl, gd));
    out.lines.push_back({par.nu_cm1[i], w, par.center_cm1[i], gd * inv_sqrt_ln2, gl, s});
    out.max_half = std::max(out.max_half, w);
  }
  auto by_center = [](const PreparedLine& a, const PreparedLine& b) {
    return a.window_center < b.window_center;
  };
  if (!std::is_sorted(out.lines.begin(), out.lines.end(), by_center))
    std::stable_sort(out.lines.begin(), out.lines.end(), by_center);
  return out;
}

// Grid views: the value of point j, and the first index whose value is
// > v (FirstAbove) or >= v (FirstAtOrAbove), in [0, size].
struct UniformView {
  const WavenumberGrid& g;
  std::size_t size() const { return g.size; }
  double at(std::size_t j) const { return g[j]; }
  template <class Pred>
  std::size_t First(double v, Pred beyond) const {
    const double r = std::floor((v - g.nu0_cm1) / g.step_cm1);
    std::size_t j;
    if (r < 0)
      j = 0;
    else if (r >= static_cast<double>(g.size))
      j = g.size;
    else
      j = static_cast<std::size_t>(r);
    while (j > 0 && beyond(at(j - 1), v)) --j;
    while (j < g.size && !beyond(at(j), v)) ++j;
    return j;
  }
  std::size_t FirstAbove(double v) const {
    return First(v, [](double x, double t) { return x > t; });
  }
  std::size_t FirstAtOrAbove(double v) const {
    return First(v, [](double x, double t) { return x >= t; });
  }
};

struct ArrayView {
  const double* nu;
  std::size_t n;
  std::size_t size() const { return n; }
  double at(std::size_t j) const { return nu[j]; }
  std::size_t FirstAbove(double v) const {
    return static_cast<std::size_t>(std::upper_bound(nu, nu + n, v) - nu);
  }
  std::size_t FirstAtOrAbove(double v) const {
    return static_cast<std::size_t>(std::lower_bound(nu, nu + n, v) - nu);
  }
};

template <class View>
void Accumulate(const PreparedLines& prep, const View& grid, double* out,
                const ComputeSettings& settings, const RunControl* control) {
  const std::size_t n = grid.size();
  const auto& lines = prep.lines;
  ParallelFor(
      n, kChunk,
      [&](std::size_t b, std::size_t e) {
        const std::size_t m = e - b;
        std::vector<double> nu(m), acc(m, 0.0);
        for (std::size_t j = 0; j < m; ++j) nu[j] = grid.at(b + j);
        const double lo = nu.front() - prep.max_half, hi = nu.back() + prep.max_half;
        auto first =
            std::lower_bound(lines.begin(), lines.end(), lo,
                             [](const PreparedLine& l, double v) { return l.window_center < v; });
        for (auto it = first; it != lines.end() && it->window_center <= hi; ++it) {
          const PreparedLine& l = *it;
          const std::size_t jlo = std::max(b, grid.FirstAbove(l.window_center - l.window_half));
          const std::size_t jhi = std::min(e, grid.FirstAbove(l.window_center + l.window_half));
          if (jlo >= jhi) continue;
          // Split the window by s = |x| + y into far | mid | centre | mid | far.
          const double y = l.gamma_lorentz / l.alpha;
          const double rf = (kVoigtFarLimit - y) * l.alpha;
          const double rm = (kVoigtCentreLimit - y) * l.alpha;
          std::size_t a1, a2, a3, a4;
          if (rf <= 0) {
            a1 = a2 = a3 = a4 = jhi;
          } else {
            a1 = grid.FirstAbove(l.center - rf);
            a4 = grid.FirstAtOrAbove(l.center + rf);
            if (rm <= 0) {
              a2 = a3 = grid.FirstAbove(l.center);
            } else {
              a2 = grid.FirstAbove(l.center - rm);
              a3 = grid.FirstAtOrAbove(l.center + rm);
            }
          }
          a1 = std::clamp(a1, jlo, jhi);
          a2 = std::clamp(a2, a1, jhi);
          a3 = std::clamp(a3, a2, jhi);
          a4 = std::clamp(a4, a3, jhi);
          const double* x = nu.data() - b;
          double* o = acc.data() - b;
          if (a1 > jlo)
            AddVoigtFarWing(x + jlo, a1 - jlo, l.center, l.alpha, l.gamma_lorentz, l.intensity,
                            o + jlo);
          if (a2 > a1)
            AddVoigtContinuedFraction4(x + a1, a2 - a1, l.center, l.alpha, l.gamma_lorentz,
                                       l.intensity, o + a1);
          if (a3 > a2)
            AddVoigtWeideman(x + a2, a3 - a2, l.center, l.alpha, l.gamma_lorentz, l.intensity,
                             o + a2);
          if (a4 > a3)
            AddVoigtContinuedFraction4(x + a3, a4 - a3, l.center, l.alpha, l.gamma_lorentz,
                                       l.intensity, o + a3);
          if (jhi > a4)
            AddVoigtFarWing(x + a4, jhi - a4, l.center, l.alpha, l.gamma_lorentz, l.intensity,
                            o + a4);
        }
        std::copy(acc.begin(), acc.end(), out + b);
      },
      settings.num_threads, control);
}

}  // namespace

void ComputeCrossSection(const LineList& lines, const GasConditions& conditions,
                         const WavenumberGrid& grid, const CrossSectionOptions& options,
                         double* out, const ComputeSettings& settings, const RunControl* control) {
  grid.Check();
  const PreparedLines prep = Prepare(lines, conditions, options);
  Accumulate(prep, UniformView{grid}, out, settings, control);
}

void ComputeCrossSection(const LineList& lines, const GasConditions& conditions,
                         const double* nu_cm1, std::size_t n, const CrossSectionOptions& options,
                         double* out, const ComputeSettings& settings, const RunControl* control) {
  for (std::size_t j = 0; j < n; ++j) {
    if (!std::isfinite(nu_cm1[j]) || nu_cm1[j] < 0)
      throw std::invalid_argument("nu_cm1[" + std::to_string(j) +
                                  "] must be finite and >= 0 cm-1; got " + FormatNumber(nu_cm1[j]));
    if (j > 0 && !(nu_cm1[j] > nu_cm1[j - 1]))
      throw std::invalid_argument("nu_cm1 must be strictly increasing; nu_cm1[" +
                                  std::to_string(j) + "] = " + FormatNumber(nu_cm1[j]) +
                                  " follows " + FormatNumber(nu_cm1[j - 1]));
  }
  const PreparedLines prep = Prepare(lines, conditions, options);
  Accumulate(prep, ArrayView{nu_cm1, n}, out, settings, control);
}

std::vector<double> CrossSection(const LineList& lines, const GasConditions& conditions,
                                 const WavenumberGrid& grid, const CrossSectionOptions& options,
                                 const ComputeSettings& settings, const RunControl* control) {
  grid.Check();
  std::vector<double> out(grid.size);
  ComputeCrossSection(lines, conditions, grid, options, out.data(), settings, control);
  return out;
}

std::vector<double> CrossSection(const LineList& lines, const GasConditions& conditions,
                                 const std::vector<double>& nu_cm1,
                                 const CrossSectionOptions& options,
                                 const ComputeSettings& settings, const RunControl* control) {
  std::vector<double> out(nu_cm1.size());
  ComputeCrossSection(lines, conditions, nu_cm1.data(), nu_cm1.size(), options, out.data(),
                      settings, control);
  return out;
}

std::vector<double> AbsorptionCoefficient(const LineList& lines, const GasConditions& conditions,
                                          const WavenumberGrid& grid,
                                          const CrossSectionOptions& options,
                                          const ComputeSettings& settings,
                                          const RunControl* control) {
  std::vector<double> k = CrossSection(lines, conditions, grid, options, settings, control);
  const double n = conditions.self_fraction *
                   NumberDensity_cm3(conditions.pressure_Pa, conditions.temperature_K);
  for (double& v : k) v *= n;
  return k;
}

}  // namespace qogi
