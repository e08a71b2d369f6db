// The shipped camera presets. Where a number is the manufacturer's or the
// thesis's, it says so; the filter curves are not public and are
// approximated by smooth band-passes placed as described.
#include <map>
#include <string>

#include "engine/camera/camera.h"
#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {
std::vector<double> PresetWavenumbers(double lo_cm1, double hi_cm1, double step_cm1) {
  std::vector<double> nu;
  for (double x = lo_cm1; x <= hi_cm1 + 1e-9; x += step_cm1) nu.push_back(x);
  return nu;
}

namespace {

SpectralResponse Channel(const std::string& name, const std::vector<double>& nu,
                         const std::vector<double>& filter, bool lens, bool detector) {
  std::vector<double> r = filter;
  const std::vector<double> l = MwirLensTransmittance(nu), d = InSbDetectorResponse(nu);
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (lens) r[i] *= l[i];
    if (detector) r[i] *= d[i];
  }
  return SpectralResponse(nu, r, name);
}

CameraModel Gf320() {
  CameraModel c;
  c.name = "gf320";
  c.description =
      "FLIR GF320 optical gas imaging camera: cooled InSb focal plane behind a cold "
      "3.2-3.4 um band-pass filter (FLIR datasheet: spectral range 3.2-3.4 um, 320x240 "
      "pixels, NETD < 15 mK, 24 x 18 deg standard lens); 15 Hz as recorded in the "
      "thesis's lab releases. Approximated: the filter as a flat-topped band-pass with "
      "50 % points at 3.20 and 3.40 um, 0.02 um edges, 0.85 peak transmittance; the lens "
      "as an AR-coated MWIR lens (~0.92); the detector as flat over its band. "
      "IFOV = 24 deg / 320 px = 1.309 mrad.";
  c.width = 320;
  c.height = 240;
  c.ifov_rad = 24.0 * constants::kPi / 180.0 / 320.0;
  c.frame_rate_hz = 15.0;
  c.netd_K = 0.015;
  const std::vector<double> nu = PresetWavenumbers(2800.0, 3300.0, 0.5);
  c.channels.push_back(Channel("gf320 3.2-3.4 um", nu,
                               BandpassTransmittance(nu, 3.20, 3.40, 0.85, 0.02), true, true));
  return c;
}

CameraModel FastM150() {
  CameraModel c;
  c.name = "fast-m150";
  c.description =
      "Four-position filter-wheel MWIR camera as used in the thesis's multispectral work "
      "(section 4.1.1): cooled InSb 320x256, 100 Hz, NETD 17 mK. Channels: 1 open (lens "
      "only over the InSb range 1.5-5.4 um, 1852-6667 cm-1); 2 CO2 band-pass placed over "
      "the CO2 nu3 lines, 4.17-4.45 um (2247-2398 cm-1), shifted as in the thesis's "
      "simulation (section 4.3.1); 3 CH4 band-pass 3.15-3.45 um over the CH4 nu3 band; "
      "4 CH4 + H2O band-pass 2.70-3.45 um, adding the wing of the H2O 2.7 um band. "
      "Approximated: the filter curves are not public; each is a flat-topped band-pass "
      "(0.80 peak, 0.03 um edges) times an AR-coated MWIR lens; the detector is flat over "
      "1.5-5.4 um. IFOV assumed 0.6 mrad (30 um pitch behind a 50 mm lens; 2 mm pixels at 3.3 m, "
      "like the thesis's synthetic scenes). Note: the HITRAN CO2 "
      "list shipped for tests covers 2100-2300 cm-1 only, so with it the CO2 channel sees "
      "only the low-wavenumber edge of the nu3 band.";
  c.width = 320;
  c.height = 256;
  c.ifov_rad = 0.6e-3;
  c.frame_rate_hz = 100.0;
  c.netd_K = 0.017;
  const std::vector<double> nu = PresetWavenumbers(1800.0, 6700.0, 1.0);
  const std::vector<double> open(nu.size(), 1.0);
  c.channels.push_back(Channel("open", nu, open, true, true));
  c.channels.push_back(Channel("CO2 4.17-4.45 um", nu,
                               BandpassTransmittance(nu, 4.17, 4.45, 0.80, 0.03), true, true));
  c.channels.push_back(Channel("CH4 3.15-3.45 um", nu,
                               BandpassTransmittance(nu, 3.15, 3.45, 0.80, 0.03), true, true));
  c.channels.push_back(Channel("CH4+H2O 2.70-3.45 um", nu,
                               BandpassTransmittance(nu, 2.70, 3.45, 0.80, 0.03), true, true));
  return c;
}

const std::map<std::string, CameraModel (*)()>& Registry() {
  static const std::map<std::string, CameraModel (*)()> r = {{"gf320", &Gf320},
                                                             {"fast-m150", &FastM150}};
  return r;
}

}  // namespace

std::vector<std::string> CameraPresetNames() {
  std::vector<std::string> out;
  for (const auto& kv : Registry()) out.push_back(kv.first);
  return out;
}

CameraModel CameraPreset(const std::string& name) {
  const auto it = Registry().find(name);
  if (it == Registry().end()) {
    std::string known;
    for (const auto& n : CameraPresetNames()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown camera preset '" + name + "'; known presets: " + known);
  }
  CameraModel c = it->second();
  c.Check();
  return c;
}

}  // namespace qogi
