// Bindings of the camera presets (engine/camera/camera.h).
#include "common.h"
#include "engine/camera/camera.h"

namespace qogi {

void BindCameraPresets(py::module_& m) {
  py::class_<CameraModel>(m, "CameraModel", "A camera model (use qogi.camera_preset).")
      .def_readonly("name", &CameraModel::name)
      .def_readonly("description", &CameraModel::description)
      .def_readonly("width", &CameraModel::width)
      .def_readonly("height", &CameraModel::height)
      .def_readonly("ifov_rad", &CameraModel::ifov_rad)
      .def_readonly("frame_rate_hz", &CameraModel::frame_rate_hz)
      .def_readonly("netd_K", &CameraModel::netd_K)
      .def_readonly("channels", &CameraModel::channels);
  m.def("camera_preset_names", &CameraPresetNames);
  m.def("camera_preset", &CameraPreset, py::arg("name"));
}

}  // namespace qogi
