// Shared glue for the bindings: array checks, GIL-aware run control.
#pragma once

#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

#include "engine/util/check.h"
#include "engine/util/parallel.h"

namespace qogi {
namespace py = pybind11;

// A contiguous float64 array (input is converted when needed).
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
// A contiguous float32 array that must already be float32 and C-contiguous
// (big frame stacks cross without copies).
using FloatArray = py::array_t<float, py::array::c_style>;

// Throws std::invalid_argument unless `a` has `ndim` dimensions.
void CheckNdim(const py::array& a, int ndim, const char* name);

// A RunControl whose `cancelled` hook honours Ctrl-C (PyErr_CheckSignals) and,
// when given, a Python callable progress(fraction) -> bool|None that returns
// False to cancel. The hooks take the GIL themselves, so the computation may
// run with the GIL released.
RunControl MakeRunControl(py::object progress = py::none());

}  // namespace qogi
