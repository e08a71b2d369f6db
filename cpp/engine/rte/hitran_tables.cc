#include "engine/rte/hitran_tables.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "engine/util/check.h"

namespace qogi {
namespace {

std::string OneDecimal(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

// A RunControl that reports progress within [from, to] of `parent`'s.
RunControl Slice(const RunControl* parent, double from, double to) {
  RunControl c;
  if (parent == nullptr) return c;
  c.cancelled = parent->cancelled;
  if (parent->progress)
    c.progress = [p = parent->progress, from, to](double f) { p(from + (to - from) * f); };
  return c;
}

void CheckMade(const XsecTable& t, const std::string& species, const WavenumberGrid& grid,
               const std::vector<double>& temperatures_K, double pressure_Pa,
               double self_fraction) {
  const WavenumberGrid& g = t.grid();
  const bool ok = g.nu0_cm1 == grid.nu0_cm1 && g.step_cm1 == grid.step_cm1 && g.size == grid.size &&
                  t.temperatures_K() == temperatures_K && t.pressure_Pa() == pressure_Pa &&
                  t.self_fraction() == self_fraction;
  if (!ok)
    throw std::logic_error("the table maker returned a " + species +
                           " table on another grid, temperatures, pressure or self fraction "
                           "than asked for");
}

}  // namespace

std::vector<double> AbsorberTableOptions::DefaultTemperatures() {
  std::vector<double> t;
  for (int i = 0; i <= 40; ++i) t.push_back(200.0 + 10.0 * i);
  return t;
}

void AbsorberTableOptions::Check() const {
  CheckPositive(pressure_Pa, "AbsorberTableOptions.pressure_Pa", "Pa");
  CheckPositive(step_cm1, "AbsorberTableOptions.step_cm1", "cm-1");
  Require(temperatures_K.size() >= 2,
          "AbsorberTableOptions.temperatures_K needs at least 2 values; got " +
              std::to_string(temperatures_K.size()));
  for (std::size_t i = 0; i < temperatures_K.size(); ++i) {
    CheckPositive(temperatures_K[i], "AbsorberTableOptions.temperatures_K", "K");
    Require(i == 0 || temperatures_K[i] > temperatures_K[i - 1],
            "AbsorberTableOptions.temperatures_K must be strictly increasing; got " +
                FormatNumber(temperatures_K[i]) + " K after " +
                FormatNumber(temperatures_K[i - 1]) + " K");
  }
  Require(num_threads >= 0, "AbsorberTableOptions.num_threads must be >= 0 (0 = all cores); got " +
                                std::to_string(num_threads));
  cross_section_options().Check();
}

CrossSectionOptions AbsorberTableOptions::cross_section_options() const {
  CrossSectionOptions o;
  o.wing_cm1 = wing_cm1;
  o.wing_half_widths = wing_half_widths;
  o.line_shift = true;
  o.min_intensity = 0.0;
  return o;
}

WavenumberGrid AbsorberTableGrid(const std::string& species, const LineList& lines,
                                 const std::vector<SpectralResponse>& channels, double step_cm1) {
  Require(!channels.empty(), "AbsorberTableGrid: no channels given");
  Require(!lines.empty(), "AbsorberTableGrid: the " + species + " line list is empty");
  CheckPositive(step_cm1, "step_cm1", "cm-1");
  double lo = channels.front().min_nu_cm1(), hi = channels.front().max_nu_cm1();
  for (const auto& ch : channels) {
    lo = std::min(lo, ch.min_nu_cm1());
    hi = std::max(hi, ch.max_nu_cm1());
  }
  const auto span = std::minmax_element(lines.nu_cm1.begin(), lines.nu_cm1.end());
  lo = std::max(lo, *span.first - kTableWing_cm1);
  hi = std::min(hi, *span.second + kTableWing_cm1);
  if (!(hi > lo))
    throw std::invalid_argument("the " + species + " line list (" + OneDecimal(*span.first) + "-" +
                                OneDecimal(*span.second) +
                                " cm-1) does not reach any channel's band; drop " + species +
                                " from the species or give a line list that covers the channels");
  // The start on a multiple of the step: every species' grid on one lattice.
  lo = std::floor(lo / step_cm1) * step_cm1;
  return WavenumberGrid::FromRange(lo, hi, step_cm1);
}

AbsorberTable BuildAbsorberTable(const std::string& species, const LineList& lines,
                                 const std::vector<SpectralResponse>& channels,
                                 const AbsorberTableOptions& options, const RunControl* control,
                                 const XsecTableMaker& make) {
  options.Check();
  const WavenumberGrid grid = AbsorberTableGrid(species, lines, channels, options.step_cm1);
  const CrossSectionOptions xs = options.cross_section_options();
  const std::vector<double>& temps = options.temperatures_K;
  const double p = options.pressure_Pa;
  const auto one = [&](double self_fraction, const RunControl* c) {
    if (!make) {
      ComputeSettings settings;
      settings.num_threads = options.num_threads;
      return XsecTable::Build(lines, grid, temps, p, self_fraction, xs, settings, c);
    }
    XsecTable t = make(species, lines, grid, temps, p, self_fraction, xs, c);
    CheckMade(t, species, grid, temps, p, self_fraction);
    return t;
  };
  const double split = options.self_broadening ? 0.5 : 1.0;
  const RunControl air_control = Slice(control, 0.0, split);
  const XsecTable air = one(0.0, control ? &air_control : nullptr);

  AbsorberTable out;
  out.species = species;
  out.pressure_Pa = p;
  out.nu0_cm1 = grid.nu0_cm1;
  out.dnu_cm1 = grid.step_cm1;
  out.n_nu = grid.size;
  out.temperatures_K = temps;
  out.sigma_air = air.sigma();
  if (options.self_broadening) {
    const RunControl self_control = Slice(control, split, 1.0);
    out.sigma_self = one(1.0, control ? &self_control : nullptr).sigma();
  }
  out.Check();
  return out;
}

std::vector<AbsorberTable> BuildAbsorberTables(const std::vector<std::string>& species,
                                               const std::vector<SpectralResponse>& channels,
                                               const LineSources& sources,
                                               const AbsorberTableOptions& options,
                                               const RunControl* control,
                                               const XsecTableMaker& make) {
  options.Check();
  Require(!species.empty(), "BuildAbsorberTables: no species given; e.g. {\"CH4\"}");
  Require(!channels.empty(), "BuildAbsorberTables: no channels given");
  for (const auto& s : species) MolarMass(s);  // an unknown species fails before any work
  std::vector<AbsorberTable> out;
  const double n = static_cast<double>(species.size());
  for (std::size_t k = 0; k < species.size(); ++k) {
    const LineList lines = LoadSpeciesLines(species[k], sources);
    const RunControl c = Slice(control, k / n, (k + 1) / n);
    out.push_back(
        BuildAbsorberTable(species[k], lines, channels, options, control ? &c : nullptr, make));
  }
  return out;
}

}  // namespace qogi
