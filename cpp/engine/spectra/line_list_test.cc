#include "engine/spectra/line_list.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "engine/spectra/test_data.h"

namespace qogi {
namespace {

using testing_util::HitranDir;
using testing_util::ScratchDir;

std::string Pad(const std::string& s, std::size_t width) {
  EXPECT_LE(s.size(), width) << s;
  return std::string(width - s.size(), ' ') + s;
}

// One 160-character HITRAN record from field texts.
std::string Par(const std::string& mol, const std::string& iso, const std::string& nu,
                const std::string& s, const std::string& gair, const std::string& gself,
                const std::string& elower, const std::string& nair, const std::string& dair) {
  std::string r = Pad(mol, 2) + Pad(iso, 1) + Pad(nu, 12) + Pad(s, 10) + Pad("1.000E-01", 10) +
                  Pad(gair, 5) + Pad(gself, 5) + Pad(elower, 10) + Pad(nair, 4) + Pad(dair, 8);
  r += std::string(60, ' ');                                  // quanta
  r += "455343453633 3 4 4" + std::string(1, ' ');            // ierr, iref, flag
  r += Pad("99.0", 7) + Pad("105.0", 7);
  EXPECT_EQ(r.size(), 160u);
  return r;
}

std::string ThreeRecords(const std::string& eol) {
  return Par("6", "1", "3000.100000", "1.000E-20", ".0500", "0.070", "100.0000", "0.75",
             "-.005000") +
         eol +
         Par("6", "2", "3000.200000", "2.000E-21", ".0400", "0.060", "200.0000", "0.70",
             "-.004000") +
         eol +
         Par("2", "A", "2300.000000", "3.000E-22", ".0700", "0.090", "300.0000", "0.65",
             "0.001000") +
         eol;
}

void ExpectThreeRecords(const LineList& l) {
  ASSERT_EQ(l.size(), 3u);
  // Sorted by wavenumber: the CO2 line first.
  EXPECT_EQ(l.molecule[0], 2);
  EXPECT_EQ(l.isotopologue[0], 11);  // 'A' = 11
  EXPECT_DOUBLE_EQ(l.nu_cm1[0], 2300.0);
  EXPECT_DOUBLE_EQ(l.delta_air[0], 0.001);
  EXPECT_EQ(l.molecule[1], 6);
  EXPECT_EQ(l.isotopologue[1], 1);
  EXPECT_DOUBLE_EQ(l.nu_cm1[1], 3000.1);
  EXPECT_DOUBLE_EQ(l.intensity[1], 1e-20);
  EXPECT_DOUBLE_EQ(l.einstein_a[1], 0.1);
  EXPECT_DOUBLE_EQ(l.gamma_air[1], 0.05);
  EXPECT_DOUBLE_EQ(l.gamma_self[1], 0.07);
  EXPECT_DOUBLE_EQ(l.elower_cm1[1], 100.0);
  EXPECT_DOUBLE_EQ(l.n_air[1], 0.75);
  EXPECT_DOUBLE_EQ(l.delta_air[1], -0.005);
  // .par has no self exponent or self shift: n_air and delta_air stand in.
  EXPECT_DOUBLE_EQ(l.n_self[1], 0.75);
  EXPECT_DOUBLE_EQ(l.delta_self[1], -0.005);
  EXPECT_EQ(l.isotopologue[2], 2);
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadLineFile(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(LineList, ReadsParPlainCrlfAndGzip) {
  ScratchDir dir;
  ExpectThreeRecords(ReadLineFile(dir.Write("a.par", ThreeRecords("\n"))));
  ExpectThreeRecords(ReadLineFile(dir.Write("b.par", ThreeRecords("\r\n"))));
  ExpectThreeRecords(ReadLineFile(dir.Write("c.par", ThreeRecords("\r\r\n") + "\n\n")));
  const std::string gz = dir.File("d.par.gz");
  gzFile f = gzopen(gz.c_str(), "wb");
  const std::string text = ThreeRecords("\r\n");
  gzwrite(f, text.data(), static_cast<unsigned>(text.size()));
  gzclose(f);
  ExpectThreeRecords(ReadLineFile(gz));
}

TEST(LineList, SelectsByRangeIsotopologueMoleculeAndIntensity) {
  ScratchDir dir;
  const std::string p = dir.Write("a.par", ThreeRecords("\n"));
  LineSelection s;
  s.nu_min_cm1 = 2500;
  EXPECT_EQ(ReadLineFile(p, s).size(), 2u);
  s.isotopologues = {2};
  EXPECT_EQ(ReadLineFile(p, s).size(), 1u);
  LineSelection t;
  t.min_intensity = 5e-21;
  EXPECT_EQ(ReadLineFile(p, t).size(), 1u);
  LineSelection m;
  m.molecule = 2;
  const LineList co2 = ReadLineFile(p, m);
  ASSERT_EQ(co2.size(), 1u);
  EXPECT_EQ(co2.molecule[0], 2);
  // Coverage is of the file, before selection.
  LineSelection narrow;
  narrow.nu_min_cm1 = 3000.15;
  const LineList l = ReadLineFile(p, narrow);
  ASSERT_EQ(l.size(), 1u);
  bool found = false;
  for (const LineCoverage& c : l.coverage)
    if (c.molecule == 6 && c.isotopologue == 1) {
      found = true;
      EXPECT_DOUBLE_EQ(c.nu_min_cm1, 3000.1);
    }
  EXPECT_TRUE(found);
  LineSelection bad;
  bad.nu_min_cm1 = 10, bad.nu_max_cm1 = 5;
  EXPECT_THROW(ReadLineFile(p, bad), std::invalid_argument);
}

TEST(LineList, MalformedRecordsNameFileLineAndField) {
  ScratchDir dir;
  const std::string good =
      Par("6", "1", "3000.100000", "1.000E-20", ".0500", "0.070", "100.0000", "0.75", "-.005000");
  // Truncated record on line 2.
  std::string m = ErrorOf(dir.Write("trunc.par", good + "\n" + good.substr(0, 42) + "\n"));
  EXPECT_NE(m.find("trunc.par:2:"), std::string::npos) << m;
  EXPECT_NE(m.find("truncated"), std::string::npos) << m;
  EXPECT_NE(m.find("gamma_self"), std::string::npos) << m;
  // Not a number in the intensity field on line 3.
  std::string bad = good;
  bad.replace(15, 10, " 1.0X0E-20");
  m = ErrorOf(dir.Write("field.par", good + "\n" + good + "\n" + bad + "\n"));
  EXPECT_NE(m.find("field.par:3:"), std::string::npos) << m;
  EXPECT_NE(m.find("'sw' (columns 16-25)"), std::string::npos) << m;
  EXPECT_NE(m.find("not a number"), std::string::npos) << m;
  // Unknown molecule code.
  m = ErrorOf(dir.Write("mol.par", "99" + good.substr(2) + "\n"));
  EXPECT_NE(m.find("mol.par:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("molec_id"), std::string::npos) << m;
  EXPECT_NE(m.find("unknown HITRAN molecule code 99"), std::string::npos) << m;
  // Bad isotopologue character.
  m = ErrorOf(dir.Write("iso.par", good.substr(0, 2) + "*" + good.substr(3) + "\n"));
  EXPECT_NE(m.find("local_iso_id"), std::string::npos) << m;
  // Too long.
  m = ErrorOf(dir.Write("long.par", good + "  xyz\n"));
  EXPECT_NE(m.find("long.par:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("160"), std::string::npos) << m;
  // Negative width.
  std::string neg = good;
  neg.replace(35, 5, "-.050");
  m = ErrorOf(dir.Write("neg.par", neg + "\n"));
  EXPECT_NE(m.find("gamma_air"), std::string::npos) << m;
  // Missing file.
  m = ErrorOf(dir.File("nope.par"));
  EXPECT_NE(m.find("nope.par"), std::string::npos) << m;
}

const char* kHeader = R"({
  "table_type": "column-fixed",
  "order": ["molec_id", "local_iso_id", "nu", "sw", "a", "gamma_air", "gamma_self",
            "elower", "n_air", "delta_air", "global_upper_quanta", "global_lower_quanta",
            "local_upper_quanta", "local_lower_quanta", "ierr", "iref",
            "line_mixing_flag", "gp", "gpp"],
  "format": {"molec_id": "%2d", "local_iso_id": "%1d", "nu": "%12.6f", "sw": "%10.3E",
             "a": "%10.3E", "gamma_air": "%5.4f", "gamma_self": "%5.3f",
             "elower": "%10.4f", "n_air": "%4.2f", "delta_air": "%8.6f",
             "global_upper_quanta": "%15s", "global_lower_quanta": "%15s",
             "local_upper_quanta": "%15s", "local_lower_quanta": "%15s", "ierr": "%6s",
             "iref": "%12s", "line_mixing_flag": "%1s", "gp": "%7.1f", "gpp": "%7.1f"},
  "extra": ["n_self", "delta_self"],
  "extra_format": {"n_self": "%7.4f", "delta_self": "%9.6f"},
  "extra_separator": ",",
  "description": {"nu": "Transition wavenumber \u00e9"}
})";

TEST(LineList, ReadsHapiDataWithHeaderAndExtraParameters) {
  ScratchDir dir;
  const std::string a =
      Par("6", "1", "3000.100000", "1.000E-20", ".0500", "0.070", "100.0000", "0.75", "-.005000");
  const std::string b =
      Par("6", "1", "3000.200000", "1.000E-20", ".0500", "0.070", "100.0000", "0.75", "-.005000");
  dir.Write("CH4.header", kHeader);
  const std::string p = dir.Write("CH4.data", a + ",0.6000,-0.009000\r\n" + b + ",#,#\r\n");
  const LineList l = ReadLineFile(p);
  ASSERT_EQ(l.size(), 2u);
  EXPECT_DOUBLE_EQ(l.n_self[0], 0.6);
  EXPECT_DOUBLE_EQ(l.delta_self[0], -0.009);
  EXPECT_DOUBLE_EQ(l.n_self[1], 0.75);      // '#' = missing: n_air stands in
  EXPECT_DOUBLE_EQ(l.delta_self[1], -0.005);
  // A header without a needed column.
  dir.Write("X.header", R"({"order": ["molec_id", "local_iso_id", "nu"],
    "format": {"molec_id": "%2d", "local_iso_id": "%1d", "nu": "%12.6f"}})");
  const std::string m = ErrorOf(dir.Write("X.data", a.substr(0, 15) + "\n"));
  EXPECT_NE(m.find("X.header"), std::string::npos) << m;
  EXPECT_NE(m.find("'sw'"), std::string::npos) << m;
  // Broken JSON.
  dir.Write("Y.header", "{\"order\": [");
  EXPECT_NE(ErrorOf(dir.Write("Y.data", a + "\n")).find("Y.header"), std::string::npos);
}

LineList Lines(std::initializer_list<std::tuple<int, int, double>> spec) {
  LineList l;
  for (const auto& [mol, iso, nu] : spec) {
    l.molecule.push_back(mol);
    l.isotopologue.push_back(iso);
    l.nu_cm1.push_back(nu);
    l.intensity.push_back(1e-20);
    l.einstein_a.push_back(0);
    l.gamma_air.push_back(0.05);
    l.gamma_self.push_back(0.07);
    l.elower_cm1.push_back(0);
    l.n_air.push_back(0.7);
    l.n_self.push_back(0.7);
    l.delta_air.push_back(0);
    l.delta_self.push_back(0);
  }
  l.ComputeCoverage();
  return l;
}

TEST(LineList, MergeKeepsHigherPriorityAndNeverCountsALineTwice) {
  const LineList newer = Lines({{1, 1, 100.0}, {1, 1, 150.0}, {1, 1, 200.0}});
  const LineList older = Lines(
      {{1, 1, 50.0}, {1, 1, 100.0}, {1, 1, 120.0}, {1, 1, 200.0}, {1, 1, 250.0}, {1, 2, 150.0}});
  const LineList m = MergeLineLists({newer, older});
  ASSERT_EQ(m.size(), 6u);  // newer's 3 + older's 50, 250 (iso 1) + 150 (iso 2)
  const double want[] = {50, 100, 150, 150, 200, 250};
  for (std::size_t i = 0; i < 6; ++i) EXPECT_DOUBLE_EQ(m.nu_cm1[i], want[i]);
  // The same list twice is the list once.
  EXPECT_EQ(MergeLineLists({older, older}).size(), older.size());
}

TEST(LineList, BundledCh4FileMatchesItsProvenance) {
  const LineList l = ReadLineFile(HitranDir() + "/CH4.par.gz");
  ASSERT_EQ(l.size(), 25126u);
  EXPECT_DOUBLE_EQ(l.nu_cm1.front(), 2832.861365);
  EXPECT_DOUBLE_EQ(l.nu_cm1.back(), 3246.301046);
  std::size_t strongest = 0;
  for (std::size_t i = 0; i < l.size(); ++i)
    if (l.intensity[i] > l.intensity[strongest]) strongest = i;
  EXPECT_DOUBLE_EQ(l.nu_cm1[strongest], 3067.300026);
  EXPECT_DOUBLE_EQ(l.intensity[strongest], 2.114e-19);
  for (std::size_t i = 0; i < l.size(); ++i) {
    ASSERT_EQ(l.molecule[i], 6);
    ASSERT_EQ(l.isotopologue[i], 1);
  }
}

TEST(LineList, BundledWaterFilesMergeWithoutOverlap) {
  const std::string newer = HitranDir() + "/H2O.par.gz";
  const std::string older = HitranDir() + "/H2O_HITRAN2012.par.gz";
  LineSelection s;
  s.nu_min_cm1 = 1800, s.nu_max_cm1 = 6700;
  const LineList a = ReadLineFile(newer, s), b = ReadLineFile(older, s);
  ASSERT_EQ(a.size(), 29211u);
  const LineList m = ReadLineFiles({newer, older}, s);
  // Expected: all of the newer file, plus the older file's lines of other
  // isotopologues, plus its main-isotopologue lines outside the newer span.
  std::size_t expect = a.size();
  for (std::size_t i = 0; i < b.size(); ++i)
    if (b.isotopologue[i] != 1 || b.nu_cm1[i] < a.nu_cm1.front() || b.nu_cm1[i] > a.nu_cm1.back())
      ++expect;
  EXPECT_EQ(m.size(), expect);
  EXPECT_GT(m.size(), a.size() + 10000);  // HDO, H2 18O ... were added
  std::size_t iso1_in_span = 0;
  for (std::size_t i = 0; i < m.size(); ++i)
    if (m.isotopologue[i] == 1 && m.nu_cm1[i] >= a.nu_cm1.front() && m.nu_cm1[i] <= a.nu_cm1.back())
      ++iso1_in_span;
  EXPECT_EQ(iso1_in_span, a.size());
  EXPECT_EQ(m.sources.size(), 2u);
}

}  // namespace
}  // namespace qogi
