// Cross-section tables sigma(nu, T) at one pressure and self fraction: what
// the forward model consumes.
//
// sigma is stored as float32 [nT][nnu] on a uniform wavenumber grid and an
// ascending temperature grid. Between temperatures it is interpolated with
// 4-point Lagrange (cubic) interpolation of ln sigma in T, through the two
// grid temperatures below and the two above (one below and three above, or
// three below and one above, in the end intervals); where any of the four
// values is <= 0 the same weights are applied to sigma itself. ln sigma of a
// line at fixed nu varies like -c2 E''/T + const (Boltzmann factor) plus
// slowly varying width terms, which a cubic in T follows closely: on a 10 K
// grid over 200-800 K the error against direct computation, where sigma
// exceeds 1% of its maximum, is ~5e-5 for CH4 (2830-3250 cm-1) and CO2
// (2100-2300 cm-1) and 4e-4 for H2O (2830-3250 cm-1) (measured by
// benchmarks/bench_spectra.py, bounded by tests/python/test_spectra.py,
// reported in docs/spectroscopy.md).
//
// The interpolation error bound needs wing windows that do not move with
// temperature: with HAPI's half-width rule a window edge moves with the line
// width, so sigma(T) at a fixed nu jumps by up to ~1% where a strong line's
// window ends; a fixed cutoff (CrossSectionOptions::wing_cm1 > 0,
// wing_half_widths = 0) keeps sigma smooth in T.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "engine/spectra/cross_section.h"

namespace qogi {

// Version of the file format written by XsecTable::Save.
constexpr unsigned kXsecTableFormatVersion = 1;

class XsecTable {
 public:
  // Interpolation stencil at one temperature: sigma(T) ~ combination of the
  // `count` grid temperatures from `first` with weights w (and dw = dw/dT).
  struct Stencil {
    double temperature_K = 0;  // where the stencil applies [K]
    std::size_t lower = 0;     // grid interval [lower, lower + 1] holding it
    std::size_t first = 0;
    int count = 0;
    double w[4] = {0, 0, 0, 0};
    double dw[4] = {0, 0, 0, 0};  // [1/K]
  };

  // A table from its values. temperatures_K: strictly increasing, > 0, at
  // least one; sigma: temperatures_K.size() x grid.size values [cm2/molecule],
  // finite and >= 0, row k at temperatures_K[k]. Throws std::invalid_argument.
  XsecTable(const WavenumberGrid& grid, std::vector<double> temperatures_K, double pressure_Pa,
            double self_fraction, const CrossSectionOptions& options, std::vector<float> sigma,
            std::string metadata = "");

  // Computes a table: one ComputeCrossSection per temperature.
  static XsecTable Build(const LineList& lines, const WavenumberGrid& grid,
                         const std::vector<double>& temperatures_K, double pressure_Pa,
                         double self_fraction, const CrossSectionOptions& options,
                         const ComputeSettings& settings = ComputeSettings(),
                         const RunControl* control = nullptr);

  const WavenumberGrid& grid() const { return grid_; }
  const std::vector<double>& temperatures_K() const { return temperatures_; }
  double pressure_Pa() const { return pressure_Pa_; }
  double self_fraction() const { return self_fraction_; }
  const CrossSectionOptions& options() const { return options_; }
  // The stored values, [nT][nnu] row-major [cm2/molecule].
  const std::vector<float>& sigma() const { return sigma_; }
  const float* row(std::size_t k) const { return sigma_.data() + k * grid_.size; }
  std::size_t num_wavenumbers() const { return grid_.size; }
  std::size_t num_temperatures() const { return temperatures_.size(); }
  // Free text stored with the table (e.g. what it was built from).
  const std::string& metadata() const { return metadata_; }
  void set_metadata(std::string m) { metadata_ = std::move(m); }

  // The stencil at temperature_K; throws std::invalid_argument outside
  // [T_0, T_last].
  Stencil StencilAt(double temperature_K) const;
  // sigma at grid point inu and temperature_K [cm2/molecule].
  double Sigma(std::size_t inu, double temperature_K) const;
  // The same with a stencil computed once (for loops over many points at one
  // temperature); inu < num_wavenumbers() is not checked.
  double Sigma(const Stencil& stencil, std::size_t inu) const {
    double v;
    Interpolate(stencil, inu, inu + 1, &v, nullptr);
    return v;
  }
  // The whole spectrum at temperature_K into out[0 .. nnu), and optionally
  // d sigma / dT into dsigma_dT [cm2/(molecule K)].
  void Spectrum(double temperature_K, double* out, double* dsigma_dT = nullptr) const;
  std::vector<double> Spectrum(double temperature_K) const;

  // Writes the table to `path` (binary, little-endian, format version
  // kXsecTableFormatVersion, with a checksum). Throws std::runtime_error.
  void Save(const std::string& path) const;
  // Reads a table written by Save. Throws std::runtime_error naming the file
  // when it is not a table, has another format version, is truncated or fails
  // its checksum.
  static XsecTable Load(const std::string& path);

 private:
  void Interpolate(const Stencil& s, std::size_t b, std::size_t e, double* out,
                   double* dsigma_dT) const;

  WavenumberGrid grid_;
  std::vector<double> temperatures_;
  double pressure_Pa_ = 0, self_fraction_ = 0;
  CrossSectionOptions options_;
  std::vector<float> sigma_;
  // ln sigma - log_offset_[j] (float; -inf where sigma <= 0), with
  // log_offset_[j] = ln max_k sigma[k][j], so that the stored values are small
  // and float keeps ~1e-7 relative precision of sigma.
  std::vector<float> log_sigma_;
  std::vector<double> log_offset_;
  std::string metadata_;
};

}  // namespace qogi
