// Bindings of engine/optics: Planck and SpectralResponse.
#include "common.h"

#include "engine/optics/planck.h"
#include "engine/optics/spectral_response.h"

namespace qogi {
namespace {

// fn(nu, t, out, n) over blocks of equal-length 1-D arrays nu_cm1 and
// temperature_K, in parallel with the GIL released.
template <typename Fn>
py::array_t<double> MapPairs(const DoubleArray& nu, const DoubleArray& t, Fn fn) {
  CheckNdim(nu, 1, "nu_cm1");
  CheckNdim(t, 1, "temperature_K");
  CheckSameLength(nu.size(), t.size(), "nu_cm1", "temperature_K");
  py::array_t<double> out(nu.size());
  const double *pn = nu.data(), *pt = t.data();
  double* po = out.mutable_data();
  const std::size_t n = static_cast<std::size_t>(nu.size());
  py::gil_scoped_release release;
  ParallelFor(n, 8192, [&](std::size_t b, std::size_t e) { fn(pn + b, pt + b, po + b, e - b); });
  return out;
}

}  // namespace

void BindOptics(py::module_& m) {
  m.attr("C1") = constants::kC1;
  m.attr("C2") = constants::kC2;
  m.attr("WIEN_NU") = constants::kWienNu;

  m.def(
      "planck_radiance",
      [](const DoubleArray& nu, const DoubleArray& t) {
        return MapPairs(nu, t, [](const double* nu, const double* t, double* out, std::size_t n) {
          PlanckRadiance(nu, t, out, n);
        });
      },
      py::arg("nu_cm1"), py::arg("temperature_K"),
      "Planck spectral radiance B(nu, T) [W/(m2 sr cm-1)] over equal-length "
      "1-D arrays (use qogi.planck_radiance for broadcasting).");

  m.def(
      "planck_radiance_derivative",
      [](const DoubleArray& nu, const DoubleArray& t) {
        return MapPairs(nu, t, [](const double* nu, const double* t, double* out, std::size_t n) {
          for (std::size_t i = 0; i < n; ++i) out[i] = PlanckRadianceDerivative(nu[i], t[i]);
        });
      },
      py::arg("nu_cm1"), py::arg("temperature_K"),
      "dB/dT [W/(m2 sr cm-1 K)] over equal-length 1-D arrays.");

  py::class_<SpectralResponse>(m, "SpectralResponse", R"doc(
A channel's spectral response (filter x lens x detector), piecewise linear
between samples and zero outside them.

Parameters
----------
nu_cm1 : array of float, cm-1
    Strictly increasing wavenumbers, finite and >= 0, at least 2.
response : array of float, dimensionless
    Same length, finite and >= 0, not all zero.
name : str
    Channel name shown in tables and plots.
)doc")
      .def(py::init([](const DoubleArray& nu, const DoubleArray& r, std::string name) {
             return SpectralResponse(ToVector(nu, "nu_cm1"), ToVector(r, "response"),
                                     std::move(name));
           }),
           py::arg("nu_cm1"), py::arg("response"), py::arg("name") = "")
      .def_property_readonly("name", &SpectralResponse::name)
      .def_property_readonly(
          "nu_cm1", [](const SpectralResponse& s) { return ToArray(s.nu_cm1()); },
          "Wavenumber samples [cm-1] (a copy).")
      .def_property_readonly(
          "response", [](const SpectralResponse& s) { return ToArray(s.response()); },
          "Response samples [dimensionless] (a copy).")
      .def_property_readonly("integral_cm1", &SpectralResponse::Integral,
                             "Integral of the response over wavenumber [cm-1].")
      .def_property_readonly("centroid_cm1", &SpectralResponse::CentroidWavenumber,
                             "Response-weighted mean wavenumber [cm-1].")
      .def("_evaluate",
           [](const SpectralResponse& s, const DoubleArray& nu) {
             return MapValues(nu, [&](double x) { return s.Evaluate(x); });
           })
      .def("_band_radiance",
           [](const SpectralResponse& s, const DoubleArray& t) {
             return MapValues(t, [&](double x) { return s.BandRadiance(x); });
           })
      .def("_band_radiance_derivative",
           [](const SpectralResponse& s, const DoubleArray& t) {
             return MapValues(t, [&](double x) { return s.BandRadianceDerivative(x); });
           })
      .def("_radiometric_temperature",
           [](const SpectralResponse& s, const DoubleArray& l) {
             return MapValues(l, [&](double x) { return s.RadiometricTemperature(x); });
           })
      .def(py::pickle(
          [](const SpectralResponse& s) {
            return py::make_tuple(s.nu_cm1(), s.response(), s.name());
          },
          [](py::tuple t) {
            return SpectralResponse(t[0].cast<std::vector<double>>(),
                                    t[1].cast<std::vector<double>>(), t[2].cast<std::string>());
          }));
}

}  // namespace qogi
