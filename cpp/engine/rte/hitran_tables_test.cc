#include "engine/rte/hitran_tables.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/spectra/test_data.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

using testing_util::HitranDir;

// Lines of one molecule from (wavenumber, intensity, lower-state energy).
LineList Lines(int molecule, const std::vector<std::vector<double>>& lines) {
  LineList l;
  for (const auto& v : lines) {
    l.molecule.push_back(molecule);
    l.isotopologue.push_back(1);
    l.nu_cm1.push_back(v[0]);
    l.intensity.push_back(v[1]);
    l.einstein_a.push_back(0.0);
    l.gamma_air.push_back(0.06);
    l.gamma_self.push_back(0.08);
    l.elower_cm1.push_back(v[2]);
    l.n_air.push_back(0.75);
    l.n_self.push_back(0.75);
    l.delta_air.push_back(-0.005);
    l.delta_self.push_back(-0.005);
  }
  l.ComputeCoverage();
  return l;
}

LineList Methane() {
  return Lines(6, {{3000.0, 2e-20, 100.0}, {3005.5, 1e-20, 300.0}, {3010.0, 5e-21, 600.0}});
}

SpectralResponse Band(double lo, double hi) { return SpectralResponse({lo, hi}, {1.0, 1.0}); }

AbsorberTableOptions Small() {
  AbsorberTableOptions o;
  o.temperatures_K = {250.0, 300.0, 350.0};
  return o;
}

TEST(AbsorberTableGrid, BandNarrowedToTheLinesAndTheirWings) {
  // A wide band: the lines +- 25 cm-1 decide.
  const WavenumberGrid wide = AbsorberTableGrid("CH4", Methane(), {Band(2900, 3100)}, 0.01);
  EXPECT_NEAR(wide.nu0_cm1, 2975.0, 1e-9);
  EXPECT_NEAR(wide.last_cm1(), 3035.0, 1e-9);
  // Several channels: from the lowest start to the highest end.
  const WavenumberGrid two =
      AbsorberTableGrid("CH4", Methane(), {Band(3002.0, 3003.0), Band(2990.0, 2991.0)}, 0.01);
  EXPECT_NEAR(two.nu0_cm1, 2990.0, 1e-9);
  EXPECT_NEAR(two.last_cm1(), 3003.0, 1e-9);
}

TEST(AbsorberTableGrid, StartsOnAMultipleOfTheStepSoThatSpeciesShareOneLattice) {
  const WavenumberGrid g = AbsorberTableGrid("CH4", Methane(), {Band(3001.237, 3003.0)}, 0.01);
  EXPECT_DOUBLE_EQ(g.nu0_cm1, std::floor(3001.237 / 0.01) * 0.01);
  EXPECT_NEAR(g.nu0_cm1, 3001.23, 1e-9);
  EXPECT_LE(g.last_cm1(), 3003.0 + 1e-9);
  EXPECT_GT(g.last_cm1(), 3003.0 - 0.01);
  const LineList co = Lines(5, {{2990.0, 1e-21, 0.0}});
  const WavenumberGrid h = AbsorberTableGrid("CO", co, {Band(3001.237, 3003.0)}, 0.01);
  EXPECT_EQ(h.nu0_cm1, g.nu0_cm1);
  const WavenumberGrid coarse = AbsorberTableGrid("CH4", Methane(), {Band(3001.237, 3003.0)}, 0.03);
  const double k = coarse.nu0_cm1 / 0.03;
  EXPECT_NEAR(k, std::round(k), 1e-9);
  EXPECT_LE(coarse.nu0_cm1, 3001.237);
  EXPECT_GT(coarse.nu0_cm1, 3001.237 - 0.03);
}

TEST(AbsorberTableGrid, LinesOutsideEveryBandNameTheSpeciesAndTheFix) {
  const LineList co2 = Lines(2, {{2300.0, 1e-19, 0.0}, {2349.1, 1e-18, 0.0}});
  try {
    AbsorberTableGrid("CO2", co2, {Band(2900, 3100), Band(3200, 3300)}, 0.01);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "the CO2 line list (2300.0-2349.1 cm-1) does not reach any channel's band; drop "
              "CO2 from the species or give a line list that covers the channels");
  }
}

TEST(BuildAbsorberTable, AirAndSelfTablesAreTheSpectraTablesOnTheRangeRulesGrid) {
  const AbsorberTableOptions o = Small();
  const std::vector<SpectralResponse> ch = {Band(2900, 3100)};
  const AbsorberTable t = BuildAbsorberTable("CH4", Methane(), ch, o);
  const WavenumberGrid g = AbsorberTableGrid("CH4", Methane(), ch, o.step_cm1);
  EXPECT_EQ(t.species, "CH4");
  EXPECT_EQ(t.pressure_Pa, 101325.0);
  EXPECT_EQ(t.nu0_cm1, g.nu0_cm1);
  EXPECT_EQ(t.dnu_cm1, 0.01);
  EXPECT_EQ(t.n_nu, g.size);
  EXPECT_EQ(t.temperatures_K, o.temperatures_K);
  const CrossSectionOptions xs = o.cross_section_options();
  EXPECT_EQ(xs.wing_cm1, 25.0);
  EXPECT_EQ(xs.wing_half_widths, 0.0);
  const XsecTable air = XsecTable::Build(Methane(), g, o.temperatures_K, 101325.0, 0.0, xs);
  const XsecTable self = XsecTable::Build(Methane(), g, o.temperatures_K, 101325.0, 1.0, xs);
  EXPECT_EQ(t.sigma_air, air.sigma());
  EXPECT_EQ(t.sigma_self, self.sigma());
  // Self-broadened lines are wider: lower peaks, so the tables differ.
  EXPECT_NE(t.sigma_air, t.sigma_self);

  AbsorberTableOptions air_only = o;
  air_only.self_broadening = false;
  air_only.wing_cm1 = 0.0;
  air_only.wing_half_widths = 50.0;  // HAPI's rule
  const AbsorberTable h = BuildAbsorberTable("CH4", Methane(), ch, air_only);
  EXPECT_FALSE(h.has_self());
  const XsecTable hapi = XsecTable::Build(Methane(), g, o.temperatures_K, 101325.0, 0.0,
                                          air_only.cross_section_options());
  EXPECT_EQ(h.sigma_air, hapi.sigma());
  EXPECT_NE(h.sigma_air, t.sigma_air);
}

TEST(BuildAbsorberTables, ReadsTheShippedLineListsFromTheSearchPath) {
  LineSources sources;
  sources.fallback = {HitranDir()};
  const std::vector<SpectralResponse> ch = {Band(3050.0, 3051.0)};
  std::vector<double> seen;
  RunControl control;
  control.progress = [&](double f) { seen.push_back(f); };
  const auto tables = BuildAbsorberTables({"CH4"}, ch, sources, Small(), &control);
  ASSERT_EQ(tables.size(), 1u);
  const AbsorberTable direct =
      BuildAbsorberTable("CH4", ReadMoleculeLines({HitranDir() + "/CH4.par.gz"}, 6), ch, Small());
  EXPECT_EQ(tables[0].sigma_air, direct.sigma_air);
  EXPECT_EQ(tables[0].sigma_self, direct.sigma_self);
  ASSERT_FALSE(seen.empty());
  for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_GE(seen[i], seen[i - 1]);
  EXPECT_DOUBLE_EQ(seen.back(), 1.0);

  // A user's file wins over the search path.
  sources.paths["CH4"] = {HitranDir() + "/CO2.par.gz"};
  EXPECT_THROW(BuildAbsorberTables({"CH4"}, ch, sources, Small()), std::invalid_argument);
  // An unknown species fails before any table is built.
  EXPECT_THROW(BuildAbsorberTables({"CH4", "XYZ"}, ch, LineSources(), Small()),
               std::invalid_argument);
}

TEST(BuildAbsorberTables, CancelledThroughTheRunControl) {
  RunControl control;
  control.cancelled = [] { return true; };
  EXPECT_THROW(BuildAbsorberTable("CH4", Methane(), {Band(2900, 3100)}, Small(), &control),
               Cancelled);
}

TEST(BuildAbsorberTables, ACallersTableMakerIsUsedAndChecked) {
  int calls = 0;
  const XsecTableMaker maker = [&](const std::string&, const LineList& lines,
                                   const WavenumberGrid& grid, const std::vector<double>& temps,
                                   double p, double x, const CrossSectionOptions& o,
                                   const RunControl* c) {
    ++calls;
    return XsecTable::Build(lines, grid, temps, p, x, o, ComputeSettings(), c);
  };
  const std::vector<SpectralResponse> ch = {Band(2990, 3020)};
  const AbsorberTable t = BuildAbsorberTable("CH4", Methane(), ch, Small(), nullptr, maker);
  EXPECT_EQ(calls, 2);
  EXPECT_EQ(t.sigma_self, BuildAbsorberTable("CH4", Methane(), ch, Small()).sigma_self);
  const XsecTableMaker wrong = [&](const std::string&, const LineList& lines,
                                   const WavenumberGrid& grid, const std::vector<double>& temps,
                                   double p, double x, const CrossSectionOptions& o,
                                   const RunControl* c) {
    return XsecTable::Build(lines, grid, temps, p * 0.5, x, o, ComputeSettings(), c);
  };
  EXPECT_THROW(BuildAbsorberTable("CH4", Methane(), ch, Small(), nullptr, wrong), std::logic_error);
}

TEST(AbsorberTableOptions, RejectBadSettings) {
  AbsorberTableOptions o;
  EXPECT_EQ(o.temperatures_K.size(), 41u);
  EXPECT_EQ(o.temperatures_K.front(), 200.0);
  EXPECT_EQ(o.temperatures_K.back(), 600.0);
  o.Check();
  auto bad = [](auto change) {
    AbsorberTableOptions b;
    change(b);
    EXPECT_THROW(b.Check(), std::invalid_argument);
  };
  bad([](AbsorberTableOptions& b) { b.pressure_Pa = 0; });
  bad([](AbsorberTableOptions& b) { b.step_cm1 = -0.01; });
  bad([](AbsorberTableOptions& b) { b.temperatures_K = {300.0}; });
  bad([](AbsorberTableOptions& b) { b.temperatures_K = {300.0, 300.0}; });
  bad([](AbsorberTableOptions& b) { b.wing_cm1 = 0; });
  bad([](AbsorberTableOptions& b) { b.num_threads = -1; });
}

}  // namespace
}  // namespace qogi
