// Bindings of engine/synth: releases, views, the puff simulation and its
// exact ground truth. Glue only.
#include "common.h"

#include <algorithm>
#include <cstring>

#include "engine/synth/gas.h"
#include "engine/synth/mean_flow.h"
#include "engine/synth/plume.h"
#include "engine/synth/release.h"
#include "engine/synth/truth.h"
#include "engine/synth/view.h"

namespace qogi {
namespace {

using synth::ControlPlane;
using synth::Grid;
using synth::MeanFlow;
using synth::PlumeModelOptions;
using synth::PlumeSimulation;
using synth::Release;
using synth::Station;
using synth::View;

py::dict StationsToDict(const MeanFlow& mf) {
  const std::vector<Station>& st = mf.stations();
  const py::ssize_t n = static_cast<py::ssize_t>(st.size());
  py::dict d;
  auto col = [&](const char* name, auto get) {
    py::array_t<double> a(n);
    double* p = a.mutable_data();
    for (py::ssize_t i = 0; i < n; ++i) p[i] = get(st[i]);
    d[name] = a;
  };
  col("s_m", [](const Station& s) { return s.s; });
  col("psi", [](const Station& s) { return s.psi; });
  col("time_s", [](const Station& s) { return s.time_s; });
  col("x_m", [](const Station& s) { return s.pos[0]; });
  col("y_m", [](const Station& s) { return s.pos[1]; });
  col("z_m", [](const Station& s) { return s.pos[2]; });
  col("tangent_x", [](const Station& s) { return s.tangent[0]; });
  col("tangent_y", [](const Station& s) { return s.tangent[1]; });
  col("tangent_z", [](const Station& s) { return s.tangent[2]; });
  col("radius_m", [](const Station& s) { return s.radius_m; });
  col("velocity_m_s", [](const Station& s) { return s.velocity_m_s; });
  col("excess_velocity_m_s", [](const Station& s) { return s.excess_m_s; });
  col("ambient_axial_m_s", [](const Station& s) { return s.ambient_axial_m_s; });
  col("mass_fraction", [](const Station& s) { return s.mass_fraction; });
  col("temperature_K", [](const Station& s) { return s.temperature_K; });
  col("density_kg_m3", [](const Station& s) { return s.density; });
  col("development", [](const Station& s) { return s.development; });
  col("turbulence", [](const Station& s) { return s.turbulence; });
  col("internal_turbulence_m_s", [](const Station& s) { return s.internal_turbulence_m_s; });
  col("sigma_c_m", [](const Station& s) { return s.sigma_c; });
  col("sigma_puff_m", [](const Station& s) { return s.sigma_puff; });
  col("offset_scale_m", [](const Station& s) { return s.offset_scale; });
  col("mass_weighted_speed_m_s", [](const Station& s) { return s.mass_weighted_speed; });
  col("centre_partial_density_kg_m3", [](const Station& s) { return s.centre_partial_density; });
  d["num_bands"] = mf.num_bands();
  std::vector<double> bt;
  for (int b = 0; b < mf.num_bands(); ++b) bt.push_back(mf.band_time_s(b));
  d["band_time_s"] = bt;
  d["laminar_length_m"] = mf.laminar_length_m();
  d["development_length_m"] = mf.development_length_m();
  return d;
}

py::dict BoxToDict(const synth::Box& b) {
  py::dict d;
  d["lo"] = std::vector<double>(b.lo.begin(), b.lo.end());
  d["hi"] = std::vector<double>(b.hi.begin(), b.hi.end());
  return d;
}

Grid GridFromDict(const py::dict& d) {
  Grid g;
  auto get = [&](const char* k, auto& v) {
    if (!d.contains(k))
      throw std::invalid_argument(std::string("grid is missing \"") + k +
                                  "\" (needs x0, y0, z0, dx, dy, dz, nx, ny, nz)");
    v = d[k].cast<std::decay_t<decltype(v)>>();
  };
  get("x0", g.x0);
  get("y0", g.y0);
  get("z0", g.z0);
  get("dx", g.dx);
  get("dy", g.dy);
  get("dz", g.dz);
  get("nx", g.nx);
  get("ny", g.ny);
  get("nz", g.nz);
  return g;
}

py::dict GridToDict(const Grid& g) {
  return ToDict(g, Field("x0", &Grid::x0), Field("y0", &Grid::y0), Field("z0", &Grid::z0),
                Field("dx", &Grid::dx), Field("dy", &Grid::dy), Field("dz", &Grid::dz),
                Field("nx", &Grid::nx), Field("ny", &Grid::ny), Field("nz", &Grid::nz));
}

ControlPlane PlaneFrom(const py::sequence& point, const py::sequence& normal) {
  if (py::len(point) != 3 || py::len(normal) != 3)
    throw std::invalid_argument("a control plane needs a 3-element point and normal");
  ControlPlane p;
  for (int k = 0; k < 3; ++k) {
    p.point[k] = point[k].cast<double>();
    p.normal[k] = normal[k].cast<double>();
    CheckFinite(p.point[k], "plane point");
    CheckFinite(p.normal[k], "plane normal");
  }
  return p;
}

}  // namespace

void BindSynth(py::module_& m) {
  BindOptions<Release>(
      m, "SynthRelease", "Gas release (see qogi.synth.Release).", Args::kKeywordOnly,
      Field("rate", &Release::rate),
      Property<std::string, Release>(
          "rate_unit", [](const Release& r) { return synth::RateUnitName(r.rate_unit); },
          [](Release& r, const std::string& u) { r.rate_unit = synth::ParseRateUnit(u); }),
      Field("composition", &Release::composition),
      Field("exit_diameter_m", &Release::exit_diameter_m),
      Field("stack_height_m", &Release::stack_height_m), Field("exit_x_m", &Release::exit_x_m),
      Field("exit_temperature_K", &Release::exit_temperature_K),
      Field("ambient_temperature_K", &Release::ambient_temperature_K),
      Field("pressure_Pa", &Release::pressure_Pa),
      Field("wind_speed_m_s", &Release::wind_speed_m_s),
      Field("wind_direction_deg", &Release::wind_direction_deg),
      Field("turbulence_intensity", &Release::turbulence_intensity),
      Field("draft_m_s", &Release::draft_m_s),
      Field("ambient_time_scale_s", &Release::ambient_time_scale_s),
      Field("release_turbulence", &Release::release_turbulence),
      Field("standard_temperature_K", &Release::standard_temperature_K),
      Field("standard_pressure_Pa", &Release::standard_pressure_Pa))
      .def("mass_rate_kg_s", &Release::MassRateKgS)
      .def("exit_density_kg_m3", &Release::ExitDensity)
      .def("exit_velocity_m_s", &Release::ExitVelocity)
      .def("exit_reynolds_number", &Release::ExitReynoldsNumber)
      .def("ambient_rms_velocity_m_s", &Release::AmbientRmsVelocity)
      .def(
          "species_mass_fractions",
          [](const Release& r) {
            const synth::GasMixture g = r.ReleasedGas();
            py::dict d;
            for (std::size_t i = 0; i < g.names().size(); ++i)
              d[py::str(g.names()[i])] = g.mass_fractions()[i];
            return d;
          },
          "Mass fraction of each species in the released gas.")
      .def("released_molar_mass_kg_mol",
           [](const Release& r) { return r.ReleasedGas().molar_mass_kg_mol(); });

  BindOptions<View>(
      m, "SynthView", "Camera geometry (see qogi.synth.View).", Args::kKeywordOnly,
      Field("width_px", &View::width_px), Field("height_px", &View::height_px),
      Field("ifov_rad", &View::ifov_rad), Field("distance_m", &View::distance_m),
      Property<std::string, View>(
          "projection", [](const View& v) { return synth::ProjectionName(v.projection); },
          [](View& v, const std::string& p) { v.projection = synth::ParseProjection(p); }),
      Field("center_x_m", &View::center_x_m), Field("center_z_m", &View::center_z_m))
      .def_property_readonly("footprint_m", &View::footprint_m)
      .def("pixel_x", &View::PixelX, py::arg("column"), py::arg("y") = 0.0)
      .def("pixel_z", &View::PixelZ, py::arg("row"), py::arg("y") = 0.0)
      .def("column", &View::Column, py::arg("x"), py::arg("y") = 0.0)
      .def("row", &View::Row, py::arg("z"), py::arg("y") = 0.0)
      .def("path_per_depth", &View::PathPerDepth, py::arg("column"), py::arg("row"))
      .def(
          "ray",
          [](const View& v, int c, int r) {
            double o[3], d[3];
            v.Ray(c, r, o, d);
            return py::make_tuple(std::vector<double>(o, o + 3), std::vector<double>(d, d + 3));
          },
          py::arg("column"), py::arg("row"));

  using P = PlumeModelOptions;
  BindOptions<P>(m, "SynthModelOptions", "Plume model settings.", Args::kKeywordOnly,
                 Field("alpha_jet", &P::alpha_jet), Field("alpha_plume", &P::alpha_plume),
                 Field("beta_crossflow", &P::beta_crossflow),
                 Field("concentration_width_ratio", &P::concentration_width_ratio),
                 Field("edge_speed_fraction", &P::edge_speed_fraction),
                 Field("laminar_length_diameters", &P::laminar_length_diameters),
                 Field("development_length_diameters", &P::development_length_diameters),
                 Field("puff_size_fraction", &P::puff_size_fraction),
                 Field("puff_rate_per_s", &P::puff_rate_per_s),
                 Field("axial_turbulence", &P::axial_turbulence),
                 Field("structure_length", &P::structure_length),
                 Field("structure_persistence", &P::structure_persistence),
                 Field("modes_per_band", &P::modes_per_band),
                 Field("column_wave_amplitude", &P::column_wave_amplitude),
                 Field("column_wave_phase_speed", &P::column_wave_phase_speed),
                 Field("spin_up_s", &P::spin_up_s), Field("seed", &P::seed));

  m.def("synth_known_species", &synth::KnownSpecies);
  m.def(
      "synth_to_kg_per_s",
      [](double value, const std::string& unit, double molar_mass, double t_std, double p_std) {
        return synth::ToKgPerS(value, synth::ParseRateUnit(unit), molar_mass, t_std, p_std);
      },
      py::arg("value"), py::arg("unit"), py::arg("molar_mass_kg_mol"),
      py::arg("standard_temperature_K"), py::arg("standard_pressure_Pa"));
  m.def(
      "synth_mean_flow",
      [](const Release& r, const PlumeModelOptions& o, double extent_m) {
        r.Check();
        const synth::MixingModel mix(r.ReleasedGas(), r.exit_temperature_K,
                                     synth::GasMixture::DryAir(), r.ambient_temperature_K,
                                     r.pressure_Pa);
        CheckPositive(extent_m, "extent_m", "m");
        const std::array<double, 3> lo = {r.exit_x_m - extent_m, -extent_m, r.stack_height_m};
        const std::array<double, 3> hi = {r.exit_x_m + extent_m, extent_m,
                                          r.stack_height_m + extent_m};
        const MeanFlow mf(r, o, mix, lo, hi, 0.0);
        return StationsToDict(mf);
      },
      py::arg("release"), py::arg("model"), py::arg("extent_m"),
      "Mean-flow stations of the integral plume model until the axis leaves a box "
      "of half-size extent_m around the exit (dict of arrays).");
  m.def(
      "synth_mixing_state",
      [](const Release& r, const DoubleArray& partial_density) {
        r.Check();
        const synth::MixingModel mix(r.ReleasedGas(), r.exit_temperature_K,
                                     synth::GasMixture::DryAir(), r.ambient_temperature_K,
                                     r.pressure_Pa);
        const std::size_t n = partial_density.size();
        py::array_t<double> t(n), x(n);
        py::array_t<bool> ok(n);
        for (std::size_t i = 0; i < n; ++i)
          ok.mutable_data()[i] = mix.StateFromPartialDensity(
              partial_density.data()[i], t.mutable_data() + i, x.mutable_data() + i);
        py::dict d;
        d["temperature_K"] = t;
        d["mole_fraction"] = x;
        d["ok"] = ok;
        d["exit_density_kg_m3"] = mix.exit_density();
        d["ambient_density_kg_m3"] = mix.ambient_density();
        return d;
      },
      py::arg("release"), py::arg("partial_density"));
  m.def(
      "synth_mixing_temperature",
      [](const Release& r, double y) {
        r.Check();
        const synth::MixingModel mix(r.ReleasedGas(), r.exit_temperature_K,
                                     synth::GasMixture::DryAir(), r.ambient_temperature_K,
                                     r.pressure_Pa);
        return py::make_tuple(mix.TemperatureAtMassFraction(y), mix.DensityAtMassFraction(y));
      },
      py::arg("release"), py::arg("mass_fraction"));

  py::class_<PlumeSimulation>(m, "SynthSimulation", "A simulated plume (see qogi.synth).")
      .def(py::init([](const Release& r, const View& v, double duration, double rate,
                       const PlumeModelOptions& o, int threads, py::object progress) {
             RunControl control = MakeRunControl(progress);
             py::gil_scoped_release release;
             return new PlumeSimulation(r, v, duration, rate, o, threads, &control);
           }),
           py::arg("release"), py::arg("view"), py::arg("duration_s"), py::arg("frame_rate_hz"),
           py::arg("model"), py::arg("num_threads") = 0, py::arg("progress") = py::none())
      .def_property_readonly("num_frames", &PlumeSimulation::num_frames)
      .def_property_readonly("frame_rate_hz", &PlumeSimulation::frame_rate_hz)
      .def_property_readonly("mass_rate_kg_s", &PlumeSimulation::mass_rate_kg_s)
      .def_property_readonly("puff_rate_per_s", &PlumeSimulation::puff_rate_per_s)
      .def_property_readonly("spin_up_s", &PlumeSimulation::spin_up_s)
      .def_property_readonly("species", &PlumeSimulation::species)
      .def_property_readonly("species_mass_fractions", &PlumeSimulation::species_mass_fractions)
      .def_property_readonly("species_mole_fractions", &PlumeSimulation::species_mole_fractions)
      .def_property_readonly("release", &PlumeSimulation::release, py::return_value_policy::copy)
      .def_property_readonly("view", &PlumeSimulation::view, py::return_value_policy::copy)
      .def_property_readonly("model", &PlumeSimulation::options, py::return_value_policy::copy)
      .def_property_readonly("box", [](const PlumeSimulation& s) { return BoxToDict(s.box()); })
      .def_property_readonly("stats",
                             [](const PlumeSimulation& s) {
                               using S = std::decay_t<decltype(s.stats())>;
                               return ToDict(s.stats(), Field("puffs_emitted", &S::puffs_emitted),
                                             Field("max_live_puffs", &S::max_live_puffs),
                                             Field("puffs_lost_inside", &S::puffs_lost_inside));
                             })
      .def("mean_flow", [](const PlumeSimulation& s) { return StationsToDict(s.mean_flow()); })
      .def("default_grid",
           [](const PlumeSimulation& s) { return GridToDict(synth::DefaultGrid(s)); })
      .def(
          "puffs",
          [](const PlumeSimulation& s, int frame) {
            const auto& p = s.puffs(frame);
            py::array_t<float> out({static_cast<py::ssize_t>(p.size()), py::ssize_t{9}});
            float* o = out.mutable_data();
            for (std::size_t i = 0; i < p.size(); ++i) {
              const float row[9] = {p[i].x, p[i].y,     p[i].z,          p[i].u,   p[i].v,
                                    p[i].w, p[i].sigma, p[i].sigma_rate, p[i].mass};
              std::memcpy(o + 9 * i, row, sizeof(row));
            }
            return out;
          },
          py::arg("frame"))
      .def(
          "puff_ids",
          [](const PlumeSimulation& s, int frame) {
            const auto& p = s.puffs(frame);
            py::array_t<std::uint32_t> out(static_cast<py::ssize_t>(p.size()));
            for (std::size_t i = 0; i < p.size(); ++i) out.mutable_data()[i] = p[i].id;
            return out;
          },
          py::arg("frame"))
      .def(
          "truth_maps",
          [](const PlumeSimulation& s, int frame, int threads) {
            synth::TruthMaps t;
            {
              py::gil_scoped_release release;
              t = synth::ComputeTruthMaps(s, frame, threads);
            }
            const std::vector<py::ssize_t> shape = {t.height, t.width};
            py::dict d;
            d["column_kg_m2"] = ToArray<float>(t.column, shape);
            d["flux_x_kg_m_s"] = ToArray<float>(t.flux_x, shape);
            d["flux_z_kg_m_s"] = ToArray<float>(t.flux_z, shape);
            d["velocity_x_m_s"] = ToArray<float>(t.velocity_x, shape);
            d["velocity_z_m_s"] = ToArray<float>(t.velocity_z, shape);
            return d;
          },
          py::arg("frame"), py::arg("num_threads") = 0)
      .def(
          "plane_flux",
          [](const PlumeSimulation& s, const py::sequence& points, const py::sequence& normals,
             const std::vector<int>& frames) {
            CheckSameLength(py::len(points), py::len(normals), "points", "normals");
            std::vector<ControlPlane> planes;
            for (std::size_t i = 0; i < py::len(points); ++i)
              planes.push_back(
                  PlaneFrom(points[i].cast<py::sequence>(), normals[i].cast<py::sequence>()));
            for (int f : frames) s.puffs(f);  // validates the indices
            py::array_t<double> out(
                {static_cast<py::ssize_t>(frames.size()), static_cast<py::ssize_t>(planes.size())});
            double* o = out.mutable_data();
            {
              py::gil_scoped_release release;
              ParallelFor(frames.size(), 1, [&](std::size_t b, std::size_t e) {
                for (std::size_t i = b; i < e; ++i)
                  for (std::size_t k = 0; k < planes.size(); ++k)
                    o[i * planes.size() + k] = synth::PlaneMassFlux(s.puffs(frames[i]), planes[k]);
              });
            }
            return out;
          },
          py::arg("points"), py::arg("normals"), py::arg("frames"))
      .def(
          "fields",
          [](const PlumeSimulation& s, int frame, py::object grid, bool velocity, int threads) {
            const Grid g =
                grid.is_none() ? synth::DefaultGrid(s) : GridFromDict(grid.cast<py::dict>());
            synth::Fields f;
            {
              py::gil_scoped_release release;
              f = synth::ComputeFields(s, frame, g, velocity, threads);
            }
            const std::vector<py::ssize_t> shape = {g.nz, g.ny, g.nx};
            py::dict d;
            d["grid"] = GridToDict(g);
            d["partial_density_kg_m3"] = ToArray(f.partial_density, shape);
            d["mole_fraction"] = ToArray(f.mole_fraction, shape);
            d["temperature_K"] = ToArray(f.temperature, shape);
            if (velocity) {
              d["velocity_x_m_s"] = ToArray(f.velocity_x, shape);
              d["velocity_y_m_s"] = ToArray(f.velocity_y, shape);
              d["velocity_z_m_s"] = ToArray(f.velocity_z, shape);
            }
            d["over_pure"] = f.over_pure;
            return d;
          },
          py::arg("frame"), py::arg("grid") = py::none(), py::arg("velocity") = true,
          py::arg("num_threads") = 0)
      .def(
          "ray_samples",
          [](const PlumeSimulation& s, int frame, int row0, int row1, int col0, int col1,
             int threads) {
            synth::RaySamples r;
            {
              py::gil_scoped_release release;
              r = synth::SampleRays(s, frame, row0, row1, col0, col1, threads);
            }
            const std::vector<py::ssize_t> pix = {r.rows, r.cols};
            const std::vector<py::ssize_t> smp = {static_cast<py::ssize_t>(r.temperature.size())};
            py::dict d;
            d["row0"] = r.row0;
            d["col0"] = r.col0;
            d["planes"] = r.planes;
            d["step_m"] = r.step_m;
            d["y_m"] = ToArray(r.y_m, {r.planes});
            d["path_m"] = ToArray(r.path_m, pix);
            d["offset"] = ToArray(r.offset, {static_cast<py::ssize_t>(r.offset.size())});
            d["first_plane"] = ToArray(r.first_plane, pix);
            py::list mf;
            for (const auto& v : r.mole_fraction) mf.append(ToArray(v, smp));
            d["mole_fraction"] = mf;
            d["temperature_K"] = ToArray(r.temperature, smp);
            d["partial_density_kg_m3"] = ToArray(r.partial_density, smp);
            d["over_pure"] = r.over_pure;
            return d;
          },
          py::arg("frame"), py::arg("row0"), py::arg("row1"), py::arg("col0"), py::arg("col1"),
          py::arg("num_threads") = 0);
}

}  // namespace qogi
