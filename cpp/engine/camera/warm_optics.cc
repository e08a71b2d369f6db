#include "engine/camera/warm_optics.h"

#include <cmath>
#include <string>
#include <utility>

#include "engine/camera/camera.h"
#include "engine/util/check.h"

namespace qogi {
namespace {

std::vector<double> Product(const std::vector<double>& a, const std::vector<double>& b,
                            const std::vector<double>& c) {
  std::vector<double> out(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) out[i] = a[i] * b[i] * c[i];
  return out;
}

void CheckUnit(const std::vector<double>& v, const char* what, const std::string& who) {
  for (std::size_t i = 0; i < v.size(); ++i)
    Require(std::isfinite(v[i]) && v[i] >= 0 && v[i] <= 1,
            who + ": " + what + " must be within [0, 1]; " + what + "[" + std::to_string(i) +
                "] = " + FormatNumber(v[i]));
}

void CheckTemperature(double t, const char* name) {
  Require(std::isfinite(t) && t >= 0,
          std::string(name) + " must be finite and >= 0 K (0 = cold, no emission); got " +
              FormatNumber(t));
}

// The response r = d tau_f tau_l, validated first so that its errors name
// the components rather than the product.
SpectralResponse MakeResponse(const std::vector<double>& nu, const std::vector<double>& d,
                              const std::vector<double>& tau_f, const std::vector<double>& tau_l,
                              const std::string& name) {
  const std::string who = "ChannelOptics" + (name.empty() ? "" : " '" + name + "'");
  CheckSameLength(nu.size(), d.size(), "nu_cm1", "detector_response");
  CheckSameLength(nu.size(), tau_f.size(), "nu_cm1", "filter_transmittance");
  CheckSameLength(nu.size(), tau_l.size(), "nu_cm1", "lens_transmittance");
  for (std::size_t i = 0; i < d.size(); ++i)
    Require(std::isfinite(d[i]) && d[i] >= 0,
            who + ": detector_response must be finite and >= 0; detector_response[" +
                std::to_string(i) + "] = " + FormatNumber(d[i]));
  CheckUnit(tau_f, "filter_transmittance", who);
  CheckUnit(tau_l, "lens_transmittance", who);
  return SpectralResponse(nu, Product(d, tau_f, tau_l), name);
}

}  // namespace

ChannelOptics::Term ChannelOptics::MakeTerm(const std::vector<double>& nu, std::vector<double> w) {
  Term t;
  for (double& x : w)
    if (x < 0) x = 0;  // rounding of 1 - tau_f - rho_f at tau_f + rho_f = 1
  bool any = false;
  for (double x : w) any = any || x > 0;
  if (any) {
    t.zero = false;
    t.weight.emplace_back(nu, std::move(w));
  }
  return t;
}

double ChannelOptics::Term::Radiance(double t) const {
  if (zero || t == 0) return 0.0;
  return weight[0].BandRadiance(t);
}

double ChannelOptics::Term::Derivative(double t) const {
  if (zero || t == 0) return 0.0;
  return weight[0].BandRadianceDerivative(t);
}

ChannelOptics::ChannelOptics(std::vector<double> nu_cm1, std::vector<double> detector_response,
                             std::vector<double> filter_transmittance,
                             std::vector<double> lens_transmittance,
                             std::vector<double> filter_reflectance, std::string name)
    : name_(std::move(name)),
      nu_(std::move(nu_cm1)),
      d_(std::move(detector_response)),
      tau_f_(std::move(filter_transmittance)),
      rho_f_(std::move(filter_reflectance)),
      tau_l_(std::move(lens_transmittance)),
      response_(MakeResponse(nu_, d_, tau_f_, tau_l_, name_)) {
  const std::string who = "ChannelOptics" + (name_.empty() ? "" : " '" + name_ + "'");
  if (rho_f_.empty()) rho_f_.assign(nu_.size(), 0.0);
  CheckSameLength(nu_.size(), rho_f_.size(), "nu_cm1", "filter_reflectance");
  CheckUnit(rho_f_, "filter_reflectance", who);
  for (std::size_t i = 0; i < nu_.size(); ++i)
    Require(tau_f_[i] + rho_f_[i] <= 1.0 + 1e-12,
            who + ": filter transmittance + reflectance must be <= 1 (emissivity >= 0); at " +
                FormatNumber(nu_[i]) + " cm-1 they are " + FormatNumber(tau_f_[i]) + " + " +
                FormatNumber(rho_f_[i]));
  std::vector<double> w_lens(nu_.size()), w_filter(nu_.size()), w_refl(nu_.size());
  for (std::size_t i = 0; i < nu_.size(); ++i) {
    w_lens[i] = d_[i] * tau_f_[i] * (1.0 - tau_l_[i]);
    w_filter[i] = d_[i] * (1.0 - tau_f_[i] - rho_f_[i]);
    w_refl[i] = d_[i] * rho_f_[i];
  }
  lens_ = MakeTerm(nu_, std::move(w_lens));
  filter_ = MakeTerm(nu_, std::move(w_filter));
  reflected_ = MakeTerm(nu_, std::move(w_refl));
  detector_ = MakeTerm(nu_, d_);
}

double ChannelOptics::LensTerm(double t) const {
  CheckTemperature(t, "lens_temperature_K");
  return lens_.Radiance(t);
}

double ChannelOptics::FilterTerm(double t) const {
  CheckTemperature(t, "filter_temperature_K");
  return filter_.Radiance(t);
}

double ChannelOptics::ReflectedTerm(double t) const {
  CheckTemperature(t, "reflected_temperature_K");
  return reflected_.Radiance(t);
}

double ChannelOptics::DetectorBandRadiance(double t) const {
  CheckTemperature(t, "temperature_K");
  return detector_.Radiance(t);
}

double ChannelOptics::WarmRadiance(double lens_temperature_K, double filter_temperature_K,
                                   double reflected_temperature_K) const {
  return LensTerm(lens_temperature_K) + FilterTerm(filter_temperature_K) +
         ReflectedTerm(reflected_temperature_K);
}

double ChannelOptics::WarmRadianceDerivativeLens(double t) const {
  CheckTemperature(t, "lens_temperature_K");
  return lens_.Derivative(t);
}

double ChannelOptics::WarmRadianceDerivativeFilter(double t) const {
  CheckTemperature(t, "filter_temperature_K");
  return filter_.Derivative(t);
}

namespace {

// The presets' grids and curves (presets.cc): the same grid function, the
// same numbers, so the products agree sample for sample (camera tests check
// it).
ChannelOptics Optics(const std::string& name, const std::vector<double>& nu,
                     std::vector<double> filter) {
  return ChannelOptics(nu, InSbDetectorResponse(nu), std::move(filter), MwirLensTransmittance(nu),
                       {}, name);
}

}  // namespace

std::vector<ChannelOptics> CameraPresetOptics(const std::string& name) {
  const CameraModel preset = CameraPreset(name);  // throws for unknown names
  std::vector<ChannelOptics> out;
  if (name == "gf320") {
    // The preset samples 2800-3300 cm-1 every 0.5 cm-1; the same step over
    // the whole InSb range contains those samples exactly.
    const std::vector<double> nu = PresetWavenumbers(1800.0, 6700.0, 0.5);
    out.push_back(
        Optics(preset.channels[0].name(), nu, BandpassTransmittance(nu, 3.20, 3.40, 0.85, 0.02)));
  } else if (name == "fast-m150") {
    const std::vector<double> nu = PresetWavenumbers(1800.0, 6700.0, 1.0);
    out.push_back(Optics(preset.channels[0].name(), nu, std::vector<double>(nu.size(), 1.0)));
    out.push_back(
        Optics(preset.channels[1].name(), nu, BandpassTransmittance(nu, 4.17, 4.45, 0.80, 0.03)));
    out.push_back(
        Optics(preset.channels[2].name(), nu, BandpassTransmittance(nu, 3.15, 3.45, 0.80, 0.03)));
    out.push_back(
        Optics(preset.channels[3].name(), nu, BandpassTransmittance(nu, 2.70, 3.45, 0.80, 0.03)));
  } else {
    throw std::invalid_argument("camera preset '" + name +
                                "' has no optics breakdown (filter, lens, detector)");
  }
  return out;
}

}  // namespace qogi
