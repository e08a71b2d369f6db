// Per-pixel statistics over time against hand-computed values of numpy's
// definitions (np.percentile's linear method, np.median of the differences'
// absolute deviations), a strided stack, and the refusals.
#include "engine/background/temporal_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace qogi {
namespace {

TEST(TemporalStats, PercentilesInterpolateBetweenOrderStatistics) {
  // One pixel over 5 frames: 3, 1, 4, 1, 5 -> sorted 1 1 3 4 5.
  const std::vector<float> f{3, 1, 4, 1, 5};
  std::vector<double> out(4);
  TemporalPercentiles(f.data(), 5, 1, 1, {0.0, 50.0, 90.0, 100.0}, out.data());
  EXPECT_DOUBLE_EQ(out[0], 1.0);
  EXPECT_DOUBLE_EQ(out[1], 3.0);        // index 2
  EXPECT_DOUBLE_EQ(out[2], 5.0 - 0.4);  // index 3.6: 4 + 0.6 (5 - 4)
  EXPECT_DOUBLE_EQ(out[3], 5.0);
}

TEST(TemporalStats, AStridedStackReadsEachFramesFirstValues) {
  // 3 frames of 4 values each, of which the first 2 are the stack asked for.
  const std::vector<double> f{1, 10, -1, -1, 3, 30, -1, -1, 2, 20, -1, -1};
  std::vector<double> out(2);
  TemporalPercentiles(f.data(), 3, 4, 2, {50.0}, out.data());
  EXPECT_DOUBLE_EQ(out[0], 2.0);
  EXPECT_DOUBLE_EQ(out[1], 20.0);
  std::vector<double> spread(2);
  DifferenceSpread(f.data(), 3, 4, 2, spread.data());
  // differences +2, -1: median 0.5, deviations 1.5 and 1.5 -> 1.5 (x10 for the second)
  EXPECT_DOUBLE_EQ(spread[0], 1.5);
  EXPECT_DOUBLE_EQ(spread[1], 15.0);
}

TEST(TemporalStats, DifferenceSpreadIsTheMedianAbsoluteDeviationOfDifferences) {
  // 0 1 3 6 10: differences 1 2 3 4, median 2.5, deviations 1.5 .5 .5 1.5 -> 1.
  const std::vector<float> f{0, 1, 3, 6, 10};
  float out = 0;
  DifferenceSpread(f.data(), 5, 1, 1, &out);
  EXPECT_FLOAT_EQ(out, 1.0f);
}

TEST(TemporalStats, NaNInASeriesGivesNaN) {
  const std::vector<float> f{1, std::numeric_limits<float>::quiet_NaN(), 3};
  std::vector<double> out(1);
  TemporalPercentiles(f.data(), 3, 1, 1, {50.0}, out.data());
  EXPECT_TRUE(std::isnan(out[0]));
}

TEST(TemporalStats, RefusesPercentilesOutOfRangeTooFewFramesAndShortStrides) {
  const std::vector<float> f{1, 2, 3, 4};
  std::vector<double> out(4);
  EXPECT_THROW(TemporalPercentiles(f.data(), 4, 1, 1, {101.0}, out.data()), std::invalid_argument);
  EXPECT_THROW(TemporalPercentiles(f.data(), 0, 1, 1, {50.0}, out.data()), std::invalid_argument);
  float s = 0;
  EXPECT_THROW(DifferenceSpread(f.data(), 1, 1, 1, &s), std::invalid_argument);
  EXPECT_THROW(TemporalPercentiles(f.data(), 2, 1, 2, {50.0}, out.data()), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
