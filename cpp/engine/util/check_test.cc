#include "engine/util/check.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace qogi {
namespace {

std::string MessageOf(void (*f)()) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Check, MessagesNameArgumentValueAndRange) {
  const std::string m = MessageOf([] { CheckPositive(-5, "temperature_K", "K"); });
  EXPECT_NE(m.find("temperature_K"), std::string::npos);
  EXPECT_NE(m.find("> 0"), std::string::npos);
  EXPECT_NE(m.find("-5"), std::string::npos);
  const std::string r = MessageOf([] { CheckInRange(2, 0, 1, "x_peak"); });
  EXPECT_NE(r.find("[0, 1]"), std::string::npos);
  EXPECT_NE(r.find("got 2"), std::string::npos);
}

TEST(Check, RejectsNaN) {
  EXPECT_THROW(CheckFinite(std::nan(""), "v"), std::invalid_argument);
  EXPECT_THROW(CheckNonNegative(std::nan(""), "v"), std::invalid_argument);
  EXPECT_NO_THROW(CheckNonNegative(0.0, "v"));
}

}  // namespace
}  // namespace qogi
