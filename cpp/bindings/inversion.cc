// Bindings of engine/inversion: scene tables, inversion options and the
// per-pixel inverter. Glue only: shapes are checked here, the work (with the
// GIL released) happens in the engine.

#include <memory>

#include "common.h"
#include "engine/inversion/inversion.h"
#include "engine/inversion/mixing_line.h"
#include "engine/inversion/mixing_line_slope.h"
#include "engine/inversion/scene_table.h"
#include "engine/rte/binned_model.h"

namespace qogi {
namespace {

// The BinnedModel is owned by Python; engine objects hold a non-owning
// pointer and py::keep_alive ties the lifetimes.
std::shared_ptr<const BinnedModel> Borrow(const BinnedModel& m) {
  return std::shared_ptr<const BinnedModel>(&m, [](const BinnedModel*) {});
}

std::size_t Dim(const py::array& a, int k) { return static_cast<std::size_t>(a.shape(k)); }

std::string Shape(const py::array& a) {
  std::string s = "(";
  for (int k = 0; k < a.ndim(); ++k) s += (k ? ", " : "") + std::to_string(a.shape(k));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

py::dict SceneTableOptionsDict(const SceneTableOptions& o) {
  py::dict d;
  d["ambient_temperature_K"] = o.ambient_temperature_K;
  d["min_peak_temperature_K"] = o.min_peak_temperature_K;
  d["max_peak_temperature_K"] = o.max_peak_temperature_K;
  d["temperature_step_K"] = o.temperature_step_K;
  d["max_sigma_m"] = o.max_sigma_m;
  d["nodes_per_decade"] = o.nodes_per_decade;
  d["fraction_nodes"] = o.fraction_nodes;
  d["thin_optical_depth"] = o.thin_optical_depth;
  d["min_background_K"] = o.min_background_K;
  d["max_background_K"] = o.max_background_K;
  d["planck_tolerance"] = o.planck_tolerance;
  d["num_threads"] = o.num_threads;
  d["num_nodes"] = o.num_nodes;
  d["negligible_fraction"] = o.negligible_fraction;
  d["linear_optical_depth"] = o.linear_optical_depth;
  return d;
}

void BindMixingLineSlope(py::module_& m);  // at the end of this file

}  // namespace

void BindInversion(py::module_& m) {
  // --- scene tables ----------------------------------------------------------
  py::class_<SceneTableOptions>(m, "SceneTableOptions",
                                "Settings of the per-scene table (see engine/inversion/scene_table.h).")
      .def(py::init([](double t_amb, double t_lo, double t_hi, double dt, double smax, int npd,
                       int nx, double thin, double bg_lo, double bg_hi, double tol, int threads,
                       int nodes, double negligible, double linear) {
             SceneTableOptions o;
             o.ambient_temperature_K = t_amb;
             o.min_peak_temperature_K = t_lo;
             o.max_peak_temperature_K = t_hi;
             o.temperature_step_K = dt;
             o.max_sigma_m = smax;
             o.nodes_per_decade = npd;
             o.fraction_nodes = nx;
             o.thin_optical_depth = thin;
             o.min_background_K = bg_lo;
             o.max_background_K = bg_hi;
             o.planck_tolerance = tol;
             o.num_threads = threads;
             o.num_nodes = nodes;
             o.negligible_fraction = negligible;
             o.linear_optical_depth = linear;
             o.Check();
             return o;
           }),
           py::arg("ambient_temperature_K") = SceneTableOptions().ambient_temperature_K,
           py::arg("min_peak_temperature_K") = SceneTableOptions().min_peak_temperature_K,
           py::arg("max_peak_temperature_K") = SceneTableOptions().max_peak_temperature_K,
           py::arg("temperature_step_K") = SceneTableOptions().temperature_step_K,
           py::arg("max_sigma_m") = SceneTableOptions().max_sigma_m,
           py::arg("nodes_per_decade") = SceneTableOptions().nodes_per_decade,
           py::arg("fraction_nodes") = SceneTableOptions().fraction_nodes,
           py::arg("thin_optical_depth") = SceneTableOptions().thin_optical_depth,
           py::arg("min_background_K") = SceneTableOptions().min_background_K,
           py::arg("max_background_K") = SceneTableOptions().max_background_K,
           py::arg("planck_tolerance") = SceneTableOptions().planck_tolerance,
           py::arg("num_threads") = SceneTableOptions().num_threads,
           py::arg("num_nodes") = SceneTableOptions().num_nodes,
           py::arg("negligible_fraction") = SceneTableOptions().negligible_fraction,
           py::arg("linear_optical_depth") = SceneTableOptions().linear_optical_depth)
      .def_readonly("ambient_temperature_K", &SceneTableOptions::ambient_temperature_K)
      .def_readonly("min_peak_temperature_K", &SceneTableOptions::min_peak_temperature_K)
      .def_readonly("max_peak_temperature_K", &SceneTableOptions::max_peak_temperature_K)
      .def_readonly("temperature_step_K", &SceneTableOptions::temperature_step_K)
      .def_readonly("max_sigma_m", &SceneTableOptions::max_sigma_m)
      .def_readonly("nodes_per_decade", &SceneTableOptions::nodes_per_decade)
      .def_readonly("fraction_nodes", &SceneTableOptions::fraction_nodes)
      .def_readonly("thin_optical_depth", &SceneTableOptions::thin_optical_depth)
      .def_readonly("min_background_K", &SceneTableOptions::min_background_K)
      .def_readonly("max_background_K", &SceneTableOptions::max_background_K)
      .def_readonly("planck_tolerance", &SceneTableOptions::planck_tolerance)
      .def_readonly("num_threads", &SceneTableOptions::num_threads)
      .def_readonly("num_nodes", &SceneTableOptions::num_nodes)
      .def_readonly("negligible_fraction", &SceneTableOptions::negligible_fraction)
      .def_readonly("linear_optical_depth", &SceneTableOptions::linear_optical_depth)
      .def("to_dict", &SceneTableOptionsDict)
      .def("__repr__", [](const SceneTableOptions& o) {
        return "SceneTableOptions(" + py::str(SceneTableOptionsDict(o)).cast<std::string>() + ")";
      });

  py::class_<MixingLineInverter>(m, "MixingLineInverter",
                                 "Per-pixel inversion on a plume's mixing line "
                                 "(engine/inversion/mixing_line.h).")
      .def(py::init([](std::shared_ptr<SceneTable> table) {
             py::gil_scoped_release release;
             return std::make_unique<MixingLineInverter>(std::move(table));
           }),
           py::arg("table"))
      .def(
          "invert",
          [](const MixingLineInverter& self, const DoubleArray& radiance,
             const DoubleArray& background, const DoubleArray& sigma, double slope,
             std::vector<double> composition, std::vector<double> netd, double detection_sigma,
             int max_iterations, int num_threads, int line_nodes_per_unit,
             py::object progress) {
            const std::size_t nc = self.table().num_channels();
            CheckNdim(radiance, 2, "radiance");
            const std::size_t n = Dim(radiance, 0);
            if (Dim(radiance, 1) != nc || background.ndim() != 2 || Dim(background, 0) != n ||
                Dim(background, 1) != nc || static_cast<std::size_t>(sigma.size()) != n)
              throw std::invalid_argument(
                  "invert needs radiance and background_radiance (N, " + std::to_string(nc) +
                  ") and sigma_m (N,); got " + Shape(radiance) + ", " + Shape(background) +
                  ", " + Shape(sigma));
            MixingLineOptions o;
            o.slope_K_per_fraction = slope;
            o.composition = std::move(composition);
            o.netd_K = std::move(netd);
            o.detection_sigma = detection_sigma;
            o.max_iterations = max_iterations;
            o.num_threads = num_threads;
            o.line_nodes_per_unit = line_nodes_per_unit;
            py::array_t<double> x(n), xs(n), tp(n), chi2(n);
            py::array_t<std::int32_t> status(n), iters(n);
            MixingLineOutput out{x.mutable_data(), xs.mutable_data(), tp.mutable_data(),
                                 chi2.mutable_data(), status.mutable_data(),
                                 iters.mutable_data()};
            RunControl control = MakeRunControl(progress);
            {
              py::gil_scoped_release release;
              self.Invert(o, n, radiance.data(), background.data(), sigma.data(), out,
                          &control);
            }
            py::dict d;
            d["fraction"] = x;
            d["fraction_sigma"] = xs;
            d["peak_temperature_K"] = tp;
            d["chi2"] = chi2;
            d["status"] = status;
            d["iterations"] = iters;
            return d;
          },
          py::arg("radiance"), py::arg("background_radiance"), py::arg("sigma_m"),
          py::arg("slope_K_per_fraction"), py::arg("composition"), py::arg("netd_K"),
          py::arg("detection_sigma") = 3.0, py::arg("max_iterations") = 50,
          py::arg("num_threads") = 0, py::arg("line_nodes_per_unit") = 16,
          py::arg("progress") = py::none(),
          "Least-squares total peak fraction X of each pixel (rows of radiance and "
          "background_radiance (N, C)) on T_peak = T_amb + k X with x_s = w_s X. Returns a dict "
          "of (N,) arrays: fraction, fraction_sigma, peak_temperature_K, chi2, status "
          "(PixelStatus), iterations.");

  m.def("spectral_overlaps", &SceneTable::SpectralOverlaps, py::arg("model"),
        "Channels in which several species absorb in the same bin (empty: the per-scene "
        "table applies).");

  py::class_<SceneTable, std::shared_ptr<SceneTable>>(m, "SceneTable",
                                                      "Per-scene table of the fast forward model.")
      .def(py::init([](const BinnedModel& model, const SceneTableOptions& o, py::object progress) {
             RunControl control = MakeRunControl(progress);
             py::gil_scoped_release release;
             return std::make_shared<SceneTable>(Borrow(model), o, &control);
           }),
           py::arg("model"), py::arg("options"), py::arg("progress") = py::none(),
           py::keep_alive<1, 2>())
      .def_property_readonly("options", &SceneTable::options)
      .def_property_readonly("build_seconds", &SceneTable::build_seconds)
      .def_property_readonly("memory_bytes", &SceneTable::memory_bytes)
      .def_property_readonly("num_tabulated_bins", &SceneTable::num_tabulated_bins)
      .def_property_readonly("negligible_bound", &SceneTable::negligible_bound,
                             "Bound on the left-out bins' contribution to a contrast [W/(m2 sr)].")
      .def_property_readonly("min_peak_temperature_K", &SceneTable::min_peak_temperature_K)
      .def_property_readonly("max_peak_temperature_K", &SceneTable::max_peak_temperature_K)
      .def_property_readonly("min_column_proxy_m", &SceneTable::min_column_proxy_m)
      .def_property_readonly("max_column_proxy_m", &SceneTable::max_column_proxy_m)
      .def_property_readonly("grid_shape", [](const SceneTable& t) {
        return py::make_tuple(t.num_u_nodes(), t.num_fraction_nodes(), t.num_temperature_nodes());
      })
      .def("has_table", &SceneTable::has_table, py::arg("channel"), py::arg("species"))
      .def("basis_rank", &SceneTable::basis_rank, py::arg("channel"), py::arg("species"))
      .def("contrast",
           [](const SceneTable& t, const DoubleArray& x, const DoubleArray& tp, const DoubleArray& sigma,
              const DoubleArray& tbg) {
             const std::size_t nc = t.num_channels(), ns = t.num_species(), np = ns + 2;
             CheckNdim(x, 2, "peak_fractions");
             CheckNdim(tbg, 2, "background_temperature_K");
             const std::size_t n = Dim(x, 0);
             if (Dim(x, 1) != ns || static_cast<std::size_t>(tp.size()) != n ||
                 static_cast<std::size_t>(sigma.size()) != n || Dim(tbg, 0) != n || Dim(tbg, 1) != nc)
               throw std::invalid_argument(
                   "contrast needs peak_fractions (N, " + std::to_string(ns) +
                   "), peak_temperature_K (N,), sigma_m (N,), background_temperature_K (N, " +
                   std::to_string(nc) + ")");
             py::array_t<double> out({n, nc}), jac({n, nc, np});
             double* o = out.mutable_data();
             double* j = jac.mutable_data();
             {
               py::gil_scoped_release release;
               std::vector<double> phi(t.background_size());
               for (std::size_t i = 0; i < n; ++i) {
                 t.Background(tbg.data() + i * nc, phi.data());
                 t.Contrast(x.data() + i * ns, tp.data()[i], sigma.data()[i], phi.data(), o + i * nc,
                            j + i * nc * np);
               }
             }
             return py::make_tuple(out, jac);
           },
           py::arg("peak_fractions"), py::arg("peak_temperature_K"), py::arg("sigma_m"),
           py::arg("background_temperature_K"),
           "Contrast (N, C) [W/(m2 sr)] and its Jacobian (N, C, S + 2) over (fractions, "
           "T_peak, sigma) from the table.")
      .def("export",
           [](const SceneTable& t, std::size_t c, std::size_t s) {
             // The coefficients and grids of one table, for independent
             // (e.g. numpy) evaluators of the same model.
             py::dict d;
             if (!t.has_table(c, s)) return d;
             std::vector<double> coef, psi;
             double nu_ref = 0;
             t.Export(c, s, &coef, &psi, &nu_ref);
             const int r1 = t.basis_rank(c, s) + 1;
             const int nx = t.fraction_axis(s);
             const std::size_t nxc = nx > 1 ? nx + 2 : 1;
             d["coefficients"] = py::array_t<double>(
                 {static_cast<std::size_t>(t.num_temperature_nodes() + 2), nxc,
                  static_cast<std::size_t>(t.num_u_nodes() + 2), static_cast<std::size_t>(r1)},
                 coef.data());
             d["log_u0"] = t.min_log_u();
             d["log_u_step"] = t.log_u_step();
             d["num_u"] = t.num_u_nodes();
             d["num_x"] = nx;
             d["t0"] = t.min_peak_temperature_K();
             d["t_step"] = (t.max_peak_temperature_K() - t.min_peak_temperature_K()) /
                           (t.num_temperature_nodes() - 1);
             d["num_t"] = t.num_temperature_nodes();
             d["rank"] = r1 - 1;
             d["nu_ref_cm1"] = nu_ref;
             d["background_t0"] = t.options().min_background_K;
             d["background_step"] = t.background_step_K();
             d["psi_coefficients"] = py::array_t<double>(
                 {psi.size() / static_cast<std::size_t>(std::max(1, r1 - 1)),
                  static_cast<std::size_t>(r1 - 1)},
                 psi.data());
             return d;
           },
           py::arg("channel"), py::arg("species"));

  m.def("measure_table_error",
        [](const SceneTable& t, int n, unsigned seed, double floor_fraction, bool jac) {
          TableErrorReport r;
          {
            py::gil_scoped_release release;
            r = MeasureTableError(t, n, seed, floor_fraction, jac);
          }
          py::dict d;
          d["max_relative_error"] = r.max_relative_error;
          d["rms_relative_error"] = r.rms_relative_error;
          d["max_jacobian_error"] = r.max_jacobian_error;
          d["num_samples"] = r.num_samples;
          return d;
        },
        py::arg("table"), py::arg("num_samples") = 200, py::arg("seed") = 1,
        py::arg("floor_fraction") = 1e-3, py::arg("check_jacobian") = false,
        "Error of the table against the binned model over random plumes (see "
        "MeasureTableError).");

  // --- options ---------------------------------------------------------------
  py::enum_<ParameterMode>(m, "ParameterMode")
      .value("fixed", ParameterMode::kFixed)
      .value("free", ParameterMode::kFree)
      .value("prior", ParameterMode::kPrior)
      .value("tied", ParameterMode::kTied);
  py::enum_<InitialGuess>(m, "InitialGuess")
      .value("table", InitialGuess::kTable)
      .value("neighbour", InitialGuess::kNeighbour)
      .value("previous", InitialGuess::kPrevious)
      .value("given", InitialGuess::kGiven);
  py::enum_<ColdStart>(m, "ColdStart")
      .value("profile", ColdStart::kProfile)
      .value("starts", ColdStart::kStarts);
  py::enum_<SolverKind>(m, "SolverKind")
      .value("auto", SolverKind::kAuto)
      .value("table", SolverKind::kTable)
      .value("full_model", SolverKind::kFullModel);

  py::class_<ParameterSpec>(m, "ParameterSpec")
      .def(py::init([](ParameterMode mode, double value, double prior_sigma, double lower,
                       double upper, int tied_to) {
             return ParameterSpec{mode, value, prior_sigma, lower, upper, tied_to};
           }),
           py::arg("mode"), py::arg("value") = 0.0, py::arg("prior_sigma") = 0.0,
           py::arg("lower") = 0.0, py::arg("upper") = 0.0, py::arg("tied_to") = -1)
      .def_readonly("tied_to", &ParameterSpec::tied_to)
      .def_readonly("mode", &ParameterSpec::mode)
      .def_readonly("value", &ParameterSpec::value)
      .def_readonly("prior_sigma", &ParameterSpec::prior_sigma)
      .def_readonly("lower", &ParameterSpec::lower)
      .def_readonly("upper", &ParameterSpec::upper)
      .def("__repr__", [](const ParameterSpec& p) {
        return "ParameterSpec(mode=" + py::str(py::cast(p.mode)).cast<std::string>() +
               ", value=" + FormatNumber(p.value) + ", prior_sigma=" + FormatNumber(p.prior_sigma) +
               ", lower=" + FormatNumber(p.lower) + ", upper=" + FormatNumber(p.upper) +
               ", tied_to=" + std::to_string(p.tied_to) + ")";
      });

  py::class_<InversionOptions>(m, "InversionOptions")
      .def(py::init([](std::vector<ParameterSpec> fractions, ParameterSpec temperature,
                       ParameterSpec sigma, std::vector<double> netd, double detection_sigma,
                       double model_error_fraction, int max_iterations, double tolerance_chi2,
                       InitialGuess guess, int candidates, int guess_iterations, int starts,
                       SolverKind solver, int threads, ColdStart cold_start) {
             InversionOptions o;
             o.fractions = std::move(fractions);
             o.temperature = temperature;
             o.sigma = sigma;
             o.netd_K = std::move(netd);
             o.detection_sigma = detection_sigma;
             o.model_error_fraction = model_error_fraction;
             o.max_iterations = max_iterations;
             o.tolerance_chi2 = tolerance_chi2;
             o.initial_guess = guess;
             o.temperature_candidates = candidates;
             o.guess_iterations = guess_iterations;
             o.num_starts = starts;
             o.solver = solver;
             o.num_threads = threads;
             o.cold_start = cold_start;
             return o;
           }),
           py::arg("fractions") = std::vector<ParameterSpec>(),
           py::arg("temperature") = InversionOptions().temperature,
           py::arg("sigma") = InversionOptions().sigma,
           py::arg("netd_K") = InversionOptions().netd_K,
           py::arg("detection_sigma") = InversionOptions().detection_sigma,
           py::arg("model_error_fraction") = InversionOptions().model_error_fraction,
           py::arg("max_iterations") = InversionOptions().max_iterations,
           py::arg("tolerance_chi2") = InversionOptions().tolerance_chi2,
           py::arg("initial_guess") = InversionOptions().initial_guess,
           py::arg("temperature_candidates") = InversionOptions().temperature_candidates,
           py::arg("guess_iterations") = InversionOptions().guess_iterations,
           py::arg("num_starts") = InversionOptions().num_starts,
           py::arg("solver") = InversionOptions().solver,
           py::arg("num_threads") = InversionOptions().num_threads,
           py::arg("cold_start") = InversionOptions().cold_start)
      .def_readonly("fractions", &InversionOptions::fractions)
      .def_readonly("temperature", &InversionOptions::temperature)
      .def_readonly("sigma", &InversionOptions::sigma)
      .def_readonly("netd_K", &InversionOptions::netd_K)
      .def_readonly("detection_sigma", &InversionOptions::detection_sigma)
      .def_readonly("model_error_fraction", &InversionOptions::model_error_fraction)
      .def_readonly("max_iterations", &InversionOptions::max_iterations)
      .def_readonly("tolerance_chi2", &InversionOptions::tolerance_chi2)
      .def_readonly("initial_guess", &InversionOptions::initial_guess)
      .def_readonly("temperature_candidates", &InversionOptions::temperature_candidates)
      .def_readonly("guess_iterations", &InversionOptions::guess_iterations)
      .def_readonly("num_starts", &InversionOptions::num_starts)
      .def_readonly("solver", &InversionOptions::solver)
      .def_readonly("num_threads", &InversionOptions::num_threads)
      .def_readonly("cold_start", &InversionOptions::cold_start);

  m.def("pixel_status_name", [](int s) { return std::string(PixelStatusName(static_cast<PixelStatus>(s))); },
        py::arg("status"));
  m.def("gaussian_profile_integral",
        [](double tp, double ta) {
          double i, di;
          GaussianProfileIntegral(tp, ta, &i, &di);
          return py::make_tuple(i, di);
        },
        py::arg("peak_temperature_K"), py::arg("ambient_temperature_K"),
        "(I, dI/dT_peak) with I = integral g(z) / T(z) dz of a Gaussian plume [1/K].");

  // --- the inverter ----------------------------------------------------------
  py::class_<Inverter>(m, "Inverter")
      .def(py::init([](const BinnedModel& model, std::shared_ptr<SceneTable> table, double t_amb,
                       const InversionOptions& o) {
             return std::make_unique<Inverter>(Borrow(model), table, t_amb, o);
           }),
           py::arg("model"), py::arg("table"), py::arg("ambient_temperature_K"), py::arg("options"),
           py::keep_alive<1, 2>())
      .def_property_readonly("uses_table", &Inverter::uses_table)
      .def_property_readonly("uses_newton", &Inverter::uses_newton)
      .def_property_readonly("num_parameters", &Inverter::num_parameters)
      .def("channel_noise", &Inverter::ChannelNoise, py::arg("channel"),
           py::arg("background_temperature_K"))
      .def("invert",
           [](const Inverter& inv, const DoubleArray& radiance, py::object background_radiance,
              py::object background_temperature, py::object sigma_m, py::object peak_temperature,
              py::object initial, std::size_t row_length, py::object progress) {
             const std::size_t nc = inv.model().num_channels(), ns = inv.model().num_species();
             const std::size_t np = ns + 2;
             CheckNdim(radiance, 3, "radiance (frames, channels, pixels)");
             const std::size_t nf = Dim(radiance, 0), n = Dim(radiance, 2);
             if (Dim(radiance, 1) != nc)
               throw std::invalid_argument("radiance has " + std::to_string(Dim(radiance, 1)) +
                                           " channels; the model has " + std::to_string(nc));
             if (background_radiance.is_none() == background_temperature.is_none())
               throw std::invalid_argument(
                   "give exactly one of background_radiance and background_temperature_K");
             const bool bg_is_t = !background_temperature.is_none();
             DoubleArray bg = (bg_is_t ? background_temperature : background_radiance).cast<DoubleArray>();
             CheckNdim(bg, 3, "background (frames or 1, channels, pixels)");
             if (!((Dim(bg, 0) == 1 || Dim(bg, 0) == nf) && Dim(bg, 1) == nc && Dim(bg, 2) == n))
               throw std::invalid_argument("the background has shape " + Shape(bg) +
                                           "; expected (1 or " + std::to_string(nf) + ", " +
                                           std::to_string(nc) + ", " + std::to_string(n) + ")");
             DoubleArray sg, tp, init;
             PixelBatch b;
             b.num_pixels = n;
             b.num_frames = nf;
             b.row_length = row_length;
             b.radiance = radiance.data();
             b.background_per_frame = Dim(bg, 0) == nf && nf > 1;
             (bg_is_t ? b.background_temperature_K : b.background_radiance) = bg.data();
             if (!sigma_m.is_none()) {
               sg = sigma_m.cast<DoubleArray>();
               if (static_cast<std::size_t>(sg.size()) != n)
                 throw std::invalid_argument("sigma_m needs one value per pixel (" +
                                             std::to_string(n) + "); got shape " + Shape(sg));
               b.sigma_m = sg.data();
             }
             if (!peak_temperature.is_none()) {
               tp = peak_temperature.cast<DoubleArray>();
               if (static_cast<std::size_t>(tp.size()) != n)
                 throw std::invalid_argument("peak_temperature_K needs one value per pixel (" +
                                             std::to_string(n) + "); got shape " + Shape(tp));
               b.peak_temperature_K = tp.data();
             }
             if (!initial.is_none()) {
               init = initial.cast<DoubleArray>();
               if (static_cast<std::size_t>(init.size()) != n * np)
                 throw std::invalid_argument("initial needs (pixels, " + std::to_string(np) +
                                             ") values; got shape " + Shape(init));
               b.initial = init.data();
             }
             py::array_t<std::uint8_t> status({nf, n}), bound({nf, n}), flags({nf, n});
             py::array_t<double> params({nf, n, np}), psig({nf, n, np}), cov({nf, n, np, np});
             py::array_t<double> col({nf, n, ns}), colsig({nf, n, ns}), ppm({nf, n, ns}),
                 ppmsig({nf, n, ns}), chi2({nf, n}), cond({nf, n});
             py::array_t<std::int32_t> iters({nf, n});
             InversionOutput o;
             o.status = status.mutable_data();
             o.bound_mask = bound.mutable_data();
             o.flags = flags.mutable_data();
             o.parameters = params.mutable_data();
             o.parameter_sigma = psig.mutable_data();
             o.covariance = cov.mutable_data();
             o.column_density = col.mutable_data();
             o.column_density_sigma = colsig.mutable_data();
             o.path_concentration = ppm.mutable_data();
             o.path_concentration_sigma = ppmsig.mutable_data();
             o.chi2 = chi2.mutable_data();
             o.condition_number = cond.mutable_data();
             o.iterations = iters.mutable_data();
             RunControl control = MakeRunControl(progress);
             {
               py::gil_scoped_release release;
               inv.Invert(b, o, &control);
             }
             py::dict d;
             d["status"] = status;
             d["bound_mask"] = bound;
             d["flags"] = flags;
             d["parameters"] = params;
             d["parameter_sigma"] = psig;
             d["covariance"] = cov;
             d["column_density"] = col;
             d["column_density_sigma"] = colsig;
             d["path_concentration"] = ppm;
             d["path_concentration_sigma"] = ppmsig;
             d["chi2"] = chi2;
             d["condition_number"] = cond;
             d["iterations"] = iters;
             return d;
           },
           py::arg("radiance"), py::arg("background_radiance") = py::none(),
           py::arg("background_temperature_K") = py::none(), py::arg("sigma_m") = py::none(),
           py::arg("peak_temperature_K") = py::none(), py::arg("initial") = py::none(),
           py::arg("row_length") = 0, py::arg("progress") = py::none());
  BindMixingLineSlope(m);
}

namespace {

// --- the mixing line's slope (engine/inversion/mixing_line_slope.h) ----------
py::dict SlopeDict(const MixingLineSlope& r) {
  py::dict d;
  d["found"] = r.found;
  d["slope_K_per_fraction"] = r.slope_K_per_fraction;
  d["sigma_K_per_fraction"] = r.sigma_K_per_fraction;
  d["num_candidates"] = r.num_candidates;
  d["num_samples"] = r.num_samples;
  d["num_fitted"] = r.num_fitted;
  d["grid_K_per_fraction"] = py::array_t<double>(r.grid_K_per_fraction.size(),
                                                 r.grid_K_per_fraction.data());
  d["total_chi2"] = py::array_t<double>(r.total_chi2.size(), r.total_chi2.data());
  return d;
}

void CheckRows(const MixingLineInverter& self, const DoubleArray& radiance,
               const DoubleArray& background, const char* what) {
  const std::size_t nc = self.table().num_channels();
  if (radiance.ndim() != 2 || Dim(radiance, 1) != nc || background.ndim() != 2 ||
      Dim(background, 0) != Dim(radiance, 0) || Dim(background, 1) != nc)
    throw std::invalid_argument(std::string(what) + " needs radiance and background_radiance (N, " +
                                std::to_string(nc) + "); got " + Shape(radiance) + ", " +
                                Shape(background));
}

void BindMixingLineSlope(py::module_& m) {
  auto inverter = py::type::of<MixingLineInverter>();
  py::class_<MixingLineInverter> cls(inverter);
  cls.def(
         "find_slope",
         [](const MixingLineInverter& self, const DoubleArray& radiance,
            const DoubleArray& background, const DoubleArray& sigma,
            std::vector<double> composition, std::vector<double> netd, double detection_sigma,
            int max_iterations, int num_threads, int line_nodes_per_unit, double min_snr,
            std::size_t max_samples, std::uint64_t seed, std::size_t min_samples,
            double grid_step_K, double chi2_cap, py::object progress) {
           CheckRows(self, radiance, background, "find_slope");
           const std::size_t n = Dim(radiance, 0);
           if (static_cast<std::size_t>(sigma.size()) != n)
             throw std::invalid_argument("find_slope needs sigma_m (N,) = (" + std::to_string(n) +
                                         ",); got " + Shape(sigma));
           MixingLineSlopeOptions o;
           o.line.composition = std::move(composition);
           o.line.netd_K = std::move(netd);
           o.line.detection_sigma = detection_sigma;
           o.line.max_iterations = max_iterations;
           o.line.num_threads = num_threads;
           o.line.line_nodes_per_unit = line_nodes_per_unit;
           o.min_snr = min_snr;
           o.max_samples = max_samples;
           o.seed = seed;
           o.min_samples = min_samples;
           o.grid_step_K = grid_step_K;
           o.chi2_cap = chi2_cap;
           RunControl control = MakeRunControl(progress);
           MixingLineSlope r;
           {
             py::gil_scoped_release release;
             r = FindMixingLineSlope(self, o, n, radiance.data(), background.data(), sigma.data(),
                                     &control);
           }
           return SlopeDict(r);
         },
         py::arg("radiance"), py::arg("background_radiance"), py::arg("sigma_m"),
         py::arg("composition"), py::arg("netd_K"), py::arg("detection_sigma") = 3.0,
         py::arg("max_iterations") = 50, py::arg("num_threads") = 0,
         py::arg("line_nodes_per_unit") = 16, py::arg("min_snr") = 10.0,
         py::arg("max_samples") = 3000, py::arg("seed") = 0, py::arg("min_samples") = 5,
         py::arg("grid_step_K") = 10.0, py::arg("chi2_cap") = 50.0,
         py::arg("progress") = py::none(),
         "The scene's mixing-line slope k from pixel-frames (rows of radiance and "
         "background_radiance (N, C)): FindMixingLineSlope. Returns a dict: found, "
         "slope_K_per_fraction, sigma_K_per_fraction, num_candidates, num_samples, num_fitted, "
         "grid_K_per_fraction, total_chi2.")
      .def(
          "slope_sample",
          [](const MixingLineInverter& self, const DoubleArray& radiance,
             const DoubleArray& background, std::vector<double> netd, double min_snr,
             std::size_t max_samples, std::uint64_t seed) {
            CheckRows(self, radiance, background, "slope_sample");
            MixingLineSlopeOptions o;
            o.line.netd_K = std::move(netd);
            o.min_snr = min_snr;
            o.max_samples = max_samples;
            o.seed = seed;
            std::size_t candidates = 0;
            std::vector<std::size_t> idx;
            {
              py::gil_scoped_release release;
              idx = MixingLineSlopeSample(self, o, Dim(radiance, 0), radiance.data(),
                                          background.data(), &candidates);
            }
            py::array_t<std::int64_t> out(idx.size());
            for (std::size_t j = 0; j < idx.size(); ++j)
              out.mutable_data()[j] = static_cast<std::int64_t>(idx[j]);
            return py::make_tuple(out, candidates);
          },
          py::arg("radiance"), py::arg("background_radiance"), py::arg("netd_K"),
          py::arg("min_snr") = 10.0, py::arg("max_samples") = 3000, py::arg("seed") = 0,
          "(indices, num_candidates): the pixel-frames the slope search solves "
          "(MixingLineSlopeSample).");

  m.def(
      "mixing_line_slope_from_profile",
      [](std::vector<double> grid, const DoubleArray& chi2, double chi2_cap) {
        CheckNdim(chi2, 2, "chi2");
        if (Dim(chi2, 0) != grid.size())
          throw std::invalid_argument("chi2 needs one row per grid value (" +
                                      std::to_string(grid.size()) + "); got " + Shape(chi2));
        return SlopeDict(MixingLineSlopeFromProfile(grid, Dim(chi2, 1), chi2.data(), chi2_cap));
      },
      py::arg("grid_K_per_fraction"), py::arg("chi2"), py::arg("chi2_cap") = 50.0,
      "k and its 1-sigma from chi2 (K grid values, P pixels): MixingLineSlopeFromProfile.");
}

}  // namespace
}  // namespace qogi
