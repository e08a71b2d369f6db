// Argument checks shared by every engine module.
//
// A failed check throws std::invalid_argument whose message names the
// argument, the offending value and the accepted range, e.g.
//   "temperature_K must be finite and > 0 K; got -5"
// Python receives it as ValueError. The engine never aborts or prints.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

namespace qogi {

// Thrown when a caller's cancellation hook asks a long computation to stop.
// Python receives KeyboardInterrupt.
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("computation cancelled") {}
};

// Formats a double compactly and exactly enough for messages ("%.9g").
std::string FormatNumber(double v);

// Throws std::invalid_argument(what) unless `ok`.
inline void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

// `name` must be finite.
void CheckFinite(double v, const char* name);
// `name` must be finite and strictly positive.
void CheckPositive(double v, const char* name, const char* unit = "");
// `name` must be finite and >= 0.
void CheckNonNegative(double v, const char* name, const char* unit = "");
// `name` must be finite and within [lo, hi].
void CheckInRange(double v, double lo, double hi, const char* name, const char* unit = "");
// Two arrays must have equal lengths.
void CheckSameLength(std::size_t a, std::size_t b, const char* name_a, const char* name_b);

}  // namespace qogi
