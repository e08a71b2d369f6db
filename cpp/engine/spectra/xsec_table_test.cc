#include "engine/spectra/xsec_table.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/spectra/test_data.h"

namespace qogi {
namespace {

using testing_util::ScratchDir;

CrossSectionOptions Fixed25() {
  CrossSectionOptions o;
  o.wing_half_widths = 0;
  o.wing_cm1 = 25;
  return o;
}

struct Fixture {
  LineList lines;
  WavenumberGrid grid;
  std::vector<double> temps;
  Fixture() {
    LineSelection sel;
    sel.nu_min_cm1 = 3025, sel.nu_max_cm1 = 3085;
    lines = ReadLineFile(testing_util::HitranDir() + "/CH4.par.gz", sel);
    grid = WavenumberGrid::FromRange(3050, 3060, 0.01);
    for (double t = 200; t <= 800; t += 10) temps.push_back(t);
  }
};

const Fixture& F() {
  static const Fixture f;
  return f;
}

const XsecTable& Table() {
  static const XsecTable t =
      XsecTable::Build(F().lines, F().grid, F().temps, 101325.0, 0.0, Fixed25());
  return t;
}

TEST(XsecTable, StoresTheComputedRows) {
  const XsecTable& t = Table();
  ASSERT_EQ(t.num_temperatures(), 61u);
  ASSERT_EQ(t.num_wavenumbers(), F().grid.size);
  const std::vector<double> direct =
      CrossSection(F().lines, GasConditions{400.0, 101325.0, 0.0}, F().grid, Fixed25());
  const std::vector<double> at_node = t.Spectrum(400.0);
  for (std::size_t j = 0; j < direct.size(); ++j) {
    EXPECT_NEAR(t.row(20)[j], direct[j], 1e-6 * direct[j]);
    EXPECT_NEAR(at_node[j], direct[j], 1e-6 * direct[j]);
  }
}

TEST(XsecTable, InterpolationErrorAtOffGridTemperatures) {
  const XsecTable& t = Table();
  for (double temp : {203.0, 255.0, 296.0, 333.3, 517.0, 795.0}) {
    const std::vector<double> direct =
        CrossSection(F().lines, GasConditions{temp, 101325.0, 0.0}, F().grid, Fixed25());
    const std::vector<double> interp = t.Spectrum(temp);
    const double peak = *std::max_element(direct.begin(), direct.end());
    double worst = 0;
    for (std::size_t j = 0; j < direct.size(); ++j)
      if (direct[j] > 0.01 * peak) worst = std::max(worst, std::abs(interp[j] / direct[j] - 1));
    EXPECT_LT(worst, 1e-3) << temp;
    EXPECT_NEAR(t.Sigma(123, temp), interp[123], 1e-12 * interp[123]);
    const XsecTable::Stencil st = t.StencilAt(temp);
    EXPECT_NEAR(t.Sigma(st, 456), interp[456], 1e-12 * interp[456]);
  }
}

TEST(XsecTable, TemperatureDerivative) {
  const XsecTable& t = Table();
  const double temp = 437.0, h = 0.5;
  std::vector<double> s(F().grid.size), d(F().grid.size);
  t.Spectrum(temp, s.data(), d.data());
  const std::vector<double> up =
      CrossSection(F().lines, GasConditions{temp + h, 101325.0, 0.0}, F().grid, Fixed25());
  const std::vector<double> dn =
      CrossSection(F().lines, GasConditions{temp - h, 101325.0, 0.0}, F().grid, Fixed25());
  const double peak = *std::max_element(s.begin(), s.end());
  for (std::size_t j = 0; j < s.size(); ++j) {
    const double fd = (up[j] - dn[j]) / (2 * h);
    if (s[j] > 0.01 * peak) {
      EXPECT_NEAR(d[j], fd, 0.02 * std::abs(fd) + 2e-4 * s[j] / 10) << j;
    }
  }
}

TEST(XsecTable, ZerosFallBackToLinearInterpolation) {
  const WavenumberGrid g{100.0, 1.0, 3};
  // Point 0: all positive; point 1: a zero at 200 K; point 2: all zero.
  const std::vector<float> sigma = {1e-20f, 0.0f,   0.0f, 2e-20f, 1e-20f, 0.0f,
                                    4e-20f, 2e-20f, 0.0f, 8e-20f, 3e-20f, 0.0f};
  const XsecTable t(g, {200, 300, 400, 500}, 101325.0, 0.0, Fixed25(), sigma);
  // ln sigma is linear in T for point 0, so the cubic returns 2^(T/100 - 2) e-20.
  EXPECT_NEAR(t.Sigma(0, 350.0), std::pow(2.0, 1.5) * 1e-20, 1e-26);
  EXPECT_NEAR(t.Sigma(1, 250.0), 0.5e-20, 1e-27);  // linear between 0 and 1e-20
  EXPECT_NEAR(t.Sigma(1, 350.0), 1.5e-20, 1e-27);
  EXPECT_EQ(t.Sigma(2, 333.0), 0.0);
  EXPECT_THROW(t.Sigma(0, 199.0), std::invalid_argument);
  EXPECT_THROW(t.Sigma(0, 501.0), std::invalid_argument);
  EXPECT_THROW(t.Sigma(3, 300.0), std::invalid_argument);
  EXPECT_THROW(XsecTable(g, {200, 200, 400, 500}, 1e5, 0, Fixed25(), sigma), std::invalid_argument);
  EXPECT_THROW(XsecTable(g, {200, 300}, 1e5, 0, Fixed25(), sigma), std::invalid_argument);
  std::vector<float> negative = sigma;
  negative[4] = -1e-20f;
  EXPECT_THROW(XsecTable(g, {200, 300, 400, 500}, 1e5, 0, Fixed25(), negative),
               std::invalid_argument);
  // One or two temperatures: constant / linear.
  const XsecTable one(WavenumberGrid{100.0, 1.0, 1}, {300}, 1e5, 0, Fixed25(), {3e-20f});
  EXPECT_NEAR(one.Sigma(0, 300.0), 3e-20, 1e-27);
  const XsecTable two(WavenumberGrid{100.0, 1.0, 1}, {300, 400}, 1e5, 0, Fixed25(),
                      {1e-20f, 4e-20f});
  EXPECT_NEAR(two.Sigma(0, 350.0), 2e-20, 1e-26);  // geometric mean in ln sigma
}

std::string LoadError(const std::string& path) {
  try {
    XsecTable::Load(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(XsecTable, SaveLoadAndCorruption) {
  ScratchDir dir;
  XsecTable t = Table();
  t.set_metadata("{\"species\": \"CH4\"}");
  const std::string path = dir.File("t.qxs");
  t.Save(path);
  const XsecTable back = XsecTable::Load(path);
  EXPECT_EQ(back.sigma(), t.sigma());
  EXPECT_EQ(back.temperatures_K(), t.temperatures_K());
  EXPECT_EQ(back.metadata(), t.metadata());
  EXPECT_EQ(back.grid().size, t.grid().size);
  EXPECT_DOUBLE_EQ(back.grid().nu0_cm1, t.grid().nu0_cm1);
  EXPECT_DOUBLE_EQ(back.options().wing_cm1, 25.0);
  EXPECT_DOUBLE_EQ(back.pressure_Pa(), 101325.0);

  std::string bytes;
  {
    std::ifstream f(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  EXPECT_NE(LoadError(dir.Write("flip.qxs", flipped)).find("checksum"), std::string::npos);
  EXPECT_NE(
      LoadError(dir.Write("short.qxs", bytes.substr(0, bytes.size() - 100))).find("truncated"),
      std::string::npos);
  EXPECT_NE(LoadError(dir.Write("tiny.qxs", bytes.substr(0, 30))).find("truncated"),
            std::string::npos);
  std::string version = bytes;
  version[8] = 99;
  EXPECT_NE(LoadError(dir.Write("v.qxs", version)).find("format version 99"), std::string::npos);
  EXPECT_NE(LoadError(dir.Write("x.qxs", "hello")).find("not a qogi"), std::string::npos);
  EXPECT_NE(LoadError(dir.File("missing.qxs")).find("missing.qxs"), std::string::npos);
}

}  // namespace
}  // namespace qogi
