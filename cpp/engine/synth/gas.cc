#include "engine/synth/gas.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "engine/util/check.h"

namespace qogi::synth {
namespace {

// Shomate-form coefficients of the quadratic cp(t) through three tabulated
// points at t = 0.3, 0.4, 0.5 (T = 300, 400, 500 K).
Species QuadraticThrough(const char* name, double molar_mass, double cp300, double cp400,
                         double cp500) {
  const double c = (cp500 - 2 * cp400 + cp300) / (2 * 0.01);
  const double b = (cp500 - cp300) / 0.2 - 2 * c * 0.4;
  const double a = cp400 - b * 0.4 - c * 0.16;
  return {name, molar_mass, a, b, c, 0.0, 0.0};
}

const std::vector<Species>& Table() {
  static const std::vector<Species> table = {
      // NIST WebBook Shomate coefficients (gas phase).
      {"CH4", 16.0425e-3, -0.703029, 108.4773, -42.52157, 5.862788, 0.678565},
      {"CO2", 44.0095e-3, 24.99735, 55.18696, -33.69137, 7.948387, -0.136638},
      {"N2", 28.0134e-3, 28.98641, 1.853978, -9.647459, 16.63537, 0.000117},
      {"O2", 31.9988e-3, 31.32234, -20.23531, 57.86644, -36.50624, -0.007374},
      {"Ar", 39.948e-3, 20.786, 0.0, 0.0, 0.0, 0.0},
      // NIST WebBook tabulated cp [J/(mol K)] at 300, 400, 500 K.
      QuadraticThrough("C2H6", 30.0690e-3, 52.71, 65.46, 77.94),
      QuadraticThrough("C3H8", 44.0956e-3, 73.93, 94.01, 112.59),
  };
  return table;
}

double ShomateEnthalpy(const Species& s, double t) {
  // Integral of cp over T = 1000 t, in J/mol.
  return 1000.0 *
         (s.a * t + s.b * t * t / 2 + s.c * t * t * t / 3 + s.d * t * t * t * t / 4 - s.e / t);
}

}  // namespace

double Species::HeatCapacity(double temperature_K) const {
  const double t = temperature_K / 1000.0;
  return a + b * t + c * t * t + d * t * t * t + e / (t * t);
}

double Species::Enthalpy(double temperature_K) const {
  return ShomateEnthalpy(*this, temperature_K / 1000.0) - ShomateEnthalpy(*this, 298.15 / 1000.0);
}

const Species& FindSpecies(const std::string& name) {
  for (const Species& s : Table())
    if (s.name == name) return s;
  std::string known;
  for (const Species& s : Table()) known += (known.empty() ? "" : ", ") + s.name;
  throw std::invalid_argument("unknown gas species \"" + name + "\"; known species: " + known);
}

std::vector<std::string> KnownSpecies() {
  std::vector<std::string> out;
  for (const Species& s : Table()) out.push_back(s.name);
  return out;
}

GasMixture::GasMixture(const std::map<std::string, double>& mole_fractions) {
  Require(!mole_fractions.empty(),
          "composition must name at least one species, e.g. {\"CH4\": 1.0}");
  double sum = 0;
  for (const auto& [name, x] : mole_fractions) {
    const Species& s = FindSpecies(name);
    if (!(std::isfinite(x) && x >= 0))
      throw std::invalid_argument("composition[\"" + name +
                                  "\"] (volume fraction) must be finite and >= 0; got " +
                                  FormatNumber(x));
    if (x == 0) continue;
    names_.push_back(name);
    species_.push_back(&s);
    x_.push_back(x);
    sum += x;
  }
  if (!(std::abs(sum - 1.0) <= 1e-3))
    throw std::invalid_argument("composition volume fractions must sum to 1 (within 1e-3); got " +
                                FormatNumber(sum));
  for (double& x : x_) x /= sum;
  for (std::size_t i = 0; i < x_.size(); ++i) molar_mass_ += x_[i] * species_[i]->molar_mass_kg_mol;
  for (std::size_t i = 0; i < x_.size(); ++i)
    w_.push_back(x_[i] * species_[i]->molar_mass_kg_mol / molar_mass_);
}

GasMixture GasMixture::DryAir() {
  return GasMixture({{"N2", 0.78084}, {"O2", 0.20946}, {"Ar", 0.00934}, {"CO2", 0.00036}});
}

double GasMixture::SpecificHeatCapacity(double temperature_K) const {
  double cp = 0;
  for (std::size_t i = 0; i < x_.size(); ++i)
    cp += x_[i] * species_[i]->HeatCapacity(temperature_K);
  return cp / molar_mass_;
}

double GasMixture::SpecificEnthalpy(double temperature_K) const {
  double h = 0;
  for (std::size_t i = 0; i < x_.size(); ++i) h += x_[i] * species_[i]->Enthalpy(temperature_K);
  return h / molar_mass_;
}

double GasMixture::Density(double temperature_K, double pressure_Pa) const {
  return pressure_Pa * molar_mass_ / (kGasConstant * temperature_K);
}

MixingModel::MixingModel(GasMixture released, double exit_temperature_K, GasMixture ambient,
                         double ambient_temperature_K, double pressure_Pa)
    : released_(std::move(released)),
      ambient_(std::move(ambient)),
      t_exit_(exit_temperature_K),
      t_amb_(ambient_temperature_K),
      p_(pressure_Pa) {
  CheckInRange(t_exit_, 200.0, 600.0, "exit_temperature_K", "K");
  CheckInRange(t_amb_, 200.0, 600.0, "ambient_temperature_K", "K");
  CheckInRange(p_, 1e4, 2e5, "pressure_Pa", "Pa");
  h_r_exit_ = released_.SpecificEnthalpy(t_exit_);
  h_a_amb_ = ambient_.SpecificEnthalpy(t_amb_);
  rho_exit_ = released_.Density(t_exit_, p_);
  rho_amb_ = ambient_.Density(t_amb_, p_);

  // Table of T against q = rho_r / rho_exit, uniform in q. q(Y) is checked to
  // be increasing (true for every physical pair of gases here); each node is
  // inverted by bisection refined with the secant rule.
  constexpr int kNodes = 4097;
  const int kCheck = 2048;
  double prev = -1;
  for (int i = 0; i <= kCheck; ++i) {
    const double q = PartialDensityAtMassFraction(static_cast<double>(i) / kCheck);
    if (!(q > prev))
      throw std::invalid_argument(
          "the released gas's partial density does not increase with its mass "
          "fraction for these temperatures; choose exit and ambient temperatures "
          "closer together");
    prev = q;
  }
  table_t_.resize(kNodes);
  for (int k = 0; k < kNodes; ++k) {
    const double target = rho_exit_ * k / (kNodes - 1);
    double lo = 0, hi = 1;
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      if (PartialDensityAtMassFraction(mid) < target)
        lo = mid;
      else
        hi = mid;
      if (hi - lo < 1e-15) break;
    }
    table_t_[k] = TemperatureAtMassFraction(0.5 * (lo + hi));
  }
}

double MixingModel::TemperatureAtMassFraction(double y) const {
  y = std::clamp(y, 0.0, 1.0);
  const double target = y * h_r_exit_ + (1 - y) * h_a_amb_;
  // Start from the constant-cp estimate, then Newton on the exact enthalpy.
  const double cpr = released_.SpecificHeatCapacity(0.5 * (t_exit_ + t_amb_));
  const double cpa = ambient_.SpecificHeatCapacity(0.5 * (t_exit_ + t_amb_));
  double t = (y * cpr * t_exit_ + (1 - y) * cpa * t_amb_) / (y * cpr + (1 - y) * cpa);
  for (int it = 0; it < 30; ++it) {
    const double h = y * released_.SpecificEnthalpy(t) + (1 - y) * ambient_.SpecificEnthalpy(t);
    const double cp =
        y * released_.SpecificHeatCapacity(t) + (1 - y) * ambient_.SpecificHeatCapacity(t);
    const double dt = (target - h) / cp;
    t += dt;
    if (std::abs(dt) < 1e-10) break;
  }
  return t;
}

double MixingModel::DensityAtMassFraction(double y) const {
  y = std::clamp(y, 0.0, 1.0);
  const double t = TemperatureAtMassFraction(y);
  const double inv_m = y / released_.molar_mass_kg_mol() + (1 - y) / ambient_.molar_mass_kg_mol();
  return p_ / (kGasConstant * t * inv_m);
}

double MixingModel::PartialDensityAtMassFraction(double y) const {
  return std::clamp(y, 0.0, 1.0) * DensityAtMassFraction(y);
}

bool MixingModel::StateFromPartialDensity(double rho_r, double* temperature_K,
                                          double* mole_fraction) const {
  if (!(rho_r > 0)) {
    *temperature_K = t_amb_;
    *mole_fraction = 0;
    return true;
  }
  const double pos = rho_r / rho_exit_ * (table_t_.size() - 1);
  bool ok = true;
  double t;
  if (pos >= table_t_.size() - 1) {
    ok = pos <= (table_t_.size() - 1) * (1 + 1e-9);
    t = table_t_.back();
  } else {
    const std::size_t k = static_cast<std::size_t>(pos);
    const double f = pos - k;
    t = table_t_[k] + f * (table_t_[k + 1] - table_t_[k]);
  }
  *temperature_K = t;
  *mole_fraction = rho_r * kGasConstant * t / (p_ * released_.molar_mass_kg_mol());
  return ok;
}

}  // namespace qogi::synth
