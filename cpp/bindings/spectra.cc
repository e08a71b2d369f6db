// Bindings of engine/spectra: isotopologues and partition sums, line lists,
// line parameters, the Voigt profile, cross-sections and sigma(nu, T) tables.
#include <limits>
#include <memory>

#include "common.h"
#include "engine/spectra/cross_section.h"
#include "engine/spectra/isotopologue.h"
#include "engine/spectra/line_list.h"
#include "engine/spectra/line_parameters.h"
#include "engine/spectra/line_sources.h"
#include "engine/spectra/voigt.h"
#include "engine/spectra/xsec_table.h"

namespace qogi {
namespace {

LineSelection MakeSelection(double nu_min, double nu_max, int molecule,
                            std::vector<int> isotopologues, double min_intensity) {
  LineSelection s;
  s.nu_min_cm1 = nu_min;
  s.nu_max_cm1 = nu_max;
  s.molecule = molecule;
  s.isotopologues = std::move(isotopologues);
  s.min_intensity = min_intensity;
  s.Check();
  return s;
}

WavenumberGrid MakeGrid(double nu0, double step, std::size_t n) {
  WavenumberGrid g{nu0, step, n};
  g.Check();
  return g;
}

}  // namespace

void BindSpectra(py::module_& m) {
  // --- molecules, isotopologues, partition sums ---------------------------
  m.def("molecule_id", &MoleculeId, py::arg("formula"),
        "HITRAN molecule code of a formula ('CH4' -> 6), case-insensitive.");
  m.def("molecule_formula", &MoleculeFormula, py::arg("molecule"),
        "Formula of a HITRAN molecule code (6 -> 'CH4').");
  m.def(
      "isotopologues",
      [] {
        using I = Isotopologue;
        py::list out;
        for (const I& i : Isotopologues())
          out.append(ToDict(i, Field("molecule", &I::molecule), Field("local_id", &I::local_id),
                            Field("global_id", &I::global_id), Field("formula", &I::formula),
                            Field("abundance", &I::abundance),
                            Field("molar_mass_g_mol", &I::molar_mass_g_mol),
                            Field("q_ref", &I::q_ref), Field("t_min_K", &I::t_min_K),
                            Field("t_max_K", &I::t_max_K)));
        return out;
      },
      "Isotopologues with shipped data (HITRAN masses and abundances, TIPS-2025 Q).");
  m.def(
      "partition_sum",
      [](int molecule, int local_id, const DoubleArray& t) {
        CheckNdim(t, 1, "temperature_K");
        py::array_t<double> out(t.size());
        for (py::ssize_t i = 0; i < t.size(); ++i)
          out.mutable_data()[i] = PartitionSum(molecule, local_id, t.data()[i]);
        return out;
      },
      py::arg("molecule"), py::arg("local_id"), py::arg("temperature_K"),
      "TIPS-2025 total internal partition sum Q(T) over a 1-D array of temperatures.");

  // --- line lists ---------------------------------------------------------
  py::class_<LineList, std::shared_ptr<LineList>>(m, "LineList", R"doc(
HITRAN lines as parallel arrays, one entry per transition, sorted by wavenumber.

Usually made by qogi.load_line_list; built from arrays for synthetic lines.

Parameters
----------
molecule, isotopologue : array of int
    HITRAN molecule code (6 = CH4) and local isotopologue number (1 = most abundant).
nu_cm1 : array, cm-1
    Transition wavenumbers (> 0).
intensity : array, cm/molecule
    Line intensity S at 296 K, natural abundance included (>= 0).
gamma_air, gamma_self : array, cm-1/atm
    Air- and self-broadened Lorentz HWHM at 296 K (>= 0).
elower_cm1 : array, cm-1
    Lower-state energy E''.
n_air : array
    Temperature exponent of gamma_air.
delta_air : array, cm-1/atm
    Air pressure shift at 296 K.
n_self, delta_self : array, optional
    Self exponent and shift; default n_air and delta_air.
einstein_a : array, 1/s, optional
    Einstein A coefficients (not used by the cross-section); default 0.

Attributes
----------
The same names as read-only arrays (copies), plus ``sources`` (files, in
priority order) and ``coverage`` ((molecule, isotopologue, nu_min_cm1,
nu_max_cm1, source index) spans used when merging files).
)doc")
      .def(
          py::init([](const IntArray& molecule, const IntArray& isotopologue, const DoubleArray& nu,
                      const DoubleArray& intensity, const DoubleArray& gamma_air,
                      const DoubleArray& gamma_self, const DoubleArray& elower,
                      const DoubleArray& n_air, const DoubleArray& delta_air, py::object n_self,
                      py::object delta_self, py::object einstein_a) {
            auto l = std::make_shared<LineList>();
            l->molecule = ToVector<int>(molecule, "molecule");
            l->isotopologue = ToVector<int>(isotopologue, "isotopologue");
            l->nu_cm1 = ToVector<double>(nu, "nu_cm1");
            l->intensity = ToVector<double>(intensity, "intensity");
            l->gamma_air = ToVector<double>(gamma_air, "gamma_air");
            l->gamma_self = ToVector<double>(gamma_self, "gamma_self");
            l->elower_cm1 = ToVector<double>(elower, "elower_cm1");
            l->n_air = ToVector<double>(n_air, "n_air");
            l->delta_air = ToVector<double>(delta_air, "delta_air");
            l->n_self = n_self.is_none() ? l->n_air
                                         : ToVector<double>(n_self.cast<DoubleArray>(), "n_self");
            l->delta_self = delta_self.is_none()
                                ? l->delta_air
                                : ToVector<double>(delta_self.cast<DoubleArray>(), "delta_self");
            l->einstein_a = einstein_a.is_none()
                                ? std::vector<double>(l->nu_cm1.size(), 0.0)
                                : ToVector<double>(einstein_a.cast<DoubleArray>(), "einstein_a");
            l->Check();
            l->SortByWavenumber();
            l->ComputeCoverage();
            l->sources = {"<memory>"};
            return l;
          }),
          py::arg("molecule"), py::arg("isotopologue"), py::arg("nu_cm1"), py::arg("intensity"),
          py::arg("gamma_air"), py::arg("gamma_self"), py::arg("elower_cm1"), py::arg("n_air"),
          py::arg("delta_air"), py::arg("n_self") = py::none(), py::arg("delta_self") = py::none(),
          py::arg("einstein_a") = py::none())
      .def("__len__", &LineList::size)
      .def_property_readonly("molecule", [](const LineList& l) { return ToArray(l.molecule); })
      .def_property_readonly("isotopologue",
                             [](const LineList& l) { return ToArray(l.isotopologue); })
      .def_property_readonly("nu_cm1", [](const LineList& l) { return ToArray(l.nu_cm1); })
      .def_property_readonly("intensity", [](const LineList& l) { return ToArray(l.intensity); })
      .def_property_readonly("einstein_a", [](const LineList& l) { return ToArray(l.einstein_a); })
      .def_property_readonly("gamma_air", [](const LineList& l) { return ToArray(l.gamma_air); })
      .def_property_readonly("gamma_self", [](const LineList& l) { return ToArray(l.gamma_self); })
      .def_property_readonly("elower_cm1", [](const LineList& l) { return ToArray(l.elower_cm1); })
      .def_property_readonly("n_air", [](const LineList& l) { return ToArray(l.n_air); })
      .def_property_readonly("n_self", [](const LineList& l) { return ToArray(l.n_self); })
      .def_property_readonly("delta_air", [](const LineList& l) { return ToArray(l.delta_air); })
      .def_property_readonly("delta_self", [](const LineList& l) { return ToArray(l.delta_self); })
      .def_property_readonly("sources", [](const LineList& l) { return l.sources; })
      .def_property_readonly(
          "coverage",
          [](const LineList& l) {
            py::list out;
            for (const LineCoverage& c : l.coverage)
              out.append(
                  py::make_tuple(c.molecule, c.isotopologue, c.nu_min_cm1, c.nu_max_cm1, c.source));
            return out;
          },
          "(molecule, isotopologue, nu_min_cm1, nu_max_cm1, source index) spans of the sources.")
      .def(
          "select",
          [](const LineList& l, double nu_min, double nu_max, int molecule, std::vector<int> isos,
             double min_intensity) {
            return std::make_shared<LineList>(
                l.Select(MakeSelection(nu_min, nu_max, molecule, std::move(isos), min_intensity)));
          },
          py::arg("nu_min_cm1") = 0.0,
          py::arg("nu_max_cm1") = std::numeric_limits<double>::infinity(), py::arg("molecule") = 0,
          py::arg("isotopologues") = std::vector<int>(), py::arg("min_intensity") = 0.0);

  m.def(
      "read_line_files",
      [](const std::vector<std::string>& paths, double nu_min, double nu_max, int molecule,
         std::vector<int> isos, double min_intensity) {
        const LineSelection s =
            MakeSelection(nu_min, nu_max, molecule, std::move(isos), min_intensity);
        py::gil_scoped_release release;
        return std::make_shared<LineList>(ReadLineFiles(paths, s));
      },
      py::arg("paths"), py::arg("nu_min_cm1") = 0.0,
      py::arg("nu_max_cm1") = std::numeric_limits<double>::infinity(), py::arg("molecule") = 0,
      py::arg("isotopologues") = std::vector<int>(), py::arg("min_intensity") = 0.0,
      "Reads HITRAN .par / HAPI .data files (first = highest priority) and merges them.");
  m.def(
      "merge_line_lists",
      [](const std::vector<std::shared_ptr<LineList>>& lists) {
        std::vector<LineList> v;
        for (const auto& l : lists) v.push_back(*l);
        return std::make_shared<LineList>(MergeLineLists(v));
      },
      py::arg("lists"), "Merges line lists given in priority order (see MergeLineLists).");

  // --- where line lists come from --------------------------------------------
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const LineListNotFound& e) {
      PyErr_SetString(PyExc_FileNotFoundError, e.what());
    }
  });
  m.def("line_search_path", &LineSearchPath, py::arg("folders"), py::arg("fallback"),
        "Folders searched for line lists: `folders`, then $QOGI_HITRAN_PATH, then `fallback`.");
  m.def("find_line_files", &FindLineFiles, py::arg("species"), py::arg("paths"),
        py::arg("fallback"),
        "The line files of a species (FindLineFiles): named files as given, else the first "
        "folder of line_search_path(paths, fallback) holding any; FileNotFoundError naming "
        "the folders searched.");
  m.def(
      "read_molecule_lines",
      [](const std::vector<std::string>& files, int molecule) {
        py::gil_scoped_release release;
        return std::make_shared<LineList>(ReadMoleculeLines(files, molecule));
      },
      py::arg("files"), py::arg("molecule"),
      "The lines of one molecule (HITRAN code) from line files (first = highest priority); "
      "ValueError when they hold none.");

  // --- conditions and options ----------------------------------------------
  BindOptions<GasConditions>(m, "GasConditions", nullptr, Args::kPositional,
                             Field("temperature_K", &GasConditions::temperature_K,
                                   "gas temperature [K], > 0 (default 296)"),
                             Field("pressure_Pa", &GasConditions::pressure_Pa,
                                   "total pressure [Pa], >= 0 (default 101325)"),
                             Field("self_fraction", &GasConditions::self_fraction,
                                   "absorber mole fraction for broadening, [0, 1] (default 0)"));

  using X = CrossSectionOptions;
  BindOptions<X>(
      m, "CrossSectionOptions", nullptr, Args::kPositional,
      Field("wing_half_widths", &X::wing_half_widths,
            "wing half-width in units of max(gamma_L, gamma_D), >= 0 (default 50, HAPI's "
            "WavenumberWingHW)"),
      Field("wing_cm1", &X::wing_cm1,
            "minimum wing half-width [cm-1], >= 0 (default 0, HAPI's WavenumberWing)"),
      Field("line_shift", &X::line_shift,
            "apply the pressure shift of line centres (default True, HAPI's LineShift)"),
      Field("min_intensity", &X::min_intensity,
            "lines with S(T) below this are skipped [cm/molecule], >= 0 (default 0)"));

  m.def(
      "grid_from_range",
      [](double lo, double hi, double step) {
        const WavenumberGrid g = WavenumberGrid::FromRange(lo, hi, step);
        return py::make_tuple(g.nu0_cm1, g.step_cm1, g.size);
      },
      py::arg("nu_min_cm1"), py::arg("nu_max_cm1"), py::arg("step_cm1"),
      "HAPI's grid for a range and step: (nu0_cm1, step_cm1, size).");

  m.def(
      "line_parameters",
      [](const LineList& l, const GasConditions& c, bool shift) {
        const LineParameters p = ComputeLineParameters(l, c, shift);
        py::dict d;
        d["nu_cm1"] = ToArray(p.nu_cm1);
        d["center_cm1"] = ToArray(p.center_cm1);
        d["intensity"] = ToArray(p.intensity);
        d["gamma_lorentz"] = ToArray(p.gamma_lorentz);
        d["gamma_doppler"] = ToArray(p.gamma_doppler);
        return d;
      },
      py::arg("lines"), py::arg("conditions"), py::arg("line_shift") = true);

  m.def("number_density_cm3", &NumberDensity_cm3, py::arg("pressure_Pa"), py::arg("temperature_K"),
        "Ideal-gas number density [molecule/cm3].");

  // --- Voigt ------------------------------------------------------------
  m.def(
      "faddeeva",
      [](const DoubleArray& x, const DoubleArray& y) {
        CheckNdim(x, 1, "x");
        CheckNdim(y, 1, "y");
        CheckSameLength(x.size(), y.size(), "x", "y");
        py::array_t<std::complex<double>> out(x.size());
        for (py::ssize_t i = 0; i < x.size(); ++i)
          out.mutable_data()[i] = Faddeeva(x.data()[i], y.data()[i]);
        return out;
      },
      py::arg("x"), py::arg("y"), "w(x + iy) over equal-length 1-D arrays (y >= 0).");
  m.def(
      "voigt_profile",
      [](const DoubleArray& d, double gd, double gl) {
        CheckNdim(d, 1, "dnu_cm1");
        py::array_t<double> out(d.size());
        for (py::ssize_t i = 0; i < d.size(); ++i)
          out.mutable_data()[i] = VoigtProfile(d.data()[i], gd, gl);
        return out;
      },
      py::arg("dnu_cm1"), py::arg("gamma_doppler_cm1"), py::arg("gamma_lorentz_cm1"));

  // --- cross-sections -----------------------------------------------------
  m.def(
      "cross_section_uniform",
      [](const LineList& l, const GasConditions& c, double nu0, double step, std::size_t n,
         const CrossSectionOptions& o, int threads, py::object progress) {
        const WavenumberGrid g = MakeGrid(nu0, step, n);
        py::array_t<double> out(static_cast<py::ssize_t>(n));
        double* p = out.mutable_data();
        const RunControl control = MakeRunControl(progress);
        ComputeSettings s;
        s.num_threads = threads;
        {
          py::gil_scoped_release release;
          ComputeCrossSection(l, c, g, o, p, s, &control);
        }
        return out;
      },
      py::arg("lines"), py::arg("conditions"), py::arg("nu0_cm1"), py::arg("step_cm1"),
      py::arg("size"), py::arg("options"), py::arg("num_threads") = 0,
      py::arg("progress") = py::none(), "sigma [cm2/molecule] on nu0 + j step, j < size.");
  m.def(
      "cross_section_grid",
      [](const LineList& l, const GasConditions& c, const DoubleArray& nu,
         const CrossSectionOptions& o, int threads, py::object progress) {
        CheckNdim(nu, 1, "nu_cm1");
        const std::size_t n = static_cast<std::size_t>(nu.size());
        py::array_t<double> out(static_cast<py::ssize_t>(n));
        double* p = out.mutable_data();
        const double* x = nu.data();
        const RunControl control = MakeRunControl(progress);
        ComputeSettings s;
        s.num_threads = threads;
        {
          py::gil_scoped_release release;
          ComputeCrossSection(l, c, x, n, o, p, s, &control);
        }
        return out;
      },
      py::arg("lines"), py::arg("conditions"), py::arg("nu_cm1"), py::arg("options"),
      py::arg("num_threads") = 0, py::arg("progress") = py::none(),
      "sigma [cm2/molecule] at strictly increasing wavenumbers.");

  // --- tables -----------------------------------------------------------
  m.attr("XSEC_TABLE_FORMAT_VERSION") = kXsecTableFormatVersion;
  py::class_<XsecTable, std::shared_ptr<XsecTable>>(m, "XsecTable", R"doc(
sigma(nu, T) table [cm2/molecule] at one pressure and self fraction
(float32 [nT][nnu]; cubic interpolation of ln sigma in T). See
qogi.spectra.CrossSectionTable for the public API.
)doc")
      .def(py::init([](double nu0, double step, const DoubleArray& temps, double p, double x,
                       const CrossSectionOptions& o,
                       const py::array_t<float, py::array::c_style | py::array::forcecast>& sigma,
                       std::string metadata) {
             CheckNdim(temps, 1, "temperatures_K");
             CheckNdim(sigma, 2, "sigma");
             Require(sigma.shape(0) == temps.size(),
                     "sigma must have one row per temperature; got " +
                         std::to_string(sigma.shape(0)) + " rows for " +
                         std::to_string(temps.size()) + " temperatures");
             const WavenumberGrid g = MakeGrid(nu0, step, static_cast<std::size_t>(sigma.shape(1)));
             return std::make_shared<XsecTable>(g, ToVector(temps, "temperatures_K"), p, x, o,
                                                FlatVector(sigma), std::move(metadata));
           }),
           py::arg("nu0_cm1"), py::arg("step_cm1"), py::arg("temperatures_K"),
           py::arg("pressure_Pa"), py::arg("self_fraction"), py::arg("options"), py::arg("sigma"),
           py::arg("metadata") = "")
      .def_static(
          "build",
          [](const LineList& l, double nu0, double step, std::size_t n, const DoubleArray& temps,
             double p, double x, const CrossSectionOptions& o, int threads, py::object progress) {
            const WavenumberGrid g = MakeGrid(nu0, step, n);
            const std::vector<double> t = ToVector(temps, "temperatures_K");
            const RunControl control = MakeRunControl(progress);
            ComputeSettings s;
            s.num_threads = threads;
            py::gil_scoped_release release;
            return std::make_shared<XsecTable>(XsecTable::Build(l, g, t, p, x, o, s, &control));
          },
          py::arg("lines"), py::arg("nu0_cm1"), py::arg("step_cm1"), py::arg("size"),
          py::arg("temperatures_K"), py::arg("pressure_Pa"), py::arg("self_fraction"),
          py::arg("options"), py::arg("num_threads") = 0, py::arg("progress") = py::none())
      .def_static(
          "load",
          [](const std::string& path) {
            return std::make_shared<XsecTable>(XsecTable::Load(path));
          },
          py::arg("path"))
      .def("save", &XsecTable::Save, py::arg("path"))
      .def_property_readonly("nu0_cm1", [](const XsecTable& t) { return t.grid().nu0_cm1; })
      .def_property_readonly("step_cm1", [](const XsecTable& t) { return t.grid().step_cm1; })
      .def_property_readonly("num_wavenumbers", &XsecTable::num_wavenumbers)
      .def_property_readonly("num_temperatures", &XsecTable::num_temperatures)
      .def_property_readonly("temperatures_K",
                             [](const XsecTable& t) { return ToArray(t.temperatures_K()); })
      .def_property_readonly("pressure_Pa", &XsecTable::pressure_Pa)
      .def_property_readonly("self_fraction", &XsecTable::self_fraction)
      .def_property_readonly("options", &XsecTable::options, py::return_value_policy::copy)
      .def_property("metadata", &XsecTable::metadata, &XsecTable::set_metadata,
                    "Free text stored with the table (qogi writes JSON).")
      .def_property_readonly(
          "sigma",
          [](py::object self) {
            const XsecTable& t = self.cast<const XsecTable&>();
            py::array_t<float> a({static_cast<py::ssize_t>(t.num_temperatures()),
                                  static_cast<py::ssize_t>(t.num_wavenumbers())},
                                 t.sigma().data(), self);
            a.attr("setflags")(py::arg("write") = false);
            return a;
          },
          "The stored values, float32 (nT, nnu) [cm2/molecule] (read-only view).")
      .def(
          "spectrum",
          [](const XsecTable& t, double temp, bool derivative) -> py::object {
            py::array_t<double> out(static_cast<py::ssize_t>(t.num_wavenumbers()));
            if (!derivative) {
              double* p = out.mutable_data();
              py::gil_scoped_release release;
              t.Spectrum(temp, p);
              return std::move(out);
            }
            py::array_t<double> d(static_cast<py::ssize_t>(t.num_wavenumbers()));
            double* p = out.mutable_data();
            double* q = d.mutable_data();
            {
              py::gil_scoped_release release;
              t.Spectrum(temp, p, q);
            }
            return py::make_tuple(out, d);
          },
          py::arg("temperature_K"), py::arg("derivative") = false,
          "sigma(nu) at a temperature [cm2/molecule]; with derivative=True also "
          "d sigma/dT [cm2/(molecule K)].")
      .def(
          "sigma_at",
          [](const XsecTable& t, std::size_t i, double temp) { return t.Sigma(i, temp); },
          py::arg("index"), py::arg("temperature_K"),
          "sigma at one grid index and temperature [cm2/molecule].");
}

}  // namespace qogi
