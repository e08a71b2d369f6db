#include "engine/inversion/mixing_line_slope.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "engine/inversion/inversion.h"
#include "engine/util/check.h"

namespace qogi {

void MixingLineSlopeOptions::Check(std::size_t num_species, std::size_t num_channels) const {
  MixingLineOptions l = line;
  l.slope_K_per_fraction = 0.0;  // set per grid value
  l.Check(num_species, num_channels);
  Require(std::isfinite(min_snr) && min_snr >= 0,
          "min_snr must be finite and >= 0; got " + FormatNumber(min_snr));
  Require(max_samples >= 1, "max_samples must be >= 1; got 0");
  Require(min_samples >= 1, "min_samples must be >= 1; got 0");
  Require(std::isfinite(grid_step_K) && grid_step_K > 0,
          "grid_step_K must be finite and > 0 K; got " + FormatNumber(grid_step_K));
  Require(std::isfinite(chi2_cap) && chi2_cap > 0,
          "chi2_cap must be finite and > 0; got " + FormatNumber(chi2_cap));
}

std::vector<std::size_t> MixingLineSlopeSample(const MixingLineInverter& inverter,
                                               const MixingLineSlopeOptions& options, std::size_t n,
                                               const double* radiance,
                                               const double* background_radiance,
                                               std::size_t* num_candidates) {
  const std::size_t nc = inverter.table().num_channels();
  const std::vector<double>& netd_in = options.line.netd_K;
  Require(netd_in.size() == 1 || netd_in.size() == nc,
          "netd_K needs one value or one per channel (" + std::to_string(nc) + ")");
  // One noise per channel: the NETD times dL/dT at the channel's median
  // background temperature.
  std::vector<double> noise(nc), column(n);
  for (std::size_t c = 0; c < nc; ++c) {
    for (std::size_t i = 0; i < n; ++i) column[i] = background_radiance[i * nc + c];
    double median = std::numeric_limits<double>::quiet_NaN();
    if (n > 0) {
      const std::size_t h = n / 2;
      std::nth_element(column.begin(), column.begin() + h, column.end());
      median = column[h];
      if (n % 2 == 0)
        median = 0.5 * (median + *std::max_element(column.begin(), column.begin() + h));
    }
    const RadiometricTable& band = inverter.bands()[c];
    const double t_bg = band.Temperature(median);
    Require(t_bg >= band.t_min_K() && t_bg <= band.t_max_K(),
            "the median background radiance of channel " + std::to_string(c) + " (" +
                FormatNumber(median) +
                " W/(m2 sr)) is outside the scene table's background temperature range");
    noise[c] = (netd_in.size() == nc ? netd_in[c] : netd_in[0]) * band.Derivative(t_bg);
  }
  std::vector<std::size_t> cand;
  for (std::size_t i = 0; i < n; ++i) {
    double snr = 0;
    bool finite = true;
    for (std::size_t c = 0; c < nc; ++c) {
      const double d = std::abs(radiance[i * nc + c] - background_radiance[i * nc + c]) / noise[c];
      finite = finite && std::isfinite(d);
      snr = std::max(snr, d);
    }
    if (finite && snr >= options.min_snr) cand.push_back(i);
  }
  if (num_candidates) *num_candidates = cand.size();
  if (cand.size() <= options.max_samples) return cand;
  // A seeded random subset (Floyd's algorithm on a splitmix64 stream: the
  // same on every platform), in index order. An evenly strided subset would
  // alias with the candidates' layout (so many per frame, ordered across
  // the plume) and favour some positions across the plume in every frame.
  const std::size_t nc_all = cand.size(), m = options.max_samples;
  std::uint64_t state = options.seed;
  auto next = [&state]() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  };
  std::vector<char> chosen(nc_all, 0);
  for (std::size_t j = nc_all - m; j < nc_all; ++j) {
    const std::size_t t = static_cast<std::size_t>(next() % (j + 1));
    chosen[chosen[t] ? j : t] = 1;
  }
  std::vector<std::size_t> out;
  out.reserve(m);
  for (std::size_t j = 0; j < nc_all; ++j)
    if (chosen[j]) out.push_back(cand[j]);
  return out;
}

MixingLineSlope MixingLineSlopeFromProfile(const std::vector<double>& grid, std::size_t np,
                                           const double* chi2, double chi2_cap) {
  const std::size_t nk = grid.size();
  Require(nk >= 2, "the k grid needs at least 2 values; got " + std::to_string(nk));
  const double step = grid[1] - grid[0];
  for (std::size_t k = 1; k < nk; ++k)
    Require(
        std::abs(grid[k] - grid[k - 1] - step) <= 1e-9 * std::max(1.0, std::abs(step)) && step > 0,
        "the k grid must be increasing and evenly spaced");
  Require(chi2_cap > 0, "chi2_cap must be > 0; got " + FormatNumber(chi2_cap));
  MixingLineSlope r;
  r.grid_K_per_fraction = grid;
  r.total_chi2.assign(nk, 0.0);
  r.num_samples = np;
  for (std::size_t p = 0; p < np; ++p) {
    bool good = true;
    for (std::size_t k = 0; k < nk && good; ++k) good = std::isfinite(chi2[k * np + p]);
    if (!good) continue;
    ++r.num_fitted;
    for (std::size_t k = 0; k < nk; ++k) r.total_chi2[k] += std::min(chi2[k * np + p], chi2_cap);
  }
  if (r.num_fitted == 0) return r;
  const std::vector<double>& total = r.total_chi2;
  const std::size_t i =
      static_cast<std::size_t>(std::min_element(total.begin(), total.end()) - total.begin());
  double k = grid[i];
  const double dof = static_cast<double>(std::max<std::size_t>(1, r.num_fitted - 1));
  const double scale = std::max(1.0, total[i] / dof);  // model error widens Delta chi2 = 1
  if (i > 0 && i + 1 < nk) {
    const double y0 = total[i - 1], y1 = total[i], y2 = total[i + 1];
    const double curv = (y0 - 2 * y1 + y2) / (step * step);
    if (curv > 0)
      k = std::clamp(grid[i] - 0.5 * (y2 - y0) / step / curv, grid[i] - 0.5 * step,
                     grid[i] + 0.5 * step);
  }
  // 1-sigma: where the linearly interpolated profile, sampled 20 times per
  // grid step, rises by `scale` from its minimum, on the flatter side.
  const std::size_t nf = 1 + 20 * (nk - 1);
  double in_lo = std::numeric_limits<double>::infinity(), in_hi = -in_lo;
  for (std::size_t j = 0; j < nf; ++j) {
    const double x = grid[0] + (grid[nk - 1] - grid[0]) * static_cast<double>(j) / (nf - 1);
    const std::size_t s = std::min(j / 20, nk - 2);
    const double t = (x - grid[s]) / (grid[s + 1] - grid[s]);
    const double y = total[s] + t * (total[s + 1] - total[s]);
    if (y <= total[i] + scale) {
      in_lo = std::min(in_lo, x);
      in_hi = std::max(in_hi, x);
    }
  }
  r.found = true;
  r.slope_K_per_fraction = k;
  r.sigma_K_per_fraction = in_lo <= in_hi ? std::max({k - in_lo, in_hi - k, 0.5 * step}) : step;
  return r;
}

MixingLineSlope FindMixingLineSlope(const MixingLineInverter& inverter,
                                    const MixingLineSlopeOptions& options, std::size_t n,
                                    const double* radiance, const double* background_radiance,
                                    const double* sigma_m, const RunControl* control) {
  const SceneTable& table = inverter.table();
  const std::size_t nc = table.num_channels();
  options.Check(table.num_species(), nc);
  const double t_amb = table.ambient_temperature_K();
  const double k_lo = table.min_peak_temperature_K() - t_amb;
  const double k_hi = table.max_peak_temperature_K() - t_amb;
  const std::size_t nk = static_cast<std::size_t>(
      std::max(0.0, std::ceil((k_hi - k_lo + 1e-9) / options.grid_step_K)));
  Require(nk >= 2, "the scene table's peak temperature range (" +
                       FormatNumber(table.min_peak_temperature_K()) + "-" +
                       FormatNumber(table.max_peak_temperature_K()) +
                       " K) spans less than two steps of grid_step_K (" +
                       FormatNumber(options.grid_step_K) + " K)");
  std::vector<double> grid(nk);
  for (std::size_t k = 0; k < nk; ++k) grid[k] = k_lo + options.grid_step_K * k;

  std::size_t num_candidates = 0;
  const std::vector<std::size_t> sample =
      MixingLineSlopeSample(inverter, options, n, radiance, background_radiance, &num_candidates);
  const std::size_t np = sample.size();
  if (np < options.min_samples) {
    MixingLineSlope r;
    r.num_candidates = num_candidates;
    r.num_samples = np;
    r.grid_K_per_fraction = grid;
    return r;
  }
  std::vector<double> rad(np * nc), bg(np * nc), sg(np);
  for (std::size_t p = 0; p < np; ++p) {
    const std::size_t i = sample[p];
    std::copy(radiance + i * nc, radiance + (i + 1) * nc, rad.begin() + p * nc);
    std::copy(background_radiance + i * nc, background_radiance + (i + 1) * nc,
              bg.begin() + p * nc);
    sg[p] = sigma_m[i];
  }
  std::vector<double> chi2(nk * np), x(np), xs(np), tp(np);
  std::vector<std::int32_t> status(np), iters(np);
  MixingLineOptions line = options.line;
  for (std::size_t k = 0; k < nk; ++k) {
    RunControl step;
    if (control) {
      step.cancelled = control->cancelled;
      if (control->progress) step.progress = [&, k](double f) { control->progress((k + f) / nk); };
    }
    line.slope_K_per_fraction = grid[k];
    double* row = &chi2[k * np];
    inverter.Invert(line, np, rad.data(), bg.data(), sg.data(),
                    {x.data(), xs.data(), tp.data(), row, status.data(), iters.data()},
                    control ? &step : nullptr);
    // A failed pixel adds nothing at this k (as a pixel below detection).
    for (std::size_t p = 0; p < np; ++p)
      if (status[p] == static_cast<std::int32_t>(PixelStatus::kFailed)) row[p] = 0.0;
  }
  MixingLineSlope r = MixingLineSlopeFromProfile(grid, np, chi2.data(), options.chi2_cap);
  r.num_candidates = num_candidates;
  return r;
}

}  // namespace qogi
