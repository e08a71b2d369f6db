#include "engine/spectra/isotopologue.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace qogi {
namespace {

TEST(Isotopologue, MoleculeCodes) {
  EXPECT_EQ(MoleculeId("H2O"), 1);
  EXPECT_EQ(MoleculeId("co2"), 2);
  EXPECT_EQ(MoleculeId("CH4"), 6);
  EXPECT_EQ(MoleculeFormula(6), "CH4");
  EXPECT_TRUE(IsKnownMolecule(3));  // O3: known, but no partition sums shipped
  EXPECT_FALSE(IsKnownMolecule(99));
  EXPECT_THROW(MoleculeId("XYZ"), std::invalid_argument);
  EXPECT_THROW(MoleculeFormula(99), std::invalid_argument);
}

TEST(Isotopologue, ShipsAllWaterAndMainCo2Ch4Isotopologues) {
  for (int i = 1; i <= 6; ++i) EXPECT_NE(FindIsotopologue(1, i), nullptr) << i;
  for (int i = 1; i <= 4; ++i) EXPECT_NE(FindIsotopologue(2, i), nullptr) << i;
  for (int i = 1; i <= 4; ++i) EXPECT_NE(FindIsotopologue(6, i), nullptr) << i;
  // Molar masses (HITRAN) of the main isotopologues.
  EXPECT_NEAR(GetIsotopologue(1, 1).molar_mass_g_mol, 18.010565, 1e-6);
  EXPECT_NEAR(GetIsotopologue(2, 1).molar_mass_g_mol, 43.98983, 1e-5);
  EXPECT_NEAR(GetIsotopologue(6, 1).molar_mass_g_mol, 16.0313, 1e-4);
  EXPECT_NEAR(GetIsotopologue(6, 1).abundance, 0.988274, 1e-6);
}

TEST(Isotopologue, ReferencePartitionSumsMatchHitran) {
  // Q(296 K) as listed by HITRAN (molparam.txt, HITRAN2020): H2O 161, CO2 626,
  // CH4 211. TIPS-2025 agrees to well within 0.1%.
  EXPECT_NEAR(GetIsotopologue(1, 1).q_ref / 174.58 - 1, 0, 1e-3);
  EXPECT_NEAR(GetIsotopologue(2, 1).q_ref / 286.09 - 1, 0, 1e-3);
  EXPECT_NEAR(GetIsotopologue(6, 1).q_ref / 590.48 - 1, 0, 1e-3);
  EXPECT_DOUBLE_EQ(PartitionSum(6, 1, 296.0), GetIsotopologue(6, 1).q_ref);
}

TEST(Isotopologue, RotorScalingAtLowTemperature) {
  // Below ~200 K the vibrations of CH4 and CO2 are frozen out (lowest modes
  // 1306 and 667 cm-1) and Q is the rotational sum. Its high-temperature
  // expansion (e.g. Herzberg; McDowell, J. Chem. Phys. 88 (1988) 356):
  //   spherical top CH4: Q ~ T^1.5 (1 + b/T), b = hcB/(4k), B = 5.241 cm-1;
  //   linear CO2:        Q ~ T (1 + b/T),     b = hcB/(3k), B = 0.3902 cm-1,
  // times the CO2 bending-mode factor 1 + 2 exp(-667 c2/T) at 150 K.
  const double c2 = 1.4387768775;
  const double b_ch4 = c2 * 5.241 / 4;
  EXPECT_NEAR(PartitionSum(6, 1, 200) / PartitionSum(6, 1, 100),
              std::pow(2.0, 1.5) * (1 + b_ch4 / 200) / (1 + b_ch4 / 100), 3e-3 * 2.8);
  const double b_co2 = c2 * 0.3902 / 3;
  EXPECT_NEAR(PartitionSum(2, 1, 150) / PartitionSum(2, 1, 75),
              2.0 * (1 + b_co2 / 150) / (1 + b_co2 / 75) * (1 + 2 * std::exp(-667 * c2 / 150)),
              3e-3 * 2.0);
}

TEST(Isotopologue, InterpolationIsSmoothBetweenNodes) {
  // Q is smooth: the interpolant between the 10 K nodes must not wiggle, so
  // the second difference on a 1 K grid stays tiny relative to Q.
  double prev2 = PartitionSum(6, 1, 250), prev1 = PartitionSum(6, 1, 251);
  for (double t = 252; t <= 350; t += 1) {
    const double q = PartitionSum(6, 1, t);
    EXPECT_GT(q, prev1);
    EXPECT_LT(std::abs(q - 2 * prev1 + prev2) / q, 1e-4) << t;
    prev2 = prev1, prev1 = q;
  }
}

TEST(Isotopologue, ClearErrors) {
  try {
    GetIsotopologue(3, 1);
    FAIL();
  } catch (const std::invalid_argument& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("O3"), std::string::npos);
    EXPECT_NE(m.find("no partition-sum"), std::string::npos);
    EXPECT_NE(m.find("CH4"), std::string::npos);
  }
  EXPECT_THROW(PartitionSum(6, 1, 5000.0), std::invalid_argument);  // CH4 table ends at 2500 K
  EXPECT_THROW(PartitionSum(6, 1, -1.0), std::invalid_argument);
  EXPECT_THROW(PartitionSum(6, 9, 296.0), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
