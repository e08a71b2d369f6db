#include "common.h"

#include <stdexcept>

#include "engine/util/check.h"

namespace qogi {

void CheckNdim(const py::array& a, int ndim, const char* name) {
  if (a.ndim() != ndim)
    throw std::invalid_argument(std::string(name) + " must be a " +
                                std::to_string(ndim) + "-D array; got " +
                                std::to_string(a.ndim()) + "-D");
}

RunControl MakeRunControl(py::object progress) {
  RunControl control;
  control.cancelled = [] {
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    return false;
  };
  if (!progress.is_none()) {
    auto holder = std::make_shared<py::object>(progress);
    control.progress = [holder](double fraction) {
      py::gil_scoped_acquire gil;
      py::object r = (*holder)(fraction);
      if (!r.is_none() && !r.cast<bool>()) throw Cancelled();
    };
  }
  return control;
}

void BindUtil(py::module_& m) {
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Cancelled& e) {
      if (!PyErr_Occurred()) PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
    }
  });
  m.def("resolve_threads", &ResolveThreads, py::arg("requested") = 0,
        "Number of worker threads used for `requested` (0 = all cores).");
}

}  // namespace qogi
