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

void BindMixingLineSlope(py::module_& m);  // at the end of this file

}  // namespace

void BindInversion(py::module_& m) {
  // --- scene tables ----------------------------------------------------------
  using S = SceneTableOptions;
  BindOptions<S>(
      m, "SceneTableOptions",
      "Settings of the per-scene table (see engine/inversion/scene_table.h).", Args::kPositional,
      Field("ambient_temperature_K", &S::ambient_temperature_K,
            "T_amb of the scene [K], inside the model's tables (default 296)"),
      Field("min_peak_temperature_K", &S::min_peak_temperature_K,
            "lowest T_peak tabulated [K]; 0 = the model's lowest (default 0)"),
      Field("max_peak_temperature_K", &S::max_peak_temperature_K,
            "highest T_peak tabulated [K]; 0 = the model's highest (default 0)"),
      Field("temperature_step_K", &S::temperature_step_K,
            "T_peak grid step [K], within [1, 50] (default 5)"),
      Field("max_sigma_m", &S::max_sigma_m, "largest plume depth sigma served [m] (default 2)"),
      Field("nodes_per_decade", &S::nodes_per_decade,
            "grid density in u = x sigma [nodes per factor 10], 2-40 (default 8)"),
      Field("fraction_nodes", &S::fraction_nodes,
            "self-broadening grid over x in [0, 1], 4-21 (default 4)"),
      Field("thin_optical_depth", &S::thin_optical_depth,
            "strongest bin's peak optical depth at the smallest u, 1e-8-1e-3 (default 1e-5)"),
      Field("min_background_K", &S::min_background_K,
            "lowest background temperature served [K], >= 50 (default 150)"),
      Field("max_background_K", &S::max_background_K,
            "highest background temperature served [K], <= 2000 (default 700)"),
      Field("planck_tolerance", &S::planck_tolerance,
            "relative truncation of the background Planck basis, 1e-14-1e-4 (default 1e-8)"),
      Field("num_threads", &S::num_threads, "build threads; 0 = all cores (default 0)"),
      Field("num_nodes", &S::num_nodes,
            "line-of-sight nodes of the table's march, odd >= 5; 0 = the model's (default 0)"),
      Field("negligible_fraction", &S::negligible_fraction,
            "bins whose largest contrasts stay below this fraction of the band radiance "
            "are left out, [0, 1e-3] (default 1e-6)"),
      Field("linear_optical_depth", &S::linear_optical_depth,
            "bins optically thinner than this are scaled, not marched, [1e-9, 1e-3] "
            "(default 1e-4)"));

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
             bool signed_below_detection, int max_iterations, int num_threads,
             int line_nodes_per_unit, py::object progress) {
            const std::size_t nc = self.table().num_channels();
            CheckNdim(radiance, 2, "radiance");
            const std::size_t n = Dim(radiance, 0);
            if (Dim(radiance, 1) != nc || background.ndim() != 2 || Dim(background, 0) != n ||
                Dim(background, 1) != nc || static_cast<std::size_t>(sigma.size()) != n)
              throw std::invalid_argument("invert needs radiance and background_radiance (N, " +
                                          std::to_string(nc) + ") and sigma_m (N,); got " +
                                          ShapeOf(radiance) + ", " + ShapeOf(background) + ", " +
                                          ShapeOf(sigma));
            MixingLineOptions o;
            o.slope_K_per_fraction = slope;
            o.composition = std::move(composition);
            o.netd_K = std::move(netd);
            o.detection_sigma = detection_sigma;
            o.signed_below_detection = signed_below_detection;
            o.max_iterations = max_iterations;
            o.num_threads = num_threads;
            o.line_nodes_per_unit = line_nodes_per_unit;
            OutputArrays res;
            MixingLineOutput out{res.New<double>("fraction", {n}),
                                 res.New<double>("fraction_sigma", {n}),
                                 res.New<double>("peak_temperature_K", {n}),
                                 res.New<double>("chi2", {n}),
                                 res.New<std::int32_t>("status", {n}),
                                 res.New<std::int32_t>("iterations", {n})};
            RunControl control = MakeRunControl(progress);
            {
              py::gil_scoped_release release;
              self.Invert(o, n, radiance.data(), background.data(), sigma.data(), out, &control);
            }
            return res.dict();
          },
          py::arg("radiance"), py::arg("background_radiance"), py::arg("sigma_m"),
          py::arg("slope_K_per_fraction"), py::arg("composition"), py::arg("netd_K"),
          py::arg("detection_sigma") = 3.0, py::arg("signed_below_detection") = false,
          py::arg("max_iterations") = 50, py::arg("num_threads") = 0,
          py::arg("line_nodes_per_unit") = 16, py::arg("progress") = py::none(),
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
      .def_property_readonly("options", &SceneTable::options, py::return_value_policy::copy)
      .def_property_readonly("build_seconds", &SceneTable::build_seconds)
      .def_property_readonly("memory_bytes", &SceneTable::memory_bytes)
      .def_property_readonly("num_tabulated_bins", &SceneTable::num_tabulated_bins)
      .def_property_readonly("negligible_bound", &SceneTable::negligible_bound,
                             "Bound on the left-out bins' contribution to a contrast [W/(m2 sr)].")
      .def_property_readonly("min_peak_temperature_K", &SceneTable::min_peak_temperature_K)
      .def_property_readonly("max_peak_temperature_K", &SceneTable::max_peak_temperature_K)
      .def_property_readonly("min_column_proxy_m", &SceneTable::min_column_proxy_m)
      .def_property_readonly("max_column_proxy_m", &SceneTable::max_column_proxy_m)
      .def_property_readonly("grid_shape",
                             [](const SceneTable& t) {
                               return py::make_tuple(t.num_u_nodes(), t.num_fraction_nodes(),
                                                     t.num_temperature_nodes());
                             })
      .def("has_table", &SceneTable::has_table, py::arg("channel"), py::arg("species"))
      .def("basis_rank", &SceneTable::basis_rank, py::arg("channel"), py::arg("species"))
      .def(
          "contrast",
          [](const SceneTable& t, const DoubleArray& x, const DoubleArray& tp,
             const DoubleArray& sigma, const DoubleArray& tbg) {
            const std::size_t nc = t.num_channels(), ns = t.num_species(), np = ns + 2;
            CheckNdim(x, 2, "peak_fractions");
            CheckNdim(tbg, 2, "background_temperature_K");
            const std::size_t n = Dim(x, 0);
            if (Dim(x, 1) != ns || static_cast<std::size_t>(tp.size()) != n ||
                static_cast<std::size_t>(sigma.size()) != n || Dim(tbg, 0) != n ||
                Dim(tbg, 1) != nc)
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
      .def(
          "export",
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
            d["psi_coefficients"] =
                py::array_t<double>({psi.size() / static_cast<std::size_t>(std::max(1, r1 - 1)),
                                     static_cast<std::size_t>(r1 - 1)},
                                    psi.data());
            return d;
          },
          py::arg("channel"), py::arg("species"));

  m.def(
      "measure_table_error",
      [](const SceneTable& t, int n, unsigned seed, double floor_fraction, bool jac) {
        TableErrorReport r;
        {
          py::gil_scoped_release release;
          r = MeasureTableError(t, n, seed, floor_fraction, jac);
        }
        using R = TableErrorReport;
        return ToDict(r, Field("max_relative_error", &R::max_relative_error),
                      Field("rms_relative_error", &R::rms_relative_error),
                      Field("max_jacobian_error", &R::max_jacobian_error),
                      Field("num_samples", &R::num_samples));
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

  BindOptions<ParameterSpec>(
      m, "ParameterSpec", nullptr, Args::kPositional, Required(Field("mode", &ParameterSpec::mode)),
      Field("value", &ParameterSpec::value,
            "fixed value, prior mean, start value when free, or the ratio when tied"),
      Field("prior_sigma", &ParameterSpec::prior_sigma,
            "1-sigma width of the prior (prior; > 0), same unit"),
      Field("lower", &ParameterSpec::lower, "lower bound (same unit)"),
      Field("upper", &ParameterSpec::upper, "upper bound (> lower)"),
      Field("tied_to", &ParameterSpec::tied_to,
            "tied: index of the (estimated) species this fraction follows"));

  using I = InversionOptions;
  BindOptions<I>(
      m, "InversionOptions", nullptr, Args::kPositional,
      Field("fractions", &I::fractions,
            "one ParameterSpec per species (peak volume fraction); empty: every species "
            "free in [0, 1], start 1e-3"),
      Field("temperature", &I::temperature,
            "T_peak [K]; default fixed at ambient (value 0 = ambient, bounds 0 = the table's)"),
      Field("sigma", &I::sigma, "Gaussian depth sigma [m]; default fixed at 0.05 m"),
      Field("netd_K", &I::netd_K,
            "NETD per channel [K], one value = every channel "
            "(default [0.017])"),
      Field("detection_sigma", &I::detection_sigma,
            "below detection when |y_c| < detection_sigma x n_c in every channel (default 3)"),
      Field("signed_below_detection", &I::signed_below_detection,
            "below detection: the thin-limit least-squares column from the contrasts, signed "
            "(unbiased when summed over pixels), instead of 0 (default False)"),
      Field("model_error_fraction", &I::model_error_fraction,
            "relative model uncertainty per channel, in quadrature with the noise, [0, 1] "
            "(default 0)"),
      Field("max_iterations", &I::max_iterations,
            "solver iterations per solve, >= 1 "
            "(default 100)"),
      Field("tolerance_chi2", &I::tolerance_chi2,
            "converged when a Gauss-Newton step would lower chi2 by less, [1e-12, 1] "
            "(default 0.01)"),
      Field("initial_guess", &I::initial_guess, "default table"),
      Field("temperature_candidates", &I::temperature_candidates,
            "starts only: T_peak candidates of the coarse lookup, 1-50 (default 5)"),
      Field("guess_iterations", &I::guess_iterations,
            "starts only: fraction refinements per candidate, 0-100 (default 3)"),
      Field("num_starts", &I::num_starts,
            "starts only: full solves from the best candidates, 0-50, 0 = all (default 0)"),
      Field("solver", &I::solver, "default auto"),
      Field("num_threads", &I::num_threads, "threads over pixels; 0 = all cores (default 0)"),
      Field("cold_start", &I::cold_start,
            "how a pixel without a warm start is solved when T_peak is free (default profile)"));

  m.def(
      "pixel_status_name",
      [](int s) { return std::string(PixelStatusName(static_cast<PixelStatus>(s))); },
      py::arg("status"));
  m.def(
      "gaussian_profile_integral",
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
      .def(
          "invert",
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
            DoubleArray bg =
                (bg_is_t ? background_temperature : background_radiance).cast<DoubleArray>();
            CheckNdim(bg, 3, "background (frames or 1, channels, pixels)");
            if (!((Dim(bg, 0) == 1 || Dim(bg, 0) == nf) && Dim(bg, 1) == nc && Dim(bg, 2) == n))
              throw std::invalid_argument("the background has shape " + ShapeOf(bg) +
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
            const std::string per_pixel = "one value per pixel (" + std::to_string(n) + ")";
            b.sigma_m = OptionalValues(sigma_m, n, "sigma_m", per_pixel, &sg);
            b.peak_temperature_K =
                OptionalValues(peak_temperature, n, "peak_temperature_K", per_pixel, &tp);
            b.initial = OptionalValues(initial, n * np, "initial",
                                       "(pixels, " + std::to_string(np) + ") values", &init);
            OutputArrays out;
            InversionOutput o;
            o.status = out.New<std::uint8_t>("status", {nf, n});
            o.bound_mask = out.New<std::uint8_t>("bound_mask", {nf, n});
            o.flags = out.New<std::uint8_t>("flags", {nf, n});
            o.parameters = out.New<double>("parameters", {nf, n, np});
            o.parameter_sigma = out.New<double>("parameter_sigma", {nf, n, np});
            o.covariance = out.New<double>("covariance", {nf, n, np, np});
            o.column_density = out.New<double>("column_density", {nf, n, ns});
            o.column_density_sigma = out.New<double>("column_density_sigma", {nf, n, ns});
            o.path_concentration = out.New<double>("path_concentration", {nf, n, ns});
            o.path_concentration_sigma = out.New<double>("path_concentration_sigma", {nf, n, ns});
            o.chi2 = out.New<double>("chi2", {nf, n});
            o.condition_number = out.New<double>("condition_number", {nf, n});
            o.iterations = out.New<std::int32_t>("iterations", {nf, n});
            RunControl control = MakeRunControl(progress);
            {
              py::gil_scoped_release release;
              inv.Invert(b, o, &control);
            }
            return out.dict();
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
  using R = MixingLineSlope;
  py::dict d =
      ToDict(r, Field("found", &R::found), Field("slope_K_per_fraction", &R::slope_K_per_fraction),
             Field("sigma_K_per_fraction", &R::sigma_K_per_fraction),
             Field("num_candidates", &R::num_candidates), Field("num_samples", &R::num_samples),
             Field("num_fitted", &R::num_fitted));
  d["grid_K_per_fraction"] =
      py::array_t<double>(r.grid_K_per_fraction.size(), r.grid_K_per_fraction.data());
  d["total_chi2"] = py::array_t<double>(r.total_chi2.size(), r.total_chi2.data());
  return d;
}

void CheckRows(const MixingLineInverter& self, const DoubleArray& radiance,
               const DoubleArray& background, const char* what) {
  const std::size_t nc = self.table().num_channels();
  if (radiance.ndim() != 2 || Dim(radiance, 1) != nc || background.ndim() != 2 ||
      Dim(background, 0) != Dim(radiance, 0) || Dim(background, 1) != nc)
    throw std::invalid_argument(std::string(what) + " needs radiance and background_radiance (N, " +
                                std::to_string(nc) + "); got " + ShapeOf(radiance) + ", " +
                                ShapeOf(background));
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
                                         ",); got " + ShapeOf(sigma));
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
                                      std::to_string(grid.size()) + "); got " + ShapeOf(chi2));
        return SlopeDict(MixingLineSlopeFromProfile(grid, Dim(chi2, 1), chi2.data(), chi2_cap));
      },
      py::arg("grid_K_per_fraction"), py::arg("chi2"), py::arg("chi2_cap") = 50.0,
      "k and its 1-sigma from chi2 (K grid values, P pixels): MixingLineSlopeFromProfile.");
}

}  // namespace
}  // namespace qogi
