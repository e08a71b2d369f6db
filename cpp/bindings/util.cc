#include "common.h"

#include <stdexcept>

#include "engine/util/check.h"
#include "engine/util/lookup.h"

namespace qogi {

void CheckNdim(const py::array& a, int ndim, const char* name) {
  if (a.ndim() != ndim)
    throw std::invalid_argument(std::string(name) + " must be a " + std::to_string(ndim) +
                                "-D array; got " + std::to_string(a.ndim()) + "-D");
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
      // qogi's one cancellation type (qogi.errors.Cancelled): a progress
      // callback returned False. Ctrl-C itself arrives as KeyboardInterrupt
      // (PyErr_CheckSignals in the cancelled hook).
      if (!PyErr_Occurred()) {
        py::object type = py::module_::import("qogi.errors").attr("Cancelled");
        PyErr_SetString(type.ptr(), e.what());
      }
    }
  });
  m.def("resolve_threads", &ResolveThreads, py::arg("requested") = 0,
        "Number of worker threads used for `requested` (0 = all cores).");
  m.def(
      "lookup_lines",
      [](FloatArray stack, bool lines_are_rows, const DoubleArray& x, const DoubleArray& y,
         const IntArray& node_of_line, const DoubleArray& weight_of_line, int num_threads) {
        CheckNdim(stack, 3, "stack");
        CheckNdim(x, 2, "x");
        CheckNdim(y, 2, "y");
        if (x.shape(0) != y.shape(0) || x.shape(1) != y.shape(1))
          throw std::invalid_argument("x and y must have the same shape (tables, nodes)");
        const std::size_t t = stack.shape(0), h = stack.shape(1), w = stack.shape(2);
        const std::size_t lines = lines_are_rows ? h : w;
        if (static_cast<std::size_t>(node_of_line.size()) != lines ||
            static_cast<std::size_t>(weight_of_line.size()) != lines)
          throw std::invalid_argument("node_of_line and weight_of_line need one value per line (" +
                                      std::to_string(lines) + ")");
        float* data = stack.mutable_data();
        RunControl control = MakeRunControl();
        py::gil_scoped_release release;
        LookupLines(data, t, h, w, lines_are_rows, x.data(), y.data(), x.shape(0), x.shape(1),
                    node_of_line.data(), weight_of_line.data(), num_threads, &control);
      },
      py::arg("stack"), py::arg("lines_are_rows"), py::arg("x"), py::arg("y"),
      py::arg("node_of_line"), py::arg("weight_of_line"), py::arg("num_threads") = 0,
      "In place on a C-contiguous float32 (T, H, W) stack: each value v becomes sign(v) "
      "((1 - w) f_j(|v|) + w f_{j+1}(|v|)) with j, w those of its line (row or column) and "
      "f_j numpy.interp through (x[j], y[j]) (engine/util/lookup.h).");
}

}  // namespace qogi
