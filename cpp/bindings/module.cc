// qogi._engine: the C++ engine seen from Python. Each engine module has one
// Bind<Module>() in a file named after it.
#include "common.h"

namespace qogi {
void BindUtil(py::module_& m);
void BindOptics(py::module_& m);
void BindIo(py::module_& m);
void BindRte(py::module_& m);
void BindCameraPresets(py::module_& m);
void BindSpectra(py::module_& m);
void BindCamera(py::module_& m);
void BindVelocimetry(py::module_& m);
void BindRegistration(py::module_& m);
void BindBackground(py::module_& m);
void BindSynth(py::module_& m);
void BindInversion(py::module_& m);
void BindFlux(py::module_& m);
}  // namespace qogi

PYBIND11_MODULE(_engine, m) {
  m.doc() = "qogi C++ engine (use the public API in the `qogi` package)";
  qogi::BindUtil(m);
  qogi::BindOptics(m);
  qogi::BindIo(m);
  qogi::BindRte(m);
  qogi::BindCameraPresets(m);
  qogi::BindSpectra(m);
  qogi::BindCamera(m);
  qogi::BindVelocimetry(m);
  qogi::BindRegistration(m);
  qogi::BindBackground(m);
  qogi::BindSynth(m);
  qogi::BindInversion(m);
  qogi::BindFlux(m);
}
