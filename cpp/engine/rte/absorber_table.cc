#include "engine/rte/absorber_table.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "engine/util/check.h"
#include "engine/util/interpolation.h"

namespace qogi {

double MolarMass(const std::string& species) {
  // IUPAC standard atomic weights (C 12.011, H 1.008, O 15.999, N 14.007).
  static const std::map<std::string, double> kMass = {
      {"CH4", 16.0425e-3}, {"CO2", 44.0095e-3}, {"H2O", 18.0153e-3},  {"N2O", 44.0128e-3},
      {"CO", 28.0101e-3},  {"NH3", 17.0305e-3}, {"C2H6", 30.0690e-3}, {"C3H8", 44.0956e-3}};
  const auto it = kMass.find(species);
  if (it == kMass.end()) {
    std::string known;
    for (const auto& kv : kMass) known += (known.empty() ? "" : ", ") + kv.first;
    throw std::invalid_argument("unknown species '" + species + "'; known: " + known);
  }
  return it->second;
}

double AbsorberTable::molar_mass() const {
  return molar_mass_kg_mol > 0 ? molar_mass_kg_mol : MolarMass(species);
}

void AbsorberTable::Check() const {
  const std::string who = "AbsorberTable '" + species + "'";
  Require(!species.empty(), "AbsorberTable: species name is empty");
  CheckPositive(pressure_Pa, (who + " pressure_Pa").c_str(), "Pa");
  CheckPositive(dnu_cm1, (who + " dnu_cm1").c_str(), "cm-1");
  CheckNonNegative(nu0_cm1, (who + " nu0_cm1").c_str(), "cm-1");
  Require(n_nu >= 2, who + ": needs at least 2 wavenumbers; got " + std::to_string(n_nu));
  Require(temperatures_K.size() >= 2,
          who + ": needs at least 2 temperatures; got " + std::to_string(temperatures_K.size()));
  for (std::size_t i = 0; i < temperatures_K.size(); ++i) {
    CheckPositive(temperatures_K[i], (who + " temperatures_K").c_str(), "K");
    if (i > 0)
      Require(temperatures_K[i] > temperatures_K[i - 1],
              who + ": temperatures_K must be strictly increasing");
  }
  const std::size_t n = temperatures_K.size() * n_nu;
  Require(sigma_air.size() == n, who + ": sigma_air has " + std::to_string(sigma_air.size()) +
                                     " values; expected n_T * n_nu = " + std::to_string(n));
  Require(sigma_self.empty() || sigma_self.size() == n,
          who + ": sigma_self has " + std::to_string(sigma_self.size()) +
              " values; expected 0 or n_T * n_nu = " + std::to_string(n));
  for (const auto* v : {&sigma_air, &sigma_self})
    for (float s : *v)
      if (!(std::isfinite(s) && s >= 0))
        throw std::invalid_argument(who + ": cross-sections must be finite and >= 0; found " +
                                    FormatNumber(s));
  molar_mass();
}

std::vector<double> LogValues(const std::vector<float>& sigma) {
  std::vector<double> out(sigma.size());
  for (std::size_t i = 0; i < sigma.size(); ++i)
    out[i] = sigma[i] > 0 ? std::log(static_cast<double>(sigma[i])) : -1e300;
  return out;
}

TemperatureStencil MakeTemperatureStencil(const std::vector<double>& grid, double t) {
  TemperatureStencil st;
  const std::size_t n = grid.size();
  t = std::min(std::max(t, grid.front()), grid.back());
  std::size_t i =
      static_cast<std::size_t>(std::upper_bound(grid.begin(), grid.end(), t) - grid.begin());
  i = (i == 0) ? 0 : i - 1;
  if (i + 1 >= n) i = n - 2;
  st.lower = i;
  const double h = grid[i + 1] - grid[i];
  st.frac = (t - grid[i]) / h;
  st.dfrac = 1.0 / h;
  st.count = static_cast<int>(std::min<std::size_t>(4, n));
  st.first = n >= 4 ? std::min(i == 0 ? 0 : i - 1, n - 4) : 0;
  LagrangeWeights(grid.data() + st.first, st.count, t, st.weight, st.dweight);
  return st;
}

}  // namespace qogi
