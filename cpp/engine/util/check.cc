#include "engine/util/check.h"

#include <cmath>
#include <cstdio>

namespace qogi {

std::string FormatNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

namespace {
std::string WithUnit(double v, const char* unit) {
  std::string s = FormatNumber(v);
  if (unit && *unit) s += std::string(" ") + unit;
  return s;
}
}  // namespace

void CheckFinite(double v, const char* name) {
  if (!std::isfinite(v))
    throw std::invalid_argument(std::string(name) + " must be finite; got " + FormatNumber(v));
}

void CheckPositive(double v, const char* name, const char* unit) {
  if (!(std::isfinite(v) && v > 0))
    throw std::invalid_argument(std::string(name) + " must be finite and > 0" +
                                (unit && *unit ? std::string(" ") + unit : "") + "; got " +
                                WithUnit(v, unit));
}

void CheckNonNegative(double v, const char* name, const char* unit) {
  if (!(std::isfinite(v) && v >= 0))
    throw std::invalid_argument(std::string(name) + " must be finite and >= 0" +
                                (unit && *unit ? std::string(" ") + unit : "") + "; got " +
                                WithUnit(v, unit));
}

void CheckInRange(double v, double lo, double hi, const char* name, const char* unit) {
  if (!(std::isfinite(v) && v >= lo && v <= hi))
    throw std::invalid_argument(
        std::string(name) + " must be within [" + FormatNumber(lo) + ", " + FormatNumber(hi) + "]" +
        (unit && *unit ? std::string(" ") + unit : "") + "; got " + WithUnit(v, unit));
}

void CheckSameLength(std::size_t a, std::size_t b, const char* name_a, const char* name_b) {
  if (a != b)
    throw std::invalid_argument(std::string(name_a) + " and " + name_b +
                                " must have the same length; got " + std::to_string(a) + " and " +
                                std::to_string(b));
}

}  // namespace qogi
