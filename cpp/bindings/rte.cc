// Bindings of engine/rte: absorber tables, the exact and the fast forward
// models, Gaussian plumes and general paths. Glue only.

#include "common.h"
#include "engine/rte/binned_model.h"
#include "engine/rte/exact_model.h"
#include "engine/rte/hitran_tables.h"
#include "engine/rte/path.h"
#include "engine/rte/render.h"

namespace qogi {
namespace {

using Float2D = py::array_t<float, py::array::c_style | py::array::forcecast>;

std::vector<float> TableValues(const Float2D& a, std::size_t nt, std::size_t nnu,
                               const char* name) {
  if (a.ndim() != 2 || static_cast<std::size_t>(a.shape(0)) != nt ||
      static_cast<std::size_t>(a.shape(1)) != nnu)
    throw std::invalid_argument(std::string(name) +
                                " must have shape (n_temperatures, n_wavenumbers) = (" +
                                std::to_string(nt) + ", " + std::to_string(nnu) + ")");
  return std::vector<float>(a.data(), a.data() + a.size());
}

// Per-plume parameters as arrays of length N (fractions N x species).
struct PlumeBatch {
  std::size_t n = 0, ns = 0;
  const double *x = nullptr, *tp = nullptr, *ta = nullptr, *sigma = nullptr, *tbg = nullptr;
  std::size_t tbg_stride = 0;  // 1 (one per plume) or n_channels (per channel)
};

PlumeBatch MakeBatch(const DoubleArray& x, const DoubleArray& tp, const DoubleArray& ta,
                     const DoubleArray& sigma, const DoubleArray& tbg, std::size_t ns,
                     std::size_t nc) {
  CheckNdim(x, 2, "peak_fractions");
  PlumeBatch b;
  b.n = static_cast<std::size_t>(x.shape(0));
  b.ns = ns;
  if (static_cast<std::size_t>(x.shape(1)) != ns)
    throw std::invalid_argument("peak_fractions must have one column per species (" +
                                std::to_string(ns) + "); got " + std::to_string(x.shape(1)));
  for (const auto* a : {&tp, &ta, &sigma})
    if (static_cast<std::size_t>(a->size()) != b.n)
      throw std::invalid_argument(
          "peak_temperature_K, ambient_temperature_K and sigma_m need one value per plume (" +
          std::to_string(b.n) + ")");
  if (static_cast<std::size_t>(tbg.size()) == b.n)
    b.tbg_stride = 1;
  else if (static_cast<std::size_t>(tbg.size()) == b.n * nc)
    b.tbg_stride = nc;
  else
    throw std::invalid_argument("background_temperature_K needs one value per plume (" +
                                std::to_string(b.n) + ") or per plume and channel (" +
                                std::to_string(b.n * nc) + "); got " + std::to_string(tbg.size()));
  b.x = x.data();
  b.tp = tp.data();
  b.ta = ta.data();
  b.sigma = sigma.data();
  b.tbg = tbg.data();
  for (std::size_t i = 0; i < b.n; ++i) {
    GaussianPlume p;
    p.peak_fractions.assign(b.x + i * ns, b.x + (i + 1) * ns);
    p.peak_temperature_K = b.tp[i];
    p.ambient_temperature_K = b.ta[i];
    p.sigma_m = b.sigma[i];
    p.Check();
  }
  return b;
}

std::vector<double> BackgroundOf(const PlumeBatch& b, std::size_t i, std::size_t nc) {
  if (b.tbg_stride == 1) return std::vector<double>(nc, b.tbg[i]);
  return std::vector<double>(b.tbg + i * nc, b.tbg + (i + 1) * nc);
}

Path MakePath(const DoubleArray& position, const DoubleArray& temperature,
              const DoubleArray& fractions, double pressure) {
  CheckNdim(fractions, 2, "fractions");
  Path p;
  p.num_species = static_cast<std::size_t>(fractions.shape(1));
  p.pressure_Pa = pressure;
  p.position_m = ToVector(position, "position_m");
  p.temperature_K = ToVector(temperature, "temperature_K");
  p.fraction = FlatVector(fractions);
  if (static_cast<std::size_t>(fractions.shape(0)) != p.position_m.size())
    throw std::invalid_argument("fractions must have one row per node");
  return p;
}

// A forward model's class with what both models share: the constructor
// (channels, tables, options; built with the GIL released) and the
// properties species, molar_masses, num_channels and the temperature range.
template <typename Model, typename Options>
py::class_<Model> BindForwardModel(py::module_& m, const char* name) {
  py::class_<Model> cls(m, name);
  cls.def(py::init([](std::vector<SpectralResponse> ch, std::vector<AbsorberTable> tabs,
                      const Options& o) {
            py::gil_scoped_release release;
            return Model(std::move(ch), std::move(tabs), o);
          }),
          py::arg("channels"), py::arg("tables"), py::arg("options") = Options())
      .def_property_readonly("species", &Model::species)
      .def_property_readonly("molar_masses", &Model::molar_masses)
      .def_property_readonly("num_channels", &Model::num_channels)
      .def_property_readonly("min_temperature_K", &Model::min_temperature_K)
      .def_property_readonly("max_temperature_K", &Model::max_temperature_K);
  return cls;
}

}  // namespace

void BindRte(py::module_& m) {
  m.def("molar_mass", &MolarMass, py::arg("species"),
        "Standard molar mass [kg/mol] of a species with natural isotopic composition.");

  py::class_<AbsorberTable>(m, "AbsorberTable",
                            "Cross-section table of one species as the forward models read it.")
      .def(py::init([](std::string species, double pressure, double nu0, double dnu,
                       const DoubleArray& temps, const Float2D& air, py::object self_tab,
                       double molar_mass) {
             AbsorberTable t;
             t.species = std::move(species);
             t.pressure_Pa = pressure;
             t.nu0_cm1 = nu0;
             t.dnu_cm1 = dnu;
             t.temperatures_K = ToVector(temps, "temperatures_K");
             if (air.ndim() != 2) throw std::invalid_argument("sigma_air must be 2-D (n_T, n_nu)");
             t.n_nu = static_cast<std::size_t>(air.shape(1));
             t.sigma_air = TableValues(air, t.temperatures_K.size(), t.n_nu, "sigma_air");
             if (!self_tab.is_none())
               t.sigma_self = TableValues(self_tab.cast<Float2D>(), t.temperatures_K.size(), t.n_nu,
                                          "sigma_self");
             t.molar_mass_kg_mol = molar_mass;
             t.Check();
             return t;
           }),
           py::arg("species"), py::arg("pressure_Pa"), py::arg("nu0_cm1"), py::arg("dnu_cm1"),
           py::arg("temperatures_K"), py::arg("sigma_air"), py::arg("sigma_self") = py::none(),
           py::arg("molar_mass_kg_mol") = 0.0)
      .def_readonly("species", &AbsorberTable::species)
      .def_readonly("pressure_Pa", &AbsorberTable::pressure_Pa)
      .def_readonly("nu0_cm1", &AbsorberTable::nu0_cm1)
      .def_readonly("dnu_cm1", &AbsorberTable::dnu_cm1)
      .def_readonly("n_nu", &AbsorberTable::n_nu)
      .def_readonly("temperatures_K", &AbsorberTable::temperatures_K)
      .def_property_readonly("has_self", &AbsorberTable::has_self)
      .def_property_readonly("molar_mass_kg_mol", &AbsorberTable::molar_mass)
      .def_property_readonly(
          "sigma_air",
          [](const AbsorberTable& t) {
            return ToArray<float>(t.sigma_air, {static_cast<py::ssize_t>(t.temperatures_K.size()),
                                                static_cast<py::ssize_t>(t.n_nu)});
          },
          "Cross-sections in air [cm2/molecule], (n_T, n_nu) float32 (a copy).")
      .def_property_readonly(
          "sigma_self",
          [](const AbsorberTable& t) -> py::object {
            if (!t.has_self()) return py::none();
            return ToArray<float>(t.sigma_self, {static_cast<py::ssize_t>(t.temperatures_K.size()),
                                                 static_cast<py::ssize_t>(t.n_nu)});
          },
          "Cross-sections of the pure gas [cm2/molecule], (n_T, n_nu) float32 (a copy), or "
          "None without self-broadening.");

  m.attr("TABLE_WING_CM1") = kTableWing_cm1;
  using TO = AbsorberTableOptions;
  BindOptions<TO>(
      m, "AbsorberTableOptions", "Settings of the forward models' HITRAN tables.",
      Args::kKeywordOnly,
      Field("pressure_Pa", &TO::pressure_Pa, "pressure of the tables [Pa], > 0 (default 101325)"),
      Field("temperatures_K", &TO::temperatures_K,
            "temperature grid [K], strictly increasing, >= 2 values (default 200-600 every 10)"),
      Field("step_cm1", &TO::step_cm1, "wavenumber step [cm-1], > 0 (default 0.01)"),
      Field("self_broadening", &TO::self_broadening, "also a table of the pure gas (default True)"),
      Field("wing_cm1", &TO::wing_cm1, "fixed line wing [cm-1], >= 0 (default 25)"),
      Field("wing_half_widths", &TO::wing_half_widths,
            "line wing in half-widths, >= 0 (default 0; HAPI's rule: 50 with wing_cm1 0)"),
      Field("num_threads", &TO::num_threads, "worker threads, 0 = all cores (default 0)"));

  m.def(
      "build_absorber_tables",
      [](const std::vector<std::string>& species, const std::vector<SpectralResponse>& channels,
         const py::dict& line_lists, const std::vector<std::string>& fallback,
         const AbsorberTableOptions& options, py::object make, py::object progress) {
        LineSources sources;
        sources.fallback = fallback;
        for (const auto& kv : line_lists) {
          const auto name = kv.first.cast<std::string>();
          if (py::isinstance<LineList>(kv.second))
            sources.lines[name] = kv.second.cast<const LineList&>();
          else
            sources.paths[name] = kv.second.cast<std::vector<std::string>>();
        }
        XsecTableMaker maker;
        if (!make.is_none())
          maker = [make](const std::string& sp, const LineList& lines, const WavenumberGrid& g,
                         const std::vector<double>& temps, double p, double x,
                         const CrossSectionOptions& o, const RunControl* c) {
            py::gil_scoped_acquire gil;
            py::object prog = py::none();
            if (c != nullptr && c->progress)
              prog = py::cpp_function([c](double f) { c->progress(f); });
            py::object t = make(sp, std::make_shared<LineList>(lines), g.nu0_cm1, g.step_cm1,
                                g.size, temps, p, x, o, prog);
            return XsecTable(*t.cast<std::shared_ptr<XsecTable>>());
          };
        const RunControl control = MakeRunControl(progress);
        py::gil_scoped_release release;
        return BuildAbsorberTables(species, channels, sources, options, &control, maker);
      },
      py::arg("species"), py::arg("channels"), py::arg("line_lists"), py::arg("fallback"),
      py::arg("options"), py::arg("make") = py::none(), py::arg("progress") = py::none(),
      R"doc(The forward models' tables of `species` from HITRAN lines (BuildAbsorberTables).

line_lists: {species: list of files/folders, or LineList}; fallback: folders searched
after those and $QOGI_HITRAN_PATH. make(species, lines, nu0_cm1, step_cm1, size,
temperatures_K, pressure_Pa, self_fraction, options, progress) -> XsecTable, optional:
builds (or fetches) one table; default XsecTable.build. progress(fraction) -> bool|None.)doc");

  BindOptions<ExactModelOptions>(
      m, "ExactModelOptions", nullptr, Args::kPositional,
      Field("num_nodes", &ExactModelOptions::num_nodes,
            "line-of-sight nodes of a Gaussian plume, >= 3, odd keeps the centre (default 401)"),
      Field("z_max", &ExactModelOptions::z_max,
            "the plume is sampled over [-z_max, z_max] sigma (default 6.5)"),
      Field("richardson", &ExactModelOptions::richardson,
            "Richardson-extrapolate the march on all and on every other node (default True)"),
      Field("num_threads", &ExactModelOptions::num_threads, "0 = all cores (default 0)"));

  using B = BinnedModelOptions;
  BindOptions<B>(
      m, "BinnedModelOptions", nullptr, Args::kPositional,
      Field("bin_ratio", &B::bin_ratio,
            "max ratio of cross-sections within a bin at each key temperature, > 1 "
            "(default 1.5)"),
      Field("key_temperatures_K", &B::key_temperatures_K,
            "binning temperatures [K], within the tables (default [250, 350, 500])"),
      Field("floor_fraction", &B::floor_fraction,
            "cross-sections below this fraction of a species' maximum count as zero "
            "(default 1e-8)"),
      Field("chebyshev_nodes", &B::chebyshev_nodes,
            "Planck interpolation nodes per segment, 4-32 (default 12)"),
      Field("segment_width_cm1", &B::segment_width_cm1,
            "max width of a Chebyshev segment [cm-1] (default 300)"),
      Field("num_nodes", &B::num_nodes,
            "line-of-sight nodes of a Gaussian plume, >= 3, odd for Richardson (default 129)"),
      Field("z_max", &B::z_max, "the plume is sampled over [-z_max, z_max] sigma (default 5.5)"),
      Field("richardson", &B::richardson,
            "Richardson-extrapolate the march on all and on every other node (default True)"),
      Field("self_key", &B::self_key,
            "also bin by the self-broadened cross-section (default False)"));

  BindOptions<AtmosphericPath>(
      m, "AtmosphericPath", nullptr, Args::kPositional,
      Field("distance_m", &AtmosphericPath::distance_m,
            "path length [m]; 0 = no atmosphere (default 0)"),
      Field("temperature_K", &AtmosphericPath::temperature_K,
            "air temperature [K] (default 288.15)"),
      Field("relative_humidity", &AtmosphericPath::relative_humidity,
            "[0, 1]; H2O from the saturation pressure, needs an H2O table (default 0.5)"),
      Field("co2_ppm", &AtmosphericPath::co2_ppm,
            "ambient CO2 [ppm], used if the model has a CO2 table (default 420)"),
      Field("ch4_ppm", &AtmosphericPath::ch4_ppm,
            "ambient CH4 [ppm], used if the model has a CH4 table (default 1.9)"));

  m.def("saturation_vapor_pressure", &SaturationVaporPressure, py::arg("temperature_K"));

  m.def(
      "gaussian_column_density",
      [](std::vector<double> x, double tp, double ta, double sigma, double p,
         std::vector<double> masses) {
        GaussianPlume g;
        g.peak_fractions = std::move(x);
        g.peak_temperature_K = tp;
        g.ambient_temperature_K = ta;
        g.sigma_m = sigma;
        g.pressure_Pa = p;
        return GaussianColumnDensity(g, masses);
      },
      py::arg("peak_fractions"), py::arg("peak_temperature_K"), py::arg("ambient_temperature_K"),
      py::arg("sigma_m"), py::arg("pressure_Pa"), py::arg("molar_masses_kg_mol"));

  BindForwardModel<ExactModel, ExactModelOptions>(m, "ExactModel")
      .def(
          "band_radiance",
          [](const ExactModel& mdl, const DoubleArray& x, const DoubleArray& tp,
             const DoubleArray& ta, const DoubleArray& sigma, const DoubleArray& tbg,
             double pressure, const AtmosphericPath& atm, py::object progress) {
            const std::size_t nc = mdl.num_channels();
            const PlumeBatch b = MakeBatch(x, tp, ta, sigma, tbg, mdl.num_species(), nc);
            py::array_t<double> out({b.n, nc});
            double* o = out.mutable_data();
            RunControl control = MakeRunControl(progress);
            {
              py::gil_scoped_release release;
              for (std::size_t i = 0; i < b.n; ++i) {
                GaussianPlume g;
                g.peak_fractions.assign(b.x + i * b.ns, b.x + (i + 1) * b.ns);
                g.peak_temperature_K = b.tp[i];
                g.ambient_temperature_K = b.ta[i];
                g.sigma_m = b.sigma[i];
                g.pressure_Pa = pressure;
                const auto l = mdl.BandRadiance(g, BackgroundOf(b, i, nc), atm, &control);
                std::copy(l.begin(), l.end(), o + i * nc);
                if (control.progress) {
                  py::gil_scoped_acquire gil;
                  control.progress(static_cast<double>(i + 1) / b.n);
                }
              }
            }
            return out;
          },
          py::arg("peak_fractions"), py::arg("peak_temperature_K"),
          py::arg("ambient_temperature_K"), py::arg("sigma_m"), py::arg("background_temperature_K"),
          py::arg("pressure_Pa"), py::arg("atmosphere") = AtmosphericPath(),
          py::arg("progress") = py::none())
      .def(
          "band_radiance_path",
          [](const ExactModel& mdl, const DoubleArray& pos, const DoubleArray& temp,
             const DoubleArray& fr, double pressure, std::vector<double> tbg,
             const AtmosphericPath& atm) {
            const Path p = MakePath(pos, temp, fr, pressure);
            py::gil_scoped_release release;
            return mdl.BandRadiance(p, tbg, atm);
          },
          py::arg("position_m"), py::arg("temperature_K"), py::arg("fractions"),
          py::arg("pressure_Pa"), py::arg("background_temperature_K"),
          py::arg("atmosphere") = AtmosphericPath())
      .def(
          "spectral_contrast",
          [](const ExactModel& mdl, std::size_t channel, const DoubleArray& pos,
             const DoubleArray& temp, const DoubleArray& fr, double pressure, double tbg) {
            const Path p = MakePath(pos, temp, fr, pressure);
            std::vector<double> nu, dl;
            {
              py::gil_scoped_release release;
              mdl.SpectralContrast(channel, p, tbg, &nu, &dl);
            }
            return py::make_tuple(ToArray(nu), ToArray(dl));
          },
          py::arg("channel"), py::arg("position_m"), py::arg("temperature_K"), py::arg("fractions"),
          py::arg("pressure_Pa"), py::arg("background_temperature_K"))
      .def(
          "gaussian_path",
          [](const ExactModel& mdl, std::vector<double> x, double tp, double ta, double sigma,
             double pressure) {
            GaussianPlume g;
            g.peak_fractions = std::move(x);
            g.peak_temperature_K = tp;
            g.ambient_temperature_K = ta;
            g.sigma_m = sigma;
            g.pressure_Pa = pressure;
            const Path p = mdl.GaussianPath(g);
            py::array_t<double> fr({p.size(), p.num_species});
            std::copy(p.fraction.begin(), p.fraction.end(), fr.mutable_data());
            return py::make_tuple(ToArray(p.position_m), ToArray(p.temperature_K), fr);
          },
          py::arg("peak_fractions"), py::arg("peak_temperature_K"),
          py::arg("ambient_temperature_K"), py::arg("sigma_m"), py::arg("pressure_Pa"));

  BindForwardModel<BinnedModel, BinnedModelOptions>(m, "BinnedModel")
      .def_property_readonly("pressure_Pa", &BinnedModel::pressure_Pa)
      .def_property_readonly("planck_interpolation_error", &BinnedModel::planck_interpolation_error)
      .def("num_bins", &BinnedModel::num_bins, py::arg("channel"))
      .def_property_readonly("options", &BinnedModel::options, py::return_value_policy::copy)
      .def(
          "band_radiance",
          [](const BinnedModel& mdl, const DoubleArray& x, const DoubleArray& tp,
             const DoubleArray& ta, const DoubleArray& sigma, const DoubleArray& tbg,
             int num_threads, py::object progress) {
            const std::size_t nc = mdl.num_channels();
            const PlumeBatch b = MakeBatch(x, tp, ta, sigma, tbg, mdl.num_species(), nc);
            for (std::size_t i = 0; i < b.n; ++i) {
              const double lo = std::min(b.tp[i], b.ta[i]), hi = std::max(b.tp[i], b.ta[i]);
              if (lo < mdl.min_temperature_K() - 1e-9 || hi > mdl.max_temperature_K() + 1e-9)
                throw std::invalid_argument("plume " + std::to_string(i) + " has temperatures " +
                                            FormatNumber(lo) + "-" + FormatNumber(hi) +
                                            " K outside the tables' range [" +
                                            FormatNumber(mdl.min_temperature_K()) + ", " +
                                            FormatNumber(mdl.max_temperature_K()) + "] K");
            }
            py::array_t<double> out({b.n, nc});
            double* o = out.mutable_data();
            RunControl control = MakeRunControl(progress);
            {
              py::gil_scoped_release release;
              ParallelFor(
                  b.n, 16,
                  [&](std::size_t lo, std::size_t hi) {
                    for (std::size_t i = lo; i < hi; ++i) {
                      const Path p =
                          mdl.GaussianPath<double>(b.x + i * b.ns, b.tp[i], b.ta[i], b.sigma[i]);
                      const std::vector<double> t = BackgroundOf(b, i, nc);
                      mdl.Contrast<double>(p, t.data(), o + i * nc);
                      for (std::size_t c = 0; c < nc; ++c)
                        o[i * nc + c] += mdl.channels()[c].BandRadiance(t[c]);
                    }
                  },
                  num_threads, &control);
            }
            return out;
          },
          py::arg("peak_fractions"), py::arg("peak_temperature_K"),
          py::arg("ambient_temperature_K"), py::arg("sigma_m"), py::arg("background_temperature_K"),
          py::arg("num_threads") = 0, py::arg("progress") = py::none())
      .def(
          "band_radiance_path",
          [](const BinnedModel& mdl, const DoubleArray& pos, const DoubleArray& temp,
             const DoubleArray& fr, double pressure, std::vector<double> tbg) {
            const Path p = MakePath(pos, temp, fr, pressure);
            py::gil_scoped_release release;
            return mdl.BandRadiance(p, tbg);
          },
          py::arg("position_m"), py::arg("temperature_K"), py::arg("fractions"),
          py::arg("pressure_Pa"), py::arg("background_temperature_K"))
      .def(
          "bin_contrasts",
          [](const BinnedModel& mdl, const DoubleArray& pos, const DoubleArray& temp,
             const DoubleArray& fr, double pressure, std::size_t channel, double tbg) {
            const Path p = MakePath(pos, temp, fr, pressure);
            std::vector<double> out;
            {
              py::gil_scoped_release release;
              mdl.BinContrasts(p, channel, tbg, &out);
            }
            return ToArray(out);
          },
          py::arg("position_m"), py::arg("temperature_K"), py::arg("fractions"),
          py::arg("pressure_Pa"), py::arg("channel"), py::arg("background_temperature_K"),
          "Unweighted contrast of every bin of one channel [W/(m2 sr cm-1)].")
      .def(
          "weights",
          [](const BinnedModel& mdl, std::size_t c) {
            if (c >= mdl.num_channels()) throw std::invalid_argument("channel index out of range");
            return ToArray(mdl.weights(c));
          },
          py::arg("channel"), "Bin weights of a channel [cm-1].")
      .def("subset", &BinnedModel::Subset, py::arg("bins"), py::arg("weights"),
           py::call_guard<py::gil_scoped_release>())
      .def("use_fine_temperature_grid", &BinnedModel::UseFineTemperatureGrid, py::arg("t_lo"),
           py::arg("t_hi"), py::arg("step_K") = 1.0);

  m.def(
      "render_contrast",
      [](const BinnedModel& mdl,
         py::array_t<std::int64_t, py::array::c_style | py::array::forcecast> offset,
         py::array_t<float, py::array::c_style | py::array::forcecast> step,
         py::array_t<float, py::array::c_style | py::array::forcecast> temperature,
         std::vector<py::array_t<float, py::array::c_style | py::array::forcecast>> fractions,
         double t_amb, const DoubleArray& tbg, int num_threads, py::object progress) {
        RayBatch rays;
        rays.num_rays = static_cast<std::size_t>(offset.size()) - 1;
        if (offset.size() < 1 || static_cast<std::size_t>(step.size()) != rays.num_rays)
          throw std::invalid_argument("offset needs num_rays + 1 values and step_m num_rays");
        const std::int64_t ns_total = offset.data()[rays.num_rays];
        if (temperature.size() < ns_total)
          throw std::invalid_argument("temperature_K has fewer values than the offsets address");
        rays.offset = offset.data();
        rays.step_m = step.data();
        rays.temperature_K = temperature.data();
        for (auto& f : fractions) {
          if (f.size() < ns_total)
            throw std::invalid_argument(
                "a fractions array has fewer values than the offsets address");
          rays.fraction.push_back(f.data());
        }
        const std::size_t nc = mdl.num_channels();
        std::size_t stride;
        if (static_cast<std::size_t>(tbg.size()) == nc)
          stride = 0;
        else if (static_cast<std::size_t>(tbg.size()) == nc * rays.num_rays)
          stride = nc;
        else
          throw std::invalid_argument(
              "background_temperature_K needs one value per channel or per ray and channel");
        py::array_t<float> out({rays.num_rays, nc});
        float* o = out.mutable_data();
        const double* tb = tbg.data();
        RunControl control = MakeRunControl(progress);
        {
          py::gil_scoped_release release;
          RenderContrast(mdl, rays, t_amb, tb, stride, o, num_threads, &control);
        }
        return out;
      },
      py::arg("model"), py::arg("offset"), py::arg("step_m"), py::arg("temperature_K"),
      py::arg("fractions"), py::arg("ambient_temperature_K"), py::arg("background_temperature_K"),
      py::arg("num_threads") = 0, py::arg("progress") = py::none(),
      "Contrast [W/(m2 sr)] of many rays (samples background -> camera), (rays, channels).");
}

}  // namespace qogi
