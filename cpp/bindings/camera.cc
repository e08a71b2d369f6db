// Bindings of engine/camera. Each part of the module has its own function,
// all called from BindCamera().
#include "common.h"

#include <cstdint>
#include <string>
#include <vector>

#include "engine/camera/calibration.h"
#include "engine/camera/noise.h"
#include "engine/camera/radiometric_table.h"
#include "engine/camera/warm_optics.h"

namespace qogi {
namespace {

void CheckFrames(const FloatArray& a, int height, int width, const char* name) {
  if (a.ndim() < 2 || a.shape(a.ndim() - 2) != height || a.shape(a.ndim() - 1) != width)
    throw std::invalid_argument(std::string(name) + " must end in the calibration's frame size (" +
                                std::to_string(height) + ", " + std::to_string(width) +
                                "); got an array of " + std::to_string(a.ndim()) + " dims");
}

py::dict StatsDict(const ApplyStats& s) {
  return ToDict(s, Field("out_of_range", &ApplyStats::out_of_range),
                Field("replaced", &ApplyStats::replaced),
                Field("unreplaced", &ApplyStats::unreplaced));
}

// ---------------------------------------------------------------------------
// Calibration: options, curve, per-channel calibration, fit, stack apply.
void BindCameraCalibration(py::module_& m) {
  using O = CalibrationOptions;
  BindOptions<O>(m, "CalibrationOptions", R"doc(
Options of the radiometric calibration fit (engine struct; see
qogi.camera.fit_calibration for the meaning of each field).
)doc",
                 Args::kKeywordOnly,
                 Field("quadratic", &O::quadratic,
                       "fit the quadratic term Q L^2 (needs >= 4 "
                       "temperatures); default False"),
                 Field("saturation_counts", &O::saturation_counts,
                       "raw counts >= this are saturated [counts]; default 65535"),
                 Field("min_valid_counts", &O::min_valid_counts,
                       "raw counts <= this are under range (dead) [counts]; default 0"),
                 Field("bad_response_tolerance", &O::bad_response_tolerance,
                       "a pixel whose NUC responsivity differs from the median by more than "
                       "this fraction of it is bad [-], (0, 1); default 0.3"),
                 Field("bad_noise_factor", &O::bad_noise_factor,
                       "a pixel whose temporal noise exceeds this multiple of the median is bad "
                       "[-], >= 1; default 6"),
                 Field("max_bad_fraction", &O::max_bad_fraction,
                       "more bad pixels than this fraction is an error [-]; default 0.05"),
                 Field("nuc_cold_scene", &O::nuc_cold_scene,
                       "index of the cold NUC scene; default -1 = the coldest"),
                 Field("nuc_hot_scene", &O::nuc_hot_scene,
                       "index of the hot NUC scene; default -1 = the hottest"),
                 Field("blackbody_emissivity", &O::blackbody_emissivity,
                       "emissivity of the calibration source [-], (0, 1]; default 1"),
                 Field("ambient_temperature_K", &O::ambient_temperature_K,
                       "temperature of the surroundings reflected by the source [K]; default "
                       "0 = none (needed when blackbody_emissivity < 1)"),
                 Field("num_threads", &O::num_threads, "worker threads; default 0 = all cores"));

  BindOptions<CountsFluxCurve>(
      m, "CountsFluxCurve", R"doc(
F(L) = G L + O + Q L^2 [counts/s] of band radiance L [W/(m2 sr)].
)doc",
      Args::kPositional,
      Required(Field("gain", &CountsFluxCurve::gain, "G [counts/s per W/(m2 sr)]")),
      Required(Field("offset", &CountsFluxCurve::offset, "O [counts/s]")),
      Field("quadratic", &CountsFluxCurve::quadratic, "Q [counts/s per (W/(m2 sr))^2]"))
      .def("flux", &CountsFluxCurve::Flux, py::arg("radiance"))
      .def("radiance", &CountsFluxCurve::Radiance, py::arg("flux"));

  py::class_<ChannelCalibration>(m, "ChannelCalibration", R"doc(
One channel's calibration: per-pixel NUC gain/offset, bad-pixel map and the
counts-flux curve (use qogi.camera.fit_calibration / Calibration).
)doc")
      .def(py::init(
               [](const SpectralResponse& channel, const DoubleArray& gain,
                  const DoubleArray& offset,
                  const py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>& bad,
                  const CountsFluxCurve& curve, const py::dict& points, double saturation_counts,
                  double min_valid_counts) {
                 CheckNdim(gain, 2, "nuc_gain");
                 CheckNdim(offset, 2, "nuc_offset");
                 CheckNdim(bad, 2, "bad_pixels");
                 const int h = static_cast<int>(gain.shape(0)), w = static_cast<int>(gain.shape(1));
                 std::vector<CalibrationPoint> pts;
                 if (points.size() > 0) {
                   auto col = [&](const char* k) { return points[k].cast<std::vector<double>>(); };
                   const auto t = col("blackbody_temperature_K"), ti = col("integration_time_s"),
                              l = col("radiance"), f = col("mean_flux"), rf = col("residual_flux"),
                              rk = col("residual_K"), sn = col("spatial_noise_K");
                   for (const auto* v : {&ti, &l, &f, &rf, &rk, &sn})
                     CheckSameLength(v->size(), t.size(), "calibration point column",
                                     "blackbody_temperature_K");
                   for (std::size_t k = 0; k < t.size(); ++k)
                     pts.push_back({t[k], ti[k], l[k], f[k], rf[k], rk[k], sn[k]});
                 }
                 return ChannelCalibration(
                     channel, h, w, FlatVector(gain), FlatVector(offset),
                     std::vector<std::uint8_t>(bad.data(), bad.data() + bad.size()), curve,
                     std::move(pts), saturation_counts, min_valid_counts);
               }),
           py::arg("channel"), py::arg("nuc_gain"), py::arg("nuc_offset"), py::arg("bad_pixels"),
           py::arg("curve"), py::arg("points"), py::arg("saturation_counts"),
           py::arg("min_valid_counts"))
      .def_property_readonly("channel", &ChannelCalibration::channel)
      .def_property_readonly("height", &ChannelCalibration::height)
      .def_property_readonly("width", &ChannelCalibration::width)
      .def_property_readonly(
          "nuc_gain",
          [](const ChannelCalibration& c) {
            return ToArray(c.nuc_gain()).reshape({c.height(), c.width()});
          },
          "Per-pixel NUC gain a_p [-] (height, width); 0 at bad pixels.")
      .def_property_readonly(
          "nuc_offset",
          [](const ChannelCalibration& c) {
            return ToArray(c.nuc_offset()).reshape({c.height(), c.width()});
          },
          "Per-pixel NUC offset b_p [counts/s] (height, width); 0 at bad pixels.")
      .def_property_readonly(
          "bad_pixels",
          [](const ChannelCalibration& c) {
            py::array_t<bool> out({c.height(), c.width()});
            bool* p = out.mutable_data();
            for (std::size_t i = 0; i < c.bad_pixels().size(); ++i) p[i] = c.bad_pixels()[i] != 0;
            return out;
          },
          "Bad-pixel map (height, width), True = bad.")
      .def_property_readonly("num_bad_pixels", &ChannelCalibration::num_bad_pixels)
      .def_property_readonly("curve", &ChannelCalibration::curve, py::return_value_policy::copy)
      .def_property_readonly(
          "points",
          [](const ChannelCalibration& c) {
            py::dict d;
            std::vector<double> cols[7];
            for (const auto& p : c.points()) {
              const double v[7] = {
                  p.blackbody_temperature_K, p.integration_time_s, p.radiance,       p.mean_flux,
                  p.residual_flux,           p.residual_K,         p.spatial_noise_K};
              for (int k = 0; k < 7; ++k) cols[k].push_back(v[k]);
            }
            const char* names[7] = {
                "blackbody_temperature_K", "integration_time_s", "radiance",       "mean_flux",
                "residual_flux",           "residual_K",         "spatial_noise_K"};
            for (int k = 0; k < 7; ++k) d[names[k]] = ToArray(cols[k]);
            return d;
          },
          "Per-scene fit diagnostics, a dict of arrays.")
      .def_property_readonly("saturation_counts", &ChannelCalibration::saturation_counts)
      .def_property_readonly("min_valid_counts", &ChannelCalibration::min_valid_counts)
      .def_property_readonly("rms_residual_K", &ChannelCalibration::rms_residual_K)
      .def_property_readonly("min_radiance", &ChannelCalibration::min_radiance)
      .def_property_readonly("max_radiance", &ChannelCalibration::max_radiance)
      .def(
          "_counts_to_radiance",
          [](const ChannelCalibration& c, const FloatArray& raw, std::size_t channel,
             const DoubleArray& times, FloatArray out, bool replace, int threads,
             py::object progress) {
            // raw, out: (N, C, H, W); this calibration converts channel `channel`.
            CheckNdim(raw, 4, "raw");
            CheckFrames(raw, c.height(), c.width(), "raw");
            CheckNdim(out, 4, "out");
            CheckSameLength(raw.size(), out.size(), "raw", "out");
            const std::size_t nc = raw.shape(1), npix = raw.shape(2) * raw.shape(3);
            if (channel >= nc) throw std::invalid_argument("channel index out of range");
            const std::vector<double> t = FlatVector(times);
            RunControl control = MakeRunControl(progress);
            const float* src = raw.data() + channel * npix;
            float* dst = out.mutable_data() + channel * npix;
            const std::size_t nf = raw.shape(0);
            ApplyStats s;
            {
              py::gil_scoped_release release;
              s = c.CountsToRadiance(src, nf, t, dst, replace, nc * npix, threads, &control);
            }
            return StatsDict(s);
          },
          py::arg("raw"), py::arg("channel"), py::arg("integration_time_s"), py::arg("out"),
          py::arg("replace_bad_pixels") = true, py::arg("num_threads") = 0,
          py::arg("progress") = py::none())
      .def(
          "_radiance_to_counts",
          [](const ChannelCalibration& c, const FloatArray& radiance, std::size_t channel,
             const DoubleArray& times, FloatArray out, int threads) {
            CheckNdim(radiance, 4, "radiance");
            CheckFrames(radiance, c.height(), c.width(), "radiance");
            CheckNdim(out, 4, "out");
            CheckSameLength(radiance.size(), out.size(), "radiance", "out");
            const std::size_t nc = radiance.shape(1), npix = radiance.shape(2) * radiance.shape(3);
            if (channel >= nc) throw std::invalid_argument("channel index out of range");
            const std::vector<double> t = FlatVector(times);
            const float* src = radiance.data() + channel * npix;
            float* dst = out.mutable_data() + channel * npix;
            const std::size_t nf = radiance.shape(0);
            py::gil_scoped_release release;
            c.RadianceToCounts(src, nf, t, dst, nc * npix, threads);
          },
          py::arg("radiance"), py::arg("channel"), py::arg("integration_time_s"), py::arg("out"),
          py::arg("num_threads") = 0)
      .def(py::pickle(
          [](const ChannelCalibration& c) {
            py::dict pts = py::cast(c).attr("points");
            return py::make_tuple(c.channel(), py::cast(c).attr("nuc_gain"),
                                  py::cast(c).attr("nuc_offset"), py::cast(c).attr("bad_pixels"),
                                  c.curve(), pts, c.saturation_counts(), c.min_valid_counts());
          },
          [](py::tuple t) {
            py::object cls = py::module_::import("qogi._engine").attr("ChannelCalibration");
            return cls(*t).cast<ChannelCalibration>();
          }));

  m.def(
      "_fit_channel_calibration",
      [](const SpectralResponse& channel, const py::list& scenes, const CalibrationOptions& options,
         py::object progress) {
        // scenes: [(blackbody_temperature_K, integration_time_s, frames float32 (N, H, W))]
        std::vector<CalibrationScene> cs;
        std::vector<FloatArray> keep;
        int h = -1, w = -1;
        for (std::size_t k = 0; k < scenes.size(); ++k) {
          py::tuple s = scenes[k].cast<py::tuple>();
          FloatArray f = s[2].cast<FloatArray>();
          const std::string name = "scenes[" + std::to_string(k) + "] frames";
          CheckNdim(f, 3, name.c_str());
          if (k == 0) {
            h = static_cast<int>(f.shape(1));
            w = static_cast<int>(f.shape(2));
          } else if (f.shape(1) != h || f.shape(2) != w) {
            throw std::invalid_argument(
                "calibration scenes must share one frame size: scene 0 is (" + std::to_string(h) +
                ", " + std::to_string(w) + "), scene " + std::to_string(k) + " is (" +
                std::to_string(f.shape(1)) + ", " + std::to_string(f.shape(2)) + ")");
          }
          cs.push_back({s[0].cast<double>(), s[1].cast<double>(), f.data(),
                        static_cast<std::size_t>(f.shape(0))});
          keep.push_back(f);
        }
        if (cs.empty()) throw std::invalid_argument("calibration needs scenes; got none");
        RunControl control = MakeRunControl(progress);
        py::gil_scoped_release release;
        return FitChannelCalibration(channel, h, w, cs, options, &control);
      },
      py::arg("channel"), py::arg("scenes"), py::arg("options"), py::arg("progress") = py::none());
}

// ---------------------------------------------------------------------------
// NETD noise.
void BindCameraNoise(py::module_& m) {
  m.def("netd_radiance_sigma", &NetdRadianceSigma, py::arg("channel"), py::arg("netd_K"),
        py::arg("background_temperature_K"),
        "sigma_L = NETD x dL/dT(T_bg) [W/(m2 sr)] of one channel.");
  m.def(
      "_add_gaussian_noise",
      [](FloatArray frames, std::size_t pixels_per_frame, const DoubleArray& sigma,
         std::uint64_t seed, std::uint64_t offset, int threads, py::object progress) {
        const std::size_t nc = static_cast<std::size_t>(sigma.size());
        const std::size_t per = nc * pixels_per_frame;
        if (per == 0 || frames.size() % per != 0)
          throw std::invalid_argument("frames must hold whole frames of " + std::to_string(nc) +
                                      " channels x " + std::to_string(pixels_per_frame) +
                                      " pixels; got " + std::to_string(frames.size()) + " values");
        const std::vector<double> s = FlatVector(sigma);
        RunControl control = MakeRunControl(progress);
        float* data = frames.mutable_data();
        const std::size_t nf = frames.size() / per;
        py::gil_scoped_release release;
        AddGaussianNoise(data, nf, pixels_per_frame, s, seed, offset, threads, &control);
      },
      py::arg("frames"), py::arg("pixels_per_frame"), py::arg("sigma_L"), py::arg("seed"),
      py::arg("offset") = 0, py::arg("num_threads") = 0, py::arg("progress") = py::none());
  m.def("standard_normal_draw", &StandardNormalDraw, py::arg("seed"), py::arg("index"),
        "Draw number `index` of the counter-based N(0, 1) stream keyed by `seed`.");
}

// ---------------------------------------------------------------------------
// Warm optics.
void BindCameraWarmOptics(py::module_& m) {
  py::class_<ChannelOptics>(m, "ChannelOptics", R"doc(
A channel's optics: detector response, filter transmittance and reflectance,
lens transmittance on one wavenumber grid (see qogi.camera.ChannelOptics).
)doc")
      .def(py::init([](const DoubleArray& nu, const DoubleArray& d, const DoubleArray& tf,
                       const DoubleArray& tl, py::object rf, std::string name) {
             CheckNdim(nu, 1, "nu_cm1");
             CheckNdim(d, 1, "detector_response");
             CheckNdim(tf, 1, "filter_transmittance");
             CheckNdim(tl, 1, "lens_transmittance");
             std::vector<double> rho;
             if (!rf.is_none()) {
               DoubleArray r = rf.cast<DoubleArray>();
               CheckNdim(r, 1, "filter_reflectance");
               rho = ToVector(r, "filter_reflectance");
             }
             return ChannelOptics(ToVector(nu, "nu_cm1"), ToVector(d, "detector_response"),
                                  ToVector(tf, "filter_transmittance"),
                                  ToVector(tl, "lens_transmittance"), std::move(rho),
                                  std::move(name));
           }),
           py::arg("nu_cm1"), py::arg("detector_response"), py::arg("filter_transmittance"),
           py::arg("lens_transmittance"), py::arg("filter_reflectance") = py::none(),
           py::arg("name") = "")
      .def_property_readonly("name", &ChannelOptics::name)
      .def_property_readonly("nu_cm1", [](const ChannelOptics& o) { return ToArray(o.nu_cm1()); })
      .def_property_readonly("detector_response",
                             [](const ChannelOptics& o) { return ToArray(o.detector_response()); })
      .def_property_readonly(
          "filter_transmittance",
          [](const ChannelOptics& o) { return ToArray(o.filter_transmittance()); })
      .def_property_readonly("filter_reflectance",
                             [](const ChannelOptics& o) { return ToArray(o.filter_reflectance()); })
      .def_property_readonly("lens_transmittance",
                             [](const ChannelOptics& o) { return ToArray(o.lens_transmittance()); })
      .def_property_readonly("_response", &ChannelOptics::response)
      .def("_warm_radiance",
           [](const ChannelOptics& o, const DoubleArray& tl, const DoubleArray& tf,
              const DoubleArray& tr) {
             CheckSameLength(tl.size(), tf.size(), "lens_temperature_K", "filter_temperature_K");
             CheckSameLength(tl.size(), tr.size(), "lens_temperature_K", "reflected_temperature_K");
             py::array_t<double> out(tl.size());
             double* p = out.mutable_data();
             for (py::ssize_t i = 0; i < tl.size(); ++i)
               p[i] = o.WarmRadiance(tl.data()[i], tf.data()[i], tr.data()[i]);
             return out;
           })
      .def("lens_term", &ChannelOptics::LensTerm, py::arg("temperature_K"))
      .def("filter_term", &ChannelOptics::FilterTerm, py::arg("temperature_K"))
      .def("reflected_term", &ChannelOptics::ReflectedTerm, py::arg("temperature_K"))
      .def("detector_band_radiance", &ChannelOptics::DetectorBandRadiance, py::arg("temperature_K"))
      .def("warm_radiance_derivative_lens", &ChannelOptics::WarmRadianceDerivativeLens,
           py::arg("lens_temperature_K"))
      .def("warm_radiance_derivative_filter", &ChannelOptics::WarmRadianceDerivativeFilter,
           py::arg("filter_temperature_K"))
      .def(py::pickle(
          [](const ChannelOptics& o) {
            return py::make_tuple(o.nu_cm1(), o.detector_response(), o.filter_transmittance(),
                                  o.lens_transmittance(), o.filter_reflectance(), o.name());
          },
          [](py::tuple t) {
            return ChannelOptics(t[0].cast<std::vector<double>>(), t[1].cast<std::vector<double>>(),
                                 t[2].cast<std::vector<double>>(), t[3].cast<std::vector<double>>(),
                                 t[4].cast<std::vector<double>>(), t[5].cast<std::string>());
          }));
  m.def("camera_preset_optics", &CameraPresetOptics, py::arg("name"),
        "Filter, lens and detector curves of a preset's channels.");
}

}  // namespace

void BindRadiometricTable(py::module_& m);  // at the end of this file

void BindCamera(py::module_& m) {
  BindCameraCalibration(m);
  BindCameraNoise(m);
  BindCameraWarmOptics(m);
  BindRadiometricTable(m);
}

// --- the L(T) table (engine/camera/radiometric_table.h) ---------------------
void BindRadiometricTable(py::module_& m) {
  py::class_<RadiometricTable>(m, "RadiometricTable",
                               "Band radiance <-> blackbody temperature of one channel, "
                               "tabulated (engine/camera/radiometric_table.h).")
      .def(py::init([](const SpectralResponse& channel, double t_min_K, double t_max_K, int nodes,
                       int num_threads) {
             py::gil_scoped_release release;
             return std::make_unique<RadiometricTable>(channel, t_min_K, t_max_K, nodes,
                                                       num_threads);
           }),
           py::arg("channel"), py::arg("t_min_K") = 150.0, py::arg("t_max_K") = 1500.0,
           py::arg("nodes") = 512, py::arg("num_threads") = 0)
      .def_property_readonly("t_min_K", &RadiometricTable::t_min_K)
      .def_property_readonly("t_max_K", &RadiometricTable::t_max_K)
      .def_property_readonly("radiance_min", &RadiometricTable::radiance_min)
      .def_property_readonly("radiance_max", &RadiometricTable::radiance_max)
      .def(
          "radiance",
          [](const RadiometricTable& t, const DoubleArray& temperature_K) {
            return MapValues(temperature_K, [&](double x) { return t.Radiance(x); });
          },
          py::arg("temperature_K"),
          "Band radiance [W/(m2 sr)] of blackbodies at temperature_K [K] (any shape, float64).")
      .def(
          "temperature",
          [](const RadiometricTable& t, const DoubleArray& radiance) {
            return MapValues(radiance, [&](double x) { return t.Temperature(x); });
          },
          py::arg("radiance"),
          "Radiometric temperature [K] of band radiances [W/(m2 sr)] (any shape, float64; NaN "
          "where no blackbody of 10 K - 1e5 K gives the radiance).");
}

}  // namespace qogi
