// The puff simulation: continuity, kinematic consistency, reproducibility.
#include "engine/synth/plume.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "engine/synth/truth.h"

namespace qogi::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A growing, moving Gaussian puff obeys continuity: the flux through a plane
// equals the rate at which its mass moves to the plane's positive side.
TEST(PlaneMassFlux, EqualsTheRateOfChangeOfMassAcrossThePlane) {
  auto puff_at = [](double t) {
    PuffState p{};
    p.x = static_cast<float>(0.01 + 0.3 * t);
    p.y = static_cast<float>(-0.02 + 0.1 * t);
    p.z = static_cast<float>(0.05 + 0.8 * t);
    p.u = 0.3f;
    p.v = 0.1f;
    p.w = 0.8f;
    p.sigma = static_cast<float>(0.01 + 0.05 * t);
    p.sigma_rate = 0.05f;
    p.mass = 1e-6f;
    return p;
  };
  const double normals[3][3] = {{0, 0, 1}, {1, 0, 0}, {0.3, -0.2, 1.0}};
  for (const auto& nrm : normals) {
    ControlPlane plane;
    plane.point[0] = 0.02;
    plane.point[1] = 0.0;
    plane.point[2] = 0.07;
    for (int k = 0; k < 3; ++k) plane.normal[k] = nrm[k];
    const double norm = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    auto mass_beyond = [&](double t) {
      const PuffState p = puff_at(t);
      const double d = (nrm[0] * (p.x - plane.point[0]) + nrm[1] * (p.y - plane.point[1]) +
                        nrm[2] * (p.z - plane.point[2])) /
                       norm;
      return p.mass * 0.5 * std::erfc(-d / (std::sqrt(2.0) * p.sigma));
    };
    for (double t : {0.0, 0.01, 0.03}) {
      const double h = 1e-4;
      const double rate = (mass_beyond(t + h) - mass_beyond(t - h)) / (2 * h);
      const double flux = PlaneMassFlux({puff_at(t)}, plane);
      EXPECT_NEAR(flux, rate, 1e-4 * std::abs(rate) + 1e-12) << t;
    }
  }
}

Release LabRelease() {
  Release r;  // 5 SLPM CH4, 1.9 cm exit, laminar, small draft
  r.exit_temperature_K = r.ambient_temperature_K = 294.45;
  r.draft_m_s = 0.02;
  return r;
}

View LabView() {
  View v;
  v.width_px = 96;
  v.height_px = 96;
  v.ifov_rad = 24.0 / 320 * kPi / 180;
  v.distance_m = 1.5;
  v.center_z_m = 40 * v.footprint_m();
  return v;
}

TEST(PlumeSimulation, IsReproducibleOnAnyNumberOfThreads) {
  const PlumeSimulation a(LabRelease(), LabView(), 0.5, 30, {}, 1);
  const PlumeSimulation b(LabRelease(), LabView(), 0.5, 30, {}, 2);
  ASSERT_EQ(a.num_frames(), 15);
  for (int f = 0; f < a.num_frames(); ++f) {
    const auto& pa = a.puffs(f);
    const auto& pb = b.puffs(f);
    ASSERT_EQ(pa.size(), pb.size());
    for (std::size_t i = 0; i < pa.size(); ++i) {
      EXPECT_EQ(pa[i].id, pb[i].id);
      EXPECT_EQ(pa[i].x, pb[i].x);
      EXPECT_EQ(pa[i].z, pb[i].z);
      EXPECT_EQ(pa[i].w, pb[i].w);
    }
  }
  PlumeModelOptions other;
  other.seed = 7;
  const PlumeSimulation c(LabRelease(), LabView(), 0.5, 30, other, 2);
  double diff = 0;
  for (std::size_t i = 0; i < std::min(c.puffs(10).size(), a.puffs(10).size()); ++i)
    diff += std::abs(c.puffs(10)[i].x - a.puffs(10)[i].x);
  EXPECT_GT(diff, 0.0);
  EXPECT_THROW(a.puffs(15), std::out_of_range);
}

// The velocity reported for each puff is the derivative of its trajectory.
// Trajectories are smooth between the mean-flow stations and may change slope
// at a station, so the central difference over two frames must lie within the
// range of the velocities reported at the three frames (1 % of the speed
// allowed for float32 positions).
TEST(PlumeSimulation, VelocitiesAreTheDerivativesOfThePositions) {
  Release r = LabRelease();
  r.draft_m_s = 0.05;
  const double rate = 5000;
  const PlumeSimulation sim(r, LabView(), 0.0008, rate);
  std::map<std::uint32_t, PuffState> before, after;
  for (const PuffState& p : sim.puffs(1)) before[p.id] = p;
  for (const PuffState& p : sim.puffs(3)) after[p.id] = p;
  int checked = 0;
  for (const PuffState& p : sim.puffs(2)) {
    auto a = before.find(p.id), b = after.find(p.id);
    if (a == before.end() || b == after.end()) continue;
    const PuffState &pa = a->second, &pb = b->second;
    const double dt = 2 / rate;
    const double tol = 0.01 * std::sqrt(p.u * p.u + p.v * p.v + p.w * p.w) + 1e-4;
    auto within = [&](double fd, double v0, double v1, double v2, const char* what) {
      EXPECT_GE(fd, std::min({v0, v1, v2}) - tol) << what << " puff " << p.id;
      EXPECT_LE(fd, std::max({v0, v1, v2}) + tol) << what << " puff " << p.id;
    };
    within((pb.x - pa.x) / dt, pa.u, p.u, pb.u, "u");
    within((pb.y - pa.y) / dt, pa.v, p.v, pb.v, "v");
    within((pb.z - pa.z) / dt, pa.w, p.w, pb.w, "w");
    within((pb.sigma - pa.sigma) / dt, pa.sigma_rate, p.sigma_rate, pb.sigma_rate, "sigma");
    ++checked;
  }
  EXPECT_GT(checked, 100);
  EXPECT_EQ(sim.stats().puffs_lost_inside, 0u);
}

}  // namespace
}  // namespace qogi::synth
