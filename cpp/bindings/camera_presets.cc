// Bindings of the camera presets (engine/camera/camera.h).
#include "common.h"
#include "engine/camera/camera.h"

namespace qogi {

void BindCameraPresets(py::module_& m) {
  using C = CameraModel;
  BindOptions<C>(m, "CameraModel", "A camera model (use qogi.camera_preset).", Args::kKeywordOnly,
                 Field("name", &C::name, "preset or model name"),
                 Field("description", &C::description, "sources and approximations, for people"),
                 Field("width", &C::width, "pixels across"),
                 Field("height", &C::height, "pixels down"),
                 Field("ifov_rad", &C::ifov_rad, "angular size of one pixel [rad]"),
                 Field("frame_rate_hz", &C::frame_rate_hz, "frames per second [Hz]"),
                 Field("netd_K", &C::netd_K, "noise-equivalent temperature difference [K]"),
                 Field("channels", &C::channels,
                       "one SpectralResponse per channel (filter x lens x detector)"));
  m.def("camera_preset_names", &CameraPresetNames);
  m.def("camera_preset", &CameraPreset, py::arg("name"));
}

}  // namespace qogi
