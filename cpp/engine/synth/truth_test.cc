// Exact truth maps, fields and ray samples against closed forms and each other.
#include "engine/synth/truth.h"

#include <gtest/gtest.h>

#include <cmath>

namespace qogi::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;

View SmallView(Projection proj) {
  View v;
  v.width_px = 80;
  v.height_px = 64;
  v.ifov_rad = 1e-3;
  v.distance_m = 2.0;  // 2 mm pixels
  v.projection = proj;
  return v;
}

PuffState OnePuff() {
  PuffState p{};
  p.x = 0.004f;
  p.y = 0.01f;
  p.z = -0.006f;
  p.u = 0.2f;
  p.v = -0.1f;
  p.w = 0.5f;
  p.sigma = 0.01f;
  p.sigma_rate = 0.03f;
  p.mass = 2e-6f;
  return p;
}

TEST(TruthMaps, OrthographicPuffIsItsClosedForm) {
  const View v = SmallView(Projection::kOrthographic);
  const PuffState p = OnePuff();
  const TruthMaps m = ComputeTruthMaps({p}, v, 2);
  const double fp = v.footprint_m(), a = p.sigma_rate / p.sigma;
  double total = 0;
  for (int r = 0; r < v.height_px; ++r)
    for (int c = 0; c < v.width_px; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * v.width_px + c;
      total += m.column[i] * fp * fp;
      const double dx = v.PixelX(c, 0) - p.x, dz = v.PixelZ(r, 0) - p.z;
      // Closed form, cut off 6 widths from the puff (relative tail 1.5e-8).
      const double d2 = dx * dx + dz * dz;
      const double col =
          d2 > 36.0 * p.sigma * p.sigma
              ? 0.0
              : p.mass / (2 * kPi * p.sigma * p.sigma) * std::exp(-d2 / (2.0 * p.sigma * p.sigma));
      ASSERT_NEAR(m.column[i], col, 1e-9 * col + 1e-300);
      if (col > 0) {
        EXPECT_NEAR(m.velocity_x[i], p.u + a * dx, 1e-9);
        EXPECT_NEAR(m.velocity_z[i], p.w + a * dz, 1e-9);
        EXPECT_NEAR(m.flux_z[i], m.column[i] * m.velocity_z[i], 1e-12 * col);
      }
    }
  // Riemann sum of the Gaussian over the image (its edge is 5.8 widths away,
  // the cut-off 6 widths).
  EXPECT_NEAR(total, p.mass, 4e-8 * p.mass);
}

TEST(TruthMaps, PerspectiveRayThroughThePuffCentre) {
  View v = SmallView(Projection::kPerspective);
  PuffState p = OnePuff();
  // Put the centre on pixel (30, 20)'s ray.
  p.y = 0.05f;
  p.x = static_cast<float>(v.PixelX(30, p.y));
  p.z = static_cast<float>(v.PixelZ(20, p.y));
  const TruthMaps m = ComputeTruthMaps({p}, v, 1);
  EXPECT_NEAR(m.column[20 * v.width_px + 30], p.mass / (2 * kPi * p.sigma * p.sigma),
              1e-5 * p.mass / (p.sigma * p.sigma));
}

// The identity quantification rests on: summing column x mass-weighted
// vertical velocity x pixel length along an image row gives the mass flux
// through the horizontal plane of that row.
TEST(TruthMaps, RowFluxEqualsPlaneFlux) {
  Release r;
  r.exit_temperature_K = r.ambient_temperature_K = 294.45;
  r.draft_m_s = 0.02;
  View v = SmallView(Projection::kOrthographic);
  v.width_px = 160;
  v.height_px = 160;
  v.center_z_m = 70 * v.footprint_m();
  const PlumeSimulation sim(r, v, 0.2, 20);
  for (int frame : {0, 3}) {
    const TruthMaps m = ComputeTruthMaps(sim, frame);
    for (int row : {140, 110, 60}) {
      double line = 0;
      for (int c = 0; c < v.width_px; ++c) {
        const std::size_t i = static_cast<std::size_t>(row) * v.width_px + c;
        line += m.flux_z[i] * v.footprint_m();
      }
      ControlPlane plane;
      plane.point[2] = v.PixelZ(row, 0);
      const double flux = PlaneMassFlux(sim.puffs(frame), plane);
      // Exact up to the maps' 6-width cut-off (1.5e-8 of each puff).
      EXPECT_NEAR(line, flux, 5e-8 * sim.mass_rate_kg_s()) << frame << " " << row;
    }
  }
}

TEST(RaySamples, ColumnsMatchTheTruthAndOrderIsFarToNear) {
  Release r;
  r.composition = {{"CH4", 0.5}, {"CO2", 0.5}};
  r.exit_temperature_K = 363.15;
  r.ambient_temperature_K = 293.15;
  r.exit_diameter_m = 0.02;
  for (Projection proj : {Projection::kOrthographic, Projection::kPerspective}) {
    View v = SmallView(proj);
    v.center_z_m = 25 * v.footprint_m();
    const PlumeSimulation sim(r, v, 0.1, 20);
    const TruthMaps m = ComputeTruthMaps(sim, 1);
    const RaySamples rs = SampleRays(sim, 1, 0, v.height_px, 0, v.width_px);
    ASSERT_GT(rs.planes, 2);
    EXPECT_GT(rs.y_m.front(), rs.y_m.back());
    EXPECT_EQ(rs.over_pure, 0u);
    const std::size_t npix = static_cast<std::size_t>(v.width_px) * v.height_px;
    double max_col = 0;
    for (double c : m.column) max_col = std::max(max_col, c);
    ASSERT_EQ(rs.offset.size(), npix + 1);
    for (std::size_t i = 0; i < npix; ++i) {
      double col = 0;
      for (std::int64_t k = rs.offset[i]; k < rs.offset[i + 1]; ++k)
        col += rs.partial_density[k] * rs.path_m[i];
      if (rs.offset[i + 1] > rs.offset[i]) {
        EXPECT_GT(rs.partial_density[rs.offset[i]], 0.0f);
        EXPECT_LE(rs.first_plane[i] + (rs.offset[i + 1] - rs.offset[i]), rs.planes);
      }
      // Samples integrate each puff within a sphere of 5 widths, the truth
      // within 6 widths of the ray: the tails differ by < 1e-5 of the peak;
      // where the column exceeds 1e-3 of the peak samples and truth agree to
      // 0.5 % (what the renderer needs), above 1e-2 of the peak to 0.1 %.
      EXPECT_NEAR(col, m.column[i], 1e-5 * max_col);
      if (m.column[i] > 1e-3 * max_col) {
        EXPECT_NEAR(col / m.column[i], 1.0, 5e-3);
      }
      if (m.column[i] > 1e-2 * max_col) {
        EXPECT_NEAR(col / m.column[i], 1.0, 1e-3);
      }
      for (std::int64_t k = rs.offset[i]; k < rs.offset[i + 1]; ++k)
        if (rs.partial_density[k] == 0) {
          EXPECT_EQ(rs.temperature[k], static_cast<float>(293.15));
          EXPECT_EQ(rs.mole_fraction[0][k], 0.0f);
        }
    }
  }
}

TEST(Fields, GridIntegralsMatchMassAndPlaneFlux) {
  Release r;
  r.exit_temperature_K = r.ambient_temperature_K = 294.45;
  View v = SmallView(Projection::kOrthographic);
  v.center_z_m = 25 * v.footprint_m();
  const PlumeSimulation sim(r, v, 0.1, 20);
  const auto& puffs = sim.puffs(1);
  Grid g;
  g.dx = g.dy = g.dz = 1.5e-3;
  g.nx = g.ny = 81;
  g.nz = 61;
  g.x0 = g.y0 = -0.06;
  g.z0 = 0.01;
  const Fields f = ComputeFields(sim, 1, g, true, 2);
  // Flux through the plane z = z0 + 20 dz from the grid's rho w.
  const int k = 20;
  double grid_flux = 0;
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t n = (static_cast<std::size_t>(k) * g.ny + j) * g.nx + i;
      grid_flux += f.partial_density[n] * f.velocity_z[n] * g.dx * g.dy;
    }
  ControlPlane plane;
  plane.point[2] = g.z0 + k * g.dz;
  EXPECT_NEAR(grid_flux, PlaneMassFlux(puffs, plane), 2e-4 * sim.mass_rate_kg_s());
  EXPECT_EQ(f.over_pure, 0u);
  // Where there is no gas: ambient temperature, zero mole fraction, still air.
  for (std::size_t n = 0; n < g.size(); ++n)
    if (f.partial_density[n] == 0) {
      ASSERT_EQ(f.temperature[n], static_cast<float>(294.45));
      ASSERT_EQ(f.mole_fraction[n], 0.0f);
      ASSERT_EQ(f.velocity_z[n], 0.0f);
    }
}

}  // namespace
}  // namespace qogi::synth
