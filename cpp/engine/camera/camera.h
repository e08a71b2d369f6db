// Camera models: geometry, timing, noise and the spectral response of each
// channel, and the presets the project ships (see presets.cc for where every
// number comes from and what is approximated).
#pragma once

#include <string>
#include <vector>

#include "engine/optics/spectral_response.h"

namespace qogi {

struct CameraModel {
  std::string name;            // preset or model name
  std::string description;     // sources and approximations, for people
  int width = 320;             // pixels across
  int height = 240;            // pixels down
  double ifov_rad = 1.309e-3;  // angular size of one pixel [rad]
  double frame_rate_hz = 15;   // frames per second [Hz]
  double netd_K = 0.015;       // noise-equivalent temperature difference [K]
  std::vector<SpectralResponse> channels;  // one response per channel (filter x lens x detector)
  void Check() const;
};

// Names of the shipped presets.
std::vector<std::string> CameraPresetNames();
// A shipped preset by name; throws std::invalid_argument listing the names.
CameraModel CameraPreset(const std::string& name);

// The wavenumbers lo_cm1, lo_cm1 + step_cm1, ... up to hi_cm1 (within
// 1e-9 cm-1) on which the presets sample their curves [cm-1].
std::vector<double> PresetWavenumbers(double lo_cm1, double hi_cm1, double step_cm1);

// Building blocks for channel responses, sampled every `step_cm1` over
// [nu_min, nu_max]:
// a flat-topped band-pass between wavelengths lo_um and hi_um (50 % points),
// peak transmittance `peak`, logistic edges of 10-90 % width `edge_um`.
std::vector<double> BandpassTransmittance(const std::vector<double>& nu_cm1, double lo_um,
                                          double hi_um, double peak, double edge_um);
// Transmittance of an anti-reflection-coated MWIR lens (Si/Ge, 3-5 um design
// band), ~0.92 in band falling to ~0.75 at 1.5 and 5.4 um (an approximation).
std::vector<double> MwirLensTransmittance(const std::vector<double>& nu_cm1);
// Relative response of a cooled InSb detector, flat between its 1.5 and
// 5.4 um cut-on/cut-off (1852-6667 cm-1), with 0.05 um logistic edges.
std::vector<double> InSbDetectorResponse(const std::vector<double>& nu_cm1);

}  // namespace qogi
