#include "engine/optics/planck.h"

#include <cmath>
#include <string>

#include "engine/util/check.h"

namespace qogi {
namespace {
void CheckPlanckArgs(double nu_cm1, double temperature_K) {
  CheckNonNegative(nu_cm1, "nu_cm1", "cm-1");
  CheckPositive(temperature_K, "temperature_K", "K");
}
}  // namespace

double PlanckRadiance(double nu_cm1, double temperature_K) {
  CheckPlanckArgs(nu_cm1, temperature_K);
  return PlanckUnchecked(nu_cm1, temperature_K);
}

double PlanckRadianceDerivative(double nu_cm1, double temperature_K) {
  CheckPlanckArgs(nu_cm1, temperature_K);
  if (nu_cm1 == 0.0) return 0.0;
  const double x = constants::kC2 * nu_cm1 / temperature_K;
  if (x > 700.0) return 0.0;  // B and dB/dT underflow to zero
  const double b = PlanckUnchecked(nu_cm1, temperature_K);
  // dB/dT = B * x / (T * (1 - exp(-x)))
  return b * x / (temperature_K * -std::expm1(-x));
}

void PlanckRadiance(const double* nu_cm1, const double* temperature_K, double* out, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    CheckPlanckArgs(nu_cm1[i], temperature_K[i]);
    out[i] = PlanckUnchecked(nu_cm1[i], temperature_K[i]);
  }
}

}  // namespace qogi
