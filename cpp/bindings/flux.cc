// Bindings of engine/flux: the flux integral across a surface and the
// transport flux level (glue only; python/qogi/flux.py and
// python/qogi/velocimetry.py hold the public API).
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "common.h"
#include "engine/flux/flux_level.h"
#include "engine/flux/surface_flux.h"
#include "engine/flux/transport_flux.h"

namespace qogi {

void BindFlux(py::module_& m) {
  m.def(
      "surface_flux_rate",
      [](const DoubleArray& column, const DoubleArray& column_sigma,
         const DoubleArray& normal_velocity, const DoubleArray& length_m,
         double molar_mass_kg_mol) {
        CheckNdim(column, 2, "column");
        const py::ssize_t T = column.shape(0), S = column.shape(1);
        for (const auto* a : {&column_sigma, &normal_velocity}) {
          CheckNdim(*a, 2, "column_sigma and normal_velocity");
          Require(a->shape(0) == T && a->shape(1) == S,
                  "column_sigma and normal_velocity must have the column's (frames, samples) "
                  "shape");
        }
        Require(length_m.ndim() == 1 && length_m.shape(0) == S,
                "length_m must hold one length per sample (" + std::to_string(S) + ")");
        SurfaceFluxOptions options;
        options.molar_mass_kg_mol = molar_mass_kg_mol;
        SurfaceRate r;
        {
          py::gil_scoped_release release;
          r = SurfaceFluxRate(column.data(), column_sigma.data(), normal_velocity.data(),
                              length_m.data(), std::size_t(T), std::size_t(S), options);
        }
        return py::make_tuple(ToArray(r.rate),
                              ToArray<std::int64_t>(r.samples, {py::ssize_t(r.samples.size())}),
                              ToArray(r.rate_variance));
      },
      py::arg("column"), py::arg("column_sigma"), py::arg("normal_velocity"), py::arg("length_m"),
      py::arg("molar_mass_kg_mol") = 0.0,
      "(rate [kg/s], samples, rate_variance [(kg/s)^2]) per frame (engine/flux/surface_flux.h).");

  m.def(
      "transport_flux",
      [](const FloatArray& frames, const std::string& axis, py::object source_index,
         py::object intervals, int window, int num_threads, py::object mask) {
        CheckNdim(frames, 3, "frames");
        TransportFluxOptions options;
        if (!mask.is_none()) {
          const auto m =
              mask.cast<py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>>();
          Require(m.ndim() == 2 && m.shape(0) == frames.shape(1) && m.shape(1) == frames.shape(2),
                  "mask must be (H, W) = (" + std::to_string(frames.shape(1)) + ", " +
                      std::to_string(frames.shape(2)) + "), the frames' size");
          options.mask.assign(m.data(), m.data() + m.size());
        }
        options.window = window;
        options.axis = ParseFluxAxis(axis);
        if (!source_index.is_none()) options.source_index = source_index.cast<double>();
        if (!intervals.is_none()) {
          const DoubleArray r = intervals.cast<DoubleArray>();
          options.intervals.assign(r.data(), r.data() + r.size());
        }
        options.num_threads = num_threads;
        RunControl control = MakeRunControl();
        TransportFluxResult tf;
        {
          py::gil_scoped_release release;
          tf = TransportFlux(frames.data(), frames.shape(0), frames.shape(1), frames.shape(2),
                             options, &control);
        }
        return py::make_tuple(ToArray(tf.flux), ToArray(tf.line_column), ToArray(tf.velocity),
                              ToArray(tf.displacement), ToArray(tf.unexplained));
      },
      py::arg("frames"), py::arg("axis") = "up", py::arg("source_index") = py::none(),
      py::arg("intervals") = py::none(), py::arg("window") = 0, py::arg("num_threads") = 0,
      py::arg("mask") = py::none(),
      "(flux, line_column, velocity, displacement, unexplained) per line of a float32 (T, H, "
      "W) stack, summed across the lines over the pixels of mask (H, W) when given "
      "(engine/flux/transport_flux.h).");

  m.def(
      "typical_displacement",
      [](const FloatArray& frames, const std::string& axis, int max_px, int num_threads) {
        CheckNdim(frames, 3, "frames");
        const FluxAxis a = ParseFluxAxis(axis);
        py::gil_scoped_release release;
        return TypicalDisplacement(frames.data(), frames.shape(0), frames.shape(1), frames.shape(2),
                                   a, max_px, num_threads);
      },
      py::arg("frames"), py::arg("axis") = "up", py::arg("max_px") = 16,
      py::arg("num_threads") = 0);

  m.def(
      "flux_level_scale",
      [](const FloatArray& frames, const FloatArray& u, const FloatArray& v,
         const DoubleArray& transport_flux, const std::string& axis, double smooth_px,
         double min_fraction, double max_factor, double max_reversed, int num_threads) {
        CheckNdim(frames, 3, "frames");
        for (const auto* a : {&u, &v})
          Require(a->ndim() == 3 && a->shape(0) == frames.shape(0) &&
                      a->shape(1) == frames.shape(1) && a->shape(2) == frames.shape(2),
                  "u and v must have the frames' (T, H, W) shape");
        FluxLevelOptions options;
        options.axis = ParseFluxAxis(axis);
        options.smooth_px = smooth_px;
        options.min_fraction = min_fraction;
        options.max_factor = max_factor;
        options.max_reversed = max_reversed;
        options.num_threads = num_threads;
        TransportFluxResult tf;
        tf.axis = options.axis;
        tf.flux = FlatVector(transport_flux);
        RunControl control = MakeRunControl();
        FluxLevel level;
        {
          py::gil_scoped_release release;
          level = FlowFluxLevel(frames.data(), u.data(), v.data(), frames.shape(0), frames.shape(1),
                                frames.shape(2), tf, options, &control);
        }
        return py::make_tuple(ToArray(level.scale), level.flow_used);
      },
      py::arg("frames"), py::arg("u"), py::arg("v"), py::arg("transport_flux"),
      py::arg("axis") = "up", py::arg("smooth_px") = 2.0, py::arg("min_fraction") = 0.05,
      py::arg("max_factor") = 2.5, py::arg("max_reversed") = 0.1, py::arg("num_threads") = 0,
      "(scale per line float32, flow_used) (engine/flux/flux_level.h); does not modify u, v.");

  m.def(
      "apply_flux_level",
      [](FloatArray u, FloatArray v, const FloatArray& scale, const DoubleArray& velocity,
         const DoubleArray& line_column, const std::string& axis, int num_threads) {
        CheckNdim(u, 3, "u");
        Require(v.ndim() == 3 && v.shape(0) == u.shape(0) && v.shape(1) == u.shape(1) &&
                    v.shape(2) == u.shape(2),
                "u and v must have one (T, H, W) shape");
        TransportFluxResult tf;
        tf.axis = ParseFluxAxis(axis);
        tf.velocity = FlatVector(velocity);
        tf.line_column = FlatVector(line_column);
        const std::vector<float> s(scale.data(), scale.data() + scale.size());
        float* pu = u.mutable_data();
        float* pv = v.mutable_data();
        py::gil_scoped_release release;
        ApplyFluxLevel(tf, s, u.shape(0), u.shape(1), u.shape(2), pu, pv, num_threads);
      },
      py::arg("u"), py::arg("v"), py::arg("scale"), py::arg("velocity"), py::arg("line_column"),
      py::arg("axis"), py::arg("num_threads") = 0,
      "Applies the flux level to u and v (T, H, W) float32 in place: lines with a finite "
      "scale multiplied by it, the others given the transport's line velocity "
      "(engine/flux/flux_level.h). u and v must be C-contiguous float32 arrays.");

  m.def(
      "transport_velocity",
      [](const DoubleArray& velocity, const DoubleArray& line_column, const std::string& axis,
         py::ssize_t T, py::ssize_t H, py::ssize_t W) {
        TransportFluxResult tf;
        tf.axis = ParseFluxAxis(axis);
        tf.velocity = FlatVector(velocity);
        tf.line_column = FlatVector(line_column);
        Require(T >= 0 && H >= 0 && W >= 0, "shape must be non-negative");
        py::array_t<float> u({T, H, W}), v({T, H, W});
        float* pu = u.mutable_data();
        float* pv = v.mutable_data();
        {
          py::gil_scoped_release release;
          TransportVelocity(tf, T, H, W, pu, pv);
        }
        return py::make_tuple(u, v);
      },
      py::arg("velocity"), py::arg("line_column"), py::arg("axis"), py::arg("T"), py::arg("H"),
      py::arg("W"),
      "(u, v) float32 (T, H, W): each line's transport velocity along the axis "
      "(engine/flux/flux_level.h).");
}

}  // namespace qogi
