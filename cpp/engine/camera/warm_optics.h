// Emission of warm (uncooled) optics seen by a cooled detector (thesis
// section 4.3.3 and Fig. 39).
//
// A channel is a lens of transmittance tau_l(nu) in front of a filter of
// transmittance tau_f(nu) and reflectance rho_f(nu), seen by a detector of
// relative response d(nu). The lens is taken as non-reflecting (AR coated),
// so its emissivity is 1 - tau_l (Kirchhoff); the filter's emissivity is
// eps_f = 1 - tau_f - rho_f. The filter reflects towards the detector what
// lies on the detector side (the cold shield: no emission, or an enclosure
// at T_refl). The band radiance the detector measures is
//
//   L_meas = integral d [ tau_f tau_l L_scene(nu)
//                       + tau_f (1 - tau_l) B(nu, T_lens)
//                       + (1 - tau_f - rho_f) B(nu, T_filter)
//                       + rho_f B(nu, T_refl) ] dnu
//          = L_channel + W(T_lens, T_filter, T_refl),
//
// where L_channel = integral r L_scene dnu is the band radiance through the
// channel response r = d tau_f tau_l (what the forward models compute), and
// W, the warm-optics radiance, does not depend on the scene. So the forward
// direction adds W and the correction subtracts it, exactly.
//
// Temperatures are in K; a temperature of 0 means "cold": no emission (the
// Planck function vanishes at 0 K), e.g. a filter inside the cooled dewar.
// Closed isothermal system: with scene, lens, filter and reflected enclosure
// all at T, L_meas = integral d B(nu, T) dnu.
#pragma once

#include <string>
#include <vector>

#include "engine/optics/spectral_response.h"

namespace qogi {

class ChannelOptics {
 public:
  // Components sampled on one wavenumber grid nu_cm1 [cm-1] (strictly
  // increasing, >= 0, at least 2 samples), linear between samples and zero
  // outside: detector relative response (>= 0), filter transmittance and lens
  // transmittance (in [0, 1]), and optionally the filter reflectance (in
  // [0, 1], empty = 0) with tau_f + rho_f <= 1 everywhere.
  ChannelOptics(std::vector<double> nu_cm1, std::vector<double> detector_response,
                std::vector<double> filter_transmittance, std::vector<double> lens_transmittance,
                std::vector<double> filter_reflectance = {}, std::string name = "");

  const std::string& name() const { return name_; }
  const std::vector<double>& nu_cm1() const { return nu_; }
  const std::vector<double>& detector_response() const { return d_; }
  const std::vector<double>& filter_transmittance() const { return tau_f_; }
  const std::vector<double>& filter_reflectance() const { return rho_f_; }
  const std::vector<double>& lens_transmittance() const { return tau_l_; }

  // The channel response r = d tau_f tau_l, sampled on nu_cm1.
  const SpectralResponse& response() const { return response_; }

  // The warm-optics radiance W [W/(m2 sr)]; temperatures in K, >= 0
  // (0 = cold, no emission).
  double WarmRadiance(double lens_temperature_K, double filter_temperature_K,
                      double reflected_temperature_K = 0.0) const;
  // Its partial derivatives [W/(m2 sr K)].
  double WarmRadianceDerivativeLens(double lens_temperature_K) const;
  double WarmRadianceDerivativeFilter(double filter_temperature_K) const;

  // Parts of W: integral d tau_f (1 - tau_l) B(T) dnu (lens),
  // integral d (1 - tau_f - rho_f) B(T) dnu (filter), integral d rho_f B(T)
  // dnu (reflected) and integral d B(T) dnu (the whole detector band).
  double LensTerm(double temperature_K) const;
  double FilterTerm(double temperature_K) const;
  double ReflectedTerm(double temperature_K) const;
  double DetectorBandRadiance(double temperature_K) const;

  // Forward: channel band radiance -> measured; correction: the inverse.
  double Measured(double channel_radiance, double lens_temperature_K, double filter_temperature_K,
                  double reflected_temperature_K = 0.0) const {
    return channel_radiance +
           WarmRadiance(lens_temperature_K, filter_temperature_K, reflected_temperature_K);
  }
  double Corrected(double measured_radiance, double lens_temperature_K, double filter_temperature_K,
                   double reflected_temperature_K = 0.0) const {
    return measured_radiance -
           WarmRadiance(lens_temperature_K, filter_temperature_K, reflected_temperature_K);
  }

 private:
  // integral weight B(T) dnu for one term; 0 if the weight is zero everywhere.
  struct Term {
    bool zero = true;
    std::vector<SpectralResponse> weight;  // empty or one element
    double Radiance(double t) const;
    double Derivative(double t) const;
  };
  static Term MakeTerm(const std::vector<double>& nu, std::vector<double> w);

  std::string name_;
  std::vector<double> nu_, d_, tau_f_, rho_f_, tau_l_;
  SpectralResponse response_;
  Term lens_, filter_, reflected_, detector_;
};

// Components of a shipped camera preset's channels (same order as
// CameraPreset(name).channels), built from the same helper curves as the
// preset so that response() reproduces each preset channel's response. For
// gf320 the filter is the cold filter inside the dewar: pass its cryogenic
// temperature (or 0) as the filter temperature. The grid spans the InSb
// detector's range so that filter emission is counted over the whole band.
std::vector<ChannelOptics> CameraPresetOptics(const std::string& name);

}  // namespace qogi
