#include "engine/synth/truth.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "engine/util/check.h"
#include "engine/util/parallel.h"

namespace qogi::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTruthCut = 7.0;   // truth maps: widths
constexpr double kSplatCut = 5.0;   // grids and ray samples: widths

}  // namespace

double PlaneMassFlux(const std::vector<PuffState>& puffs, const ControlPlane& plane) {
  const double* n0 = plane.normal;
  const double norm = std::sqrt(n0[0] * n0[0] + n0[1] * n0[1] + n0[2] * n0[2]);
  if (!(norm > 0) || !std::isfinite(norm))
    throw std::invalid_argument("the control plane's normal must be a finite non-zero vector");
  const double n[3] = {n0[0] / norm, n0[1] / norm, n0[2] / norm};
  const double c = n[0] * plane.point[0] + n[1] * plane.point[1] + n[2] * plane.point[2];
  double flux = 0;
  for (const PuffState& p : puffs) {
    const double sigma = p.sigma;
    const double d = c - (n[0] * p.x + n[1] * p.y + n[2] * p.z);
    const double g = std::exp(-0.5 * d * d / (sigma * sigma)) / (std::sqrt(2 * kPi) * sigma);
    const double vn = n[0] * p.u + n[1] * p.v + n[2] * p.w + p.sigma_rate / sigma * d;
    flux += static_cast<double>(p.mass) * g * vn;
  }
  return flux;
}

TruthMaps ComputeTruthMaps(const PlumeSimulation& sim, int frame, int num_threads) {
  return ComputeTruthMaps(sim.puffs(frame), sim.view(), num_threads);
}

TruthMaps ComputeTruthMaps(const std::vector<PuffState>& puffs, const View& v,
                           int num_threads) {
  v.Check();
  const int w = v.width_px, h = v.height_px;
  TruthMaps m;
  m.width = w;
  m.height = h;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  m.column.assign(n, 0.0);
  m.flux_x.assign(n, 0.0);
  m.flux_z.assign(n, 0.0);
  const bool ortho = v.projection == Projection::kOrthographic;
  const double cam[3] = {v.center_x_m, -v.distance_m, v.center_z_m};

  constexpr int kRows = 4;
  const std::size_t chunks = (h + kRows - 1) / kRows;
  ParallelFor(chunks, 1, [&](std::size_t cb, std::size_t ce) {
    std::vector<double> gx, gz;
    for (std::size_t chunk = cb; chunk < ce; ++chunk) {
      const int r_begin = static_cast<int>(chunk) * kRows;
      const int r_end = std::min(h, r_begin + kRows);
      for (const PuffState& p : puffs) {
        const double sigma = p.sigma;
        const double cut = kTruthCut * sigma;
        const double scale = v.Scale(p.y);
        const double col_c = v.Column(p.x, p.y), row_c = v.Row(p.z, p.y);
        const double rad = cut / scale * (ortho ? 1.0 : 1.1) + 1.0;
        const int c0 = std::max(0, static_cast<int>(std::ceil(col_c - rad)));
        const int c1 = std::min(w - 1, static_cast<int>(std::floor(col_c + rad)));
        const int q0 = std::max(r_begin, static_cast<int>(std::ceil(row_c - rad)));
        const int q1 = std::min(r_end - 1, static_cast<int>(std::floor(row_c + rad)));
        if (c0 > c1 || q0 > q1) continue;
        const double amp = p.mass / (2 * kPi * sigma * sigma);
        const double a = p.sigma_rate / sigma;
        const double inv2s2 = 0.5 / (sigma * sigma);
        const double cut2 = cut * cut;
        if (ortho) {
          gx.resize(c1 - c0 + 1);
          for (int i = c0; i <= c1; ++i) {
            const double dx = v.PixelX(i, 0) - p.x;
            gx[i - c0] = std::exp(-dx * dx * inv2s2);
          }
          for (int r = q0; r <= q1; ++r) {
            const double dz = v.PixelZ(r, 0) - p.z;
            const double gzr = amp * std::exp(-dz * dz * inv2s2);
            const std::size_t row = static_cast<std::size_t>(r) * w;
            for (int i = c0; i <= c1; ++i) {
              const double dx = v.PixelX(i, 0) - p.x;
              if (dx * dx + dz * dz > cut2) continue;
              const double c = gzr * gx[i - c0];
              m.column[row + i] += c;
              m.flux_x[row + i] += c * (p.u + a * dx);
              m.flux_z[row + i] += c * (p.w + a * dz);
            }
          }
        } else {
          const double vx = p.x - cam[0], vy = p.y - cam[1], vz = p.z - cam[2];
          const double v2 = vx * vx + vy * vy + vz * vz;
          for (int r = q0; r <= q1; ++r) {
            const double b = -(r - v.cy()) * v.ifov_rad;
            const std::size_t row = static_cast<std::size_t>(r) * w;
            for (int i = c0; i <= c1; ++i) {
              const double aa = (i - v.cx()) * v.ifov_rad;
              const double inv = 1.0 / std::sqrt(1 + aa * aa + b * b);
              const double dx = aa * inv, dy = inv, dz = b * inv;
              const double l = vx * dx + vy * dy + vz * dz;
              const double perp2 = v2 - l * l;
              if (perp2 > cut2) continue;
              const double c = amp * std::exp(-perp2 * inv2s2);
              // Closest point of the ray to the puff centre, minus the centre.
              const double qx = cam[0] + l * dx - p.x, qz = cam[2] + l * dz - p.z;
              m.column[row + i] += c;
              m.flux_x[row + i] += c * (p.u + a * qx);
              m.flux_z[row + i] += c * (p.w + a * qz);
            }
          }
        }
      }
    }
  }, num_threads);
  m.velocity_x.resize(n);
  m.velocity_z.resize(n);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < n; ++i) {
    const bool gas = m.column[i] > 0;
    m.velocity_x[i] = gas ? m.flux_x[i] / m.column[i] : nan;
    m.velocity_z[i] = gas ? m.flux_z[i] / m.column[i] : nan;
  }
  return m;
}

void Grid::Check() const {
  CheckInRange(nx, 1, 1 << 16, "grid nx");
  CheckInRange(ny, 1, 1 << 16, "grid ny");
  CheckInRange(nz, 1, 1 << 16, "grid nz");
  CheckPositive(dx, "grid dx", "m");
  CheckPositive(dy, "grid dy", "m");
  CheckPositive(dz, "grid dz", "m");
  CheckFinite(x0, "grid x0");
  CheckFinite(y0, "grid y0");
  CheckFinite(z0, "grid z0");
  if (size() > (std::size_t{1} << 28))
    throw std::invalid_argument("the grid has " + std::to_string(size()) +
                                " nodes; at most 268435456 are allowed (coarsen it)");
}

Grid DefaultGrid(const PlumeSimulation& sim) {
  const Box& b = sim.box();
  double step = sim.view().footprint_m();
  Grid g;
  for (;;) {
    g.dx = g.dy = g.dz = step;
    g.nx = std::max(1, static_cast<int>(std::ceil((b.hi[0] - b.lo[0]) / step)) + 1);
    g.ny = std::max(1, static_cast<int>(std::ceil((b.hi[1] - b.lo[1]) / step)) + 1);
    g.nz = std::max(1, static_cast<int>(std::ceil((b.hi[2] - b.lo[2]) / step)) + 1);
    if (g.size() <= (std::size_t{1} << 26)) break;
    step *= 1.25;
  }
  g.x0 = 0.5 * (b.lo[0] + b.hi[0]) - 0.5 * (g.nx - 1) * g.dx;
  g.y0 = 0.5 * (b.lo[1] + b.hi[1]) - 0.5 * (g.ny - 1) * g.dy;
  g.z0 = 0.5 * (b.lo[2] + b.hi[2]) - 0.5 * (g.nz - 1) * g.dz;
  return g;
}

namespace {

// Adds each puff's partial density (and, if jx is set, mass flux) to the
// nodes of a stack of planes. Plane p (0..np-1) sits at y = ys[p]; on it node
// (i, k) is at x = ax[p] + bx[p] i, z = az[p] + bz[p] k; arrays are
// [p][k][i] with ni x nk nodes per plane. Parallel over planes; every node's
// sum runs over the puffs in their order (reproducible).
void Splat(const std::vector<PuffState>& puffs, int np, int ni, int nk,
           const std::vector<double>& ys, const std::vector<double>& ax,
           const std::vector<double>& bx, const std::vector<double>& az,
           const std::vector<double>& bz, float* rho, float* jx, float* jy, float* jz,
           int num_threads) {
  const std::size_t plane_size = static_cast<std::size_t>(ni) * nk;
  ParallelFor(np, 1, [&](std::size_t pb, std::size_t pe) {
    std::vector<double> gx, gz, dxs;
    std::vector<double> acc, ax_, ay_, az_;
    for (std::size_t p = pb; p < pe; ++p) {
      acc.assign(plane_size, 0.0);
      if (jx) {
        ax_.assign(plane_size, 0.0);
        ay_.assign(plane_size, 0.0);
        az_.assign(plane_size, 0.0);
      }
      const double y = ys[p];
      for (const PuffState& q : puffs) {
        const double sigma = q.sigma;
        const double cut = kSplatCut * sigma;
        const double dy = y - q.y;
        if (std::abs(dy) > cut) continue;
        const double i_lo = (q.x - cut - ax[p]) / bx[p], i_hi = (q.x + cut - ax[p]) / bx[p];
        const double k_lo = (q.z - cut - az[p]) / bz[p], k_hi = (q.z + cut - az[p]) / bz[p];
        const int i0 = std::max(0, static_cast<int>(std::ceil(std::min(i_lo, i_hi))));
        const int i1 = std::min(ni - 1, static_cast<int>(std::floor(std::max(i_lo, i_hi))));
        const int k0 = std::max(0, static_cast<int>(std::ceil(std::min(k_lo, k_hi))));
        const int k1 = std::min(nk - 1, static_cast<int>(std::floor(std::max(k_lo, k_hi))));
        if (i0 > i1 || k0 > k1) continue;
        const double inv2s2 = 0.5 / (sigma * sigma);
        const double amp = q.mass * std::pow(2 * kPi * sigma * sigma, -1.5) *
                           std::exp(-dy * dy * inv2s2);
        const double a = q.sigma_rate / sigma;
        gx.resize(i1 - i0 + 1);
        dxs.resize(i1 - i0 + 1);
        for (int i = i0; i <= i1; ++i) {
          const double dx = ax[p] + bx[p] * i - q.x;
          dxs[i - i0] = dx;
          gx[i - i0] = std::exp(-dx * dx * inv2s2);
        }
        for (int k = k0; k <= k1; ++k) {
          const double dz = az[p] + bz[p] * k - q.z;
          const double gk = amp * std::exp(-dz * dz * inv2s2);
          const std::size_t row = static_cast<std::size_t>(k) * ni;
          if (!jx) {
            for (int i = i0; i <= i1; ++i) acc[row + i] += gk * gx[i - i0];
            continue;
          }
          const double fy = q.v + a * dy, fz = q.w + a * dz;
          for (int i = i0; i <= i1; ++i) {
            const double c = gk * gx[i - i0];
            acc[row + i] += c;
            ax_[row + i] += c * (q.u + a * dxs[i - i0]);
            ay_[row + i] += c * fy;
            az_[row + i] += c * fz;
          }
        }
      }
      float* out = rho + p * plane_size;
      for (std::size_t i = 0; i < plane_size; ++i) out[i] = static_cast<float>(acc[i]);
      if (jx) {
        float *ox = jx + p * plane_size, *oy = jy + p * plane_size, *oz = jz + p * plane_size;
        for (std::size_t i = 0; i < plane_size; ++i) {
          // Velocity = J / rho (mean wind where there is no gas; set by caller).
          ox[i] = acc[i] > 0 ? static_cast<float>(ax_[i] / acc[i]) : std::nanf("");
          oy[i] = acc[i] > 0 ? static_cast<float>(ay_[i] / acc[i]) : std::nanf("");
          oz[i] = acc[i] > 0 ? static_cast<float>(az_[i] / acc[i]) : std::nanf("");
        }
      }
    }
  }, num_threads);
}

}  // namespace

Fields ComputeFields(const PlumeSimulation& sim, int frame, const Grid& grid,
                     bool with_velocity, int num_threads) {
  const Release& rel = sim.release();
  const double th = rel.wind_direction_deg * kPi / 180;
  const std::array<double, 3> wind = {rel.wind_speed_m_s * std::cos(th),
                                      rel.wind_speed_m_s * std::sin(th), 0.0};
  return ComputeFields(sim.puffs(frame), sim.mixing(), wind, grid, with_velocity, num_threads);
}

Fields ComputeFields(const std::vector<PuffState>& puffs, const MixingModel& mix,
                     const std::array<double, 3>& wind, const Grid& grid, bool with_velocity,
                     int num_threads) {
  grid.Check();
  Fields f;
  f.grid = grid;
  const std::size_t n = grid.size();
  // Planes of constant z would also do; the splat works on planes of constant
  // y, so lay the grid out as [j][k][i] first and transpose to [k][j][i].
  std::vector<double> ys(grid.ny), ax(grid.ny, grid.x0), bx(grid.ny, grid.dx),
      az(grid.ny, grid.z0), bz(grid.ny, grid.dz);
  for (int j = 0; j < grid.ny; ++j) ys[j] = grid.y0 + j * grid.dy;
  std::vector<float> rho(n), vx, vy, vz;
  if (with_velocity) {
    vx.resize(n);
    vy.resize(n);
    vz.resize(n);
  }
  Splat(puffs, grid.ny, grid.nx, grid.nz, ys, ax, bx, az, bz, rho.data(),
        with_velocity ? vx.data() : nullptr, with_velocity ? vy.data() : nullptr,
        with_velocity ? vz.data() : nullptr, num_threads);
  f.partial_density.resize(n);
  f.mole_fraction.resize(n);
  f.temperature.resize(n);
  if (with_velocity) {
    f.velocity_x.resize(n);
    f.velocity_y.resize(n);
    f.velocity_z.resize(n);
  }
  std::atomic<std::uint64_t> over{0};
  const std::size_t nx = grid.nx, ny = grid.ny, nz = grid.nz;
  ParallelFor(nz, 1, [&](std::size_t kb, std::size_t ke) {
    std::uint64_t local = 0;
    for (std::size_t k = kb; k < ke; ++k)
      for (std::size_t j = 0; j < ny; ++j)
        for (std::size_t i = 0; i < nx; ++i) {
          const std::size_t src = (j * nz + k) * nx + i;
          const std::size_t dst = (k * ny + j) * nx + i;
          const double r = rho[src];
          double t, x;
          if (!mix.StateFromPartialDensity(r, &t, &x)) ++local;
          f.partial_density[dst] = static_cast<float>(r);
          f.temperature[dst] = static_cast<float>(t);
          f.mole_fraction[dst] = static_cast<float>(x);
          if (with_velocity) {
            const bool gas = r > 0;
            f.velocity_x[dst] = gas ? vx[src] : static_cast<float>(wind[0]);
            f.velocity_y[dst] = gas ? vy[src] : static_cast<float>(wind[1]);
            f.velocity_z[dst] = gas ? vz[src] : static_cast<float>(wind[2]);
          }
        }
    over += local;
  }, num_threads);
  f.over_pure = over;
  return f;
}

RaySamples SampleRays(const PlumeSimulation& sim, int frame, int row0, int row1, int col0,
                      int col1, int num_threads) {
  return SampleRays(sim.puffs(frame), sim.view(), sim.mixing(), row0, row1, col0, col1,
                    num_threads);
}

RaySamples SampleRays(const std::vector<PuffState>& all, const View& v, const MixingModel& mix,
                      int row0, int row1, int col0, int col1, int num_threads) {
  v.Check();
  if (!(0 <= row0 && row0 < row1 && row1 <= v.height_px))
    throw std::invalid_argument("rows must satisfy 0 <= row0 < row1 <= " +
                                std::to_string(v.height_px) + "; got " + std::to_string(row0) +
                                ", " + std::to_string(row1));
  if (!(0 <= col0 && col0 < col1 && col1 <= v.width_px))
    throw std::invalid_argument("columns must satisfy 0 <= col0 < col1 <= " +
                                std::to_string(v.width_px) + "; got " + std::to_string(col0) +
                                ", " + std::to_string(col1));
  RaySamples rs;
  rs.row0 = row0;
  rs.col0 = col0;
  rs.rows = row1 - row0;
  rs.cols = col1 - col0;
  const std::size_t npix = static_cast<std::size_t>(rs.rows) * rs.cols;
  // Puffs whose 5-width sphere reaches the rectangle's rays.
  std::vector<PuffState> puffs;
  double y_lo = 1e300, y_hi = -1e300, sigma_min = 1e300;
  for (const PuffState& p : all) {
    const double cut = kSplatCut * p.sigma;
    const double scale_lo = v.Scale(p.y - cut), scale_hi = v.Scale(p.y + cut);
    const double s_min = std::min(scale_lo, scale_hi), s_max = std::max(scale_lo, scale_hi);
    (void)s_max;
    const double cc = v.Column(p.x, p.y), rc = v.Row(p.z, p.y);
    const double rad = cut / std::max(s_min, 1e-12) + 1.0;
    if (cc + rad < col0 - 0.5 || cc - rad > col1 - 0.5 || rc + rad < row0 - 0.5 ||
        rc - rad > row1 - 0.5)
      continue;
    puffs.push_back(p);
    y_lo = std::min(y_lo, p.y - cut);
    y_hi = std::max(y_hi, p.y + cut);
    sigma_min = std::min(sigma_min, static_cast<double>(p.sigma));
  }
  const std::size_t n_species = mix.released().names().size();
  rs.mole_fraction.assign(n_species, {});
  rs.path_m.resize(npix);
  rs.first_plane.assign(npix, 0);
  rs.last_plane.assign(npix, 0);
  rs.step_m = std::min(v.footprint_m(), puffs.empty() ? v.footprint_m() : sigma_min);
  for (int r = 0; r < rs.rows; ++r)
    for (int c = 0; c < rs.cols; ++c)
      rs.path_m[static_cast<std::size_t>(r) * rs.cols + c] =
          static_cast<float>(rs.step_m * v.PathPerDepth(col0 + c, row0 + r));
  if (puffs.empty()) return rs;
  y_lo = std::max(y_lo, -0.95 * v.distance_m);
  rs.planes = std::max(1, static_cast<int>(std::ceil((y_hi - y_lo) / rs.step_m)));
  if (static_cast<double>(rs.planes) * npix > 4e8)
    throw std::invalid_argument("too many ray samples requested (" +
                                std::to_string(rs.planes) + " planes x " +
                                std::to_string(npix) + " pixels); ask for fewer rows");
  const double y_mid = 0.5 * (y_lo + y_hi);
  rs.y_m.resize(rs.planes);
  std::vector<double> ax(rs.planes), bx(rs.planes), az(rs.planes), bz(rs.planes);
  for (int p = 0; p < rs.planes; ++p) {
    // p = 0 is the farthest plane (largest y).
    const double y = y_mid + (0.5 * (rs.planes - 1) - p) * rs.step_m;
    rs.y_m[p] = y;
    ax[p] = v.PixelX(col0, y);
    bx[p] = v.Scale(y);
    az[p] = v.PixelZ(row0, y);
    bz[p] = -v.Scale(y);
  }
  const std::size_t n = npix * rs.planes;
  rs.partial_density.resize(n);
  Splat(puffs, rs.planes, rs.cols, rs.rows, rs.y_m, ax, bx, az, bz, rs.partial_density.data(),
        nullptr, nullptr, nullptr, num_threads);
  rs.temperature.resize(n);
  std::vector<float> xr(n);
  std::atomic<std::uint64_t> over{0};
  ParallelFor(rs.planes, 1, [&](std::size_t pb, std::size_t pe) {
    std::uint64_t local = 0;
    for (std::size_t i = pb * npix; i < pe * npix; ++i) {
      double t, x;
      if (!mix.StateFromPartialDensity(rs.partial_density[i], &t, &x)) ++local;
      rs.temperature[i] = static_cast<float>(t);
      xr[i] = static_cast<float>(x);
    }
    over += local;
  }, num_threads);
  rs.over_pure = over;
  for (std::size_t s = 0; s < n_species; ++s) {
    const double xs = mix.released().mole_fractions()[s];
    rs.mole_fraction[s].resize(n);
    for (std::size_t i = 0; i < n; ++i)
      rs.mole_fraction[s][i] = static_cast<float>(xs * xr[i]);
  }
  for (std::size_t i = 0; i < npix; ++i) {
    int first = rs.planes, last = 0;
    for (int p = 0; p < rs.planes; ++p)
      if (rs.partial_density[p * npix + i] > 0) {
        first = std::min(first, p);
        last = p + 1;
      }
    rs.first_plane[i] = last > 0 ? first : 0;
    rs.last_plane[i] = last;
  }
  return rs;
}

}  // namespace qogi::synth
