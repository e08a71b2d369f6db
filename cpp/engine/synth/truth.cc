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
constexpr double kTruthCut = 6.0;   // truth maps: widths (disc)
constexpr double kSplatCut = 5.0;   // grids and ray samples: widths (sphere)

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

TruthMaps ComputeTruthMaps(const std::vector<PuffState>& puffs, const View& v, int num_threads) {
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
  ParallelFor(
      chunks, 1,
      [&](std::size_t cb, std::size_t ce) {
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
              // Separable: g(x) g(z), over the disc of radius `cut` row by row.
              const double fp = v.footprint_m(), x_first = v.PixelX(c0, 0);
              gx.resize(c1 - c0 + 1);
              gz.resize(c1 - c0 + 1);  // here: g(x) (u + a dx)
              for (int i = c0; i <= c1; ++i) {
                const double dx = x_first + (i - c0) * fp - p.x;
                gx[i - c0] = std::exp(-dx * dx * inv2s2);
                gz[i - c0] = gx[i - c0] * (p.u + a * dx);
              }
              for (int r = q0; r <= q1; ++r) {
                const double dz = v.PixelZ(r, 0) - p.z;
                if (dz * dz > cut2) continue;
                const double half = std::sqrt(cut2 - dz * dz);
                const int ia = std::max(c0, static_cast<int>(std::ceil(v.Column(p.x - half, 0))));
                const int ib = std::min(c1, static_cast<int>(std::floor(v.Column(p.x + half, 0))));
                const double gzr = amp * std::exp(-dz * dz * inv2s2);
                const double wz = gzr * (p.w + a * dz);
                double* col = &m.column[static_cast<std::size_t>(r) * w];
                double* fx = &m.flux_x[static_cast<std::size_t>(r) * w];
                double* fz = &m.flux_z[static_cast<std::size_t>(r) * w];
                for (int i = ia; i <= ib; ++i) {
                  col[i] += gzr * gx[i - c0];
                  fx[i] += gzr * gz[i - c0];
                  fz[i] += wz * gx[i - c0];
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
      },
      num_threads);
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
  ParallelFor(
      np, 1,
      [&](std::size_t pb, std::size_t pe) {
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
            // The puff's cut-off sphere cuts this plane in a disc of radius rc.
            const double rc = std::sqrt(cut * cut - dy * dy);
            const double i_lo = (q.x - rc - ax[p]) / bx[p], i_hi = (q.x + rc - ax[p]) / bx[p];
            const double k_lo = (q.z - rc - az[p]) / bz[p], k_hi = (q.z + rc - az[p]) / bz[p];
            const int i0 = std::max(0, static_cast<int>(std::ceil(std::min(i_lo, i_hi))));
            const int i1 = std::min(ni - 1, static_cast<int>(std::floor(std::max(i_lo, i_hi))));
            const int k0 = std::max(0, static_cast<int>(std::ceil(std::min(k_lo, k_hi))));
            const int k1 = std::min(nk - 1, static_cast<int>(std::floor(std::max(k_lo, k_hi))));
            if (i0 > i1 || k0 > k1) continue;
            const double inv2s2 = 0.5 / (sigma * sigma);
            const double amp =
                q.mass * std::pow(2 * kPi * sigma * sigma, -1.5) * std::exp(-dy * dy * inv2s2);
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
              if (dz * dz > rc * rc) continue;
              // Columns of this row inside the disc.
              const double half = std::sqrt(rc * rc - dz * dz);
              const double c_lo = (q.x - half - ax[p]) / bx[p], c_hi = (q.x + half - ax[p]) / bx[p];
              const int ia = std::max(i0, static_cast<int>(std::ceil(std::min(c_lo, c_hi))));
              const int ib = std::min(i1, static_cast<int>(std::floor(std::max(c_lo, c_hi))));
              const double gk = amp * std::exp(-dz * dz * inv2s2);
              const std::size_t row = static_cast<std::size_t>(k) * ni;
              if (!jx) {
                for (int i = ia; i <= ib; ++i) acc[row + i] += gk * gx[i - i0];
                continue;
              }
              const double fy = q.v + a * dy, fz = q.w + a * dz;
              for (int i = ia; i <= ib; ++i) {
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
      },
      num_threads);
}

}  // namespace

Fields ComputeFields(const PlumeSimulation& sim, int frame, const Grid& grid, bool with_velocity,
                     int num_threads) {
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
  std::vector<double> ys(grid.ny), ax(grid.ny, grid.x0), bx(grid.ny, grid.dx), az(grid.ny, grid.z0),
      bz(grid.ny, grid.dz);
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
  ParallelFor(
      nz, 1,
      [&](std::size_t kb, std::size_t ke) {
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
      },
      num_threads);
  f.over_pure = over;
  return f;
}

RaySamples SampleRays(const PlumeSimulation& sim, int frame, int row0, int row1, int col0, int col1,
                      int num_threads) {
  return SampleRays(sim.puffs(frame), sim.view(), sim.mixing(), row0, row1, col0, col1,
                    num_threads);
}

RaySamples SampleRays(const std::vector<PuffState>& all, const View& v, const MixingModel& mix,
                      int row0, int row1, int col0, int col1, int num_threads) {
  v.Check();
  if (!(0 <= row0 && row0 < row1 && row1 <= v.height_px))
    throw std::invalid_argument(
        "rows must satisfy 0 <= row0 < row1 <= " + std::to_string(v.height_px) + "; got " +
        std::to_string(row0) + ", " + std::to_string(row1));
  if (!(0 <= col0 && col0 < col1 && col1 <= v.width_px))
    throw std::invalid_argument(
        "columns must satisfy 0 <= col0 < col1 <= " + std::to_string(v.width_px) + "; got " +
        std::to_string(col0) + ", " + std::to_string(col1));
  RaySamples rs;
  rs.row0 = row0;
  rs.col0 = col0;
  rs.rows = row1 - row0;
  rs.cols = col1 - col0;
  const std::size_t npix = static_cast<std::size_t>(rs.rows) * rs.cols;
  const std::size_t n_species = mix.released().names().size();
  rs.mole_fraction.assign(n_species, {});
  rs.path_m.resize(npix);
  rs.first_plane.assign(npix, 0);
  rs.offset.assign(npix + 1, 0);

  // Puffs whose cut-off sphere reaches a ray of the rectangle (rows r0..r1).
  auto touching = [&](int r0, int r1, std::vector<PuffState>& out, double& y_lo, double& y_hi,
                      double& sigma_min) {
    out.clear();
    y_lo = 1e300;
    y_hi = -1e300;
    sigma_min = 1e300;
    for (const PuffState& p : all) {
      const double cut = kSplatCut * p.sigma;
      const double s_min = std::min(v.Scale(p.y - cut), v.Scale(p.y + cut));
      const double cc = v.Column(p.x, p.y), rc = v.Row(p.z, p.y);
      const double rad = cut / std::max(s_min, 1e-12) + 1.0;
      if (cc + rad < col0 - 0.5 || cc - rad > col1 - 0.5 || rc + rad < r0 - 0.5 ||
          rc - rad > r1 - 0.5)
        continue;
      out.push_back(p);
      y_lo = std::min(y_lo, p.y - cut);
      y_hi = std::max(y_hi, p.y + cut);
      sigma_min = std::min(sigma_min, static_cast<double>(p.sigma));
    }
    y_lo = std::max(y_lo, -0.95 * v.distance_m);
  };
  std::vector<PuffState> puffs;
  double y_lo, y_hi, sigma_min;
  touching(row0, row1, puffs, y_lo, y_hi, sigma_min);
  rs.step_m = puffs.empty() ? v.footprint_m() : sigma_min;
  for (int r = 0; r < rs.rows; ++r)
    for (int c = 0; c < rs.cols; ++c)
      rs.path_m[static_cast<std::size_t>(r) * rs.cols + c] =
          static_cast<float>(rs.step_m * v.PathPerDepth(col0 + c, row0 + r));
  if (puffs.empty()) return rs;
  rs.planes = std::max(1, static_cast<int>(std::ceil((y_hi - y_lo) / rs.step_m)));
  const double y_mid = 0.5 * (y_lo + y_hi);
  rs.y_m.resize(rs.planes);
  for (int p = 0; p < rs.planes; ++p)  // p = 0 is the farthest plane (largest y)
    rs.y_m[p] = y_mid + (0.5 * (rs.planes - 1) - p) * rs.step_m;

  // Dense bands of rows, splatted then compacted to the runs of planes that
  // hold gas.
  constexpr int kBand = 8;
  std::vector<float> dense;
  std::vector<PuffState> band_puffs;
  std::int64_t total = 0;
  for (int b0 = 0; b0 < rs.rows; b0 += kBand) {
    const int b1 = std::min(rs.rows, b0 + kBand);
    double by_lo, by_hi, bs;
    touching(row0 + b0, row0 + b1, band_puffs, by_lo, by_hi, bs);
    const std::size_t bpix = static_cast<std::size_t>(b1 - b0) * rs.cols;
    if (band_puffs.empty()) {
      for (int r = b0; r < b1; ++r)
        for (int c = 0; c < rs.cols; ++c) {
          const std::size_t i = static_cast<std::size_t>(r) * rs.cols + c;
          rs.offset[i + 1] = total;
        }
      continue;
    }
    // Planes of this band: those within its puffs' depth range.
    const int p0 =
        std::clamp(static_cast<int>(std::floor((rs.y_m[0] - by_hi) / rs.step_m)), 0, rs.planes - 1);
    const int p1 = std::clamp(static_cast<int>(std::ceil((rs.y_m[0] - by_lo) / rs.step_m)) + 1,
                              p0 + 1, rs.planes);
    const int np = p1 - p0;
    std::vector<double> ys(np), ax(np), bx(np), az(np), bz(np);
    for (int p = 0; p < np; ++p) {
      const double y = rs.y_m[p0 + p];
      ys[p] = y;
      ax[p] = v.PixelX(col0, y);
      bx[p] = v.Scale(y);
      az[p] = v.PixelZ(row0 + b0, y);
      bz[p] = -v.Scale(y);
    }
    dense.assign(bpix * np, 0.0f);
    Splat(band_puffs, np, rs.cols, b1 - b0, ys, ax, bx, az, bz, dense.data(), nullptr, nullptr,
          nullptr, num_threads);
    for (int r = b0; r < b1; ++r)
      for (int c = 0; c < rs.cols; ++c) {
        const std::size_t bi = static_cast<std::size_t>(r - b0) * rs.cols + c;
        const std::size_t i = static_cast<std::size_t>(r) * rs.cols + c;
        int first = np, last = -1;
        for (int p = 0; p < np; ++p)
          if (dense[p * bpix + bi] > 0) {
            first = std::min(first, p);
            last = p;
          }
        if (last >= first) {
          rs.first_plane[i] = p0 + first;
          for (int p = first; p <= last; ++p) rs.partial_density.push_back(dense[p * bpix + bi]);
          total += last - first + 1;
        }
        rs.offset[i + 1] = total;
      }
  }
  const std::size_t n = rs.partial_density.size();
  rs.temperature.resize(n);
  std::vector<float> xr(n);
  std::atomic<std::uint64_t> over{0};
  ParallelFor(
      n, 65536,
      [&](std::size_t b, std::size_t e) {
        std::uint64_t local = 0;
        for (std::size_t i = b; i < e; ++i) {
          double t, x;
          if (!mix.StateFromPartialDensity(rs.partial_density[i], &t, &x)) ++local;
          rs.temperature[i] = static_cast<float>(t);
          xr[i] = static_cast<float>(x);
        }
        over += local;
      },
      num_threads);
  rs.over_pure = over;
  for (std::size_t sp = 0; sp < n_species; ++sp) {
    const float xs = static_cast<float>(mix.released().mole_fractions()[sp]);
    rs.mole_fraction[sp].resize(n);
    for (std::size_t i = 0; i < n; ++i) rs.mole_fraction[sp][i] = xs * xr[i];
  }
  return rs;
}

}  // namespace qogi::synth
