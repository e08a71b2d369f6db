#include "engine/spectra/xsec_table.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <utility>

#include "engine/util/check.h"
#include "engine/util/interpolation.h"

namespace qogi {

XsecTable::XsecTable(const WavenumberGrid& grid, std::vector<double> temperatures_K,
                     double pressure_Pa, double self_fraction, const CrossSectionOptions& options,
                     std::vector<float> sigma, std::string metadata)
    : grid_(grid),
      temperatures_(std::move(temperatures_K)),
      pressure_Pa_(pressure_Pa),
      self_fraction_(self_fraction),
      options_(options),
      sigma_(std::move(sigma)),
      metadata_(std::move(metadata)) {
  grid_.Check();
  options_.Check();
  CheckNonNegative(pressure_Pa_, "pressure_Pa", "Pa");
  CheckInRange(self_fraction_, 0.0, 1.0, "self_fraction");
  Require(!temperatures_.empty(), "temperatures_K must list at least one temperature");
  for (std::size_t k = 0; k < temperatures_.size(); ++k) {
    CheckPositive(temperatures_[k], "temperatures_K", "K");
    if (k > 0 && !(temperatures_[k] > temperatures_[k - 1]))
      throw std::invalid_argument("temperatures_K must be strictly increasing; got " +
                                  FormatNumber(temperatures_[k]) + " after " +
                                  FormatNumber(temperatures_[k - 1]));
  }
  const std::size_t expect = temperatures_.size() * grid_.size;
  Require(sigma_.size() == expect,
          "sigma must hold temperatures x wavenumbers = " + std::to_string(expect) +
              " values; got " + std::to_string(sigma_.size()));
  const std::size_t n = grid_.size;
  log_offset_.assign(n, 0.0);
  for (std::size_t i = 0; i < sigma_.size(); ++i) {
    const float s = sigma_[i];
    if (!(std::isfinite(s) && s >= 0))
      throw std::invalid_argument("sigma[" + std::to_string(i) +
                                  "] must be finite and >= 0 cm2/molecule; got " + FormatNumber(s));
  }
  for (std::size_t j = 0; j < n; ++j) {
    float top = 0.0f;
    for (std::size_t k = 0; k < temperatures_.size(); ++k) top = std::max(top, sigma_[k * n + j]);
    if (top > 0) log_offset_[j] = std::log(static_cast<double>(top));
  }
  log_sigma_.resize(sigma_.size());
  for (std::size_t i = 0; i < sigma_.size(); ++i)
    log_sigma_[i] =
        sigma_[i] > 0
            ? static_cast<float>(std::log(static_cast<double>(sigma_[i])) - log_offset_[i % n])
            : -std::numeric_limits<float>::infinity();
}

XsecTable XsecTable::Build(const LineList& lines, const WavenumberGrid& grid,
                           const std::vector<double>& temperatures_K, double pressure_Pa,
                           double self_fraction, const CrossSectionOptions& options,
                           const ComputeSettings& settings, const RunControl* control) {
  grid.Check();
  options.Check();
  Require(!temperatures_K.empty(), "temperatures_K must list at least one temperature");
  for (std::size_t k = 1; k < temperatures_K.size(); ++k)
    if (!(temperatures_K[k] > temperatures_K[k - 1]))
      throw std::invalid_argument("temperatures_K must be strictly increasing; got " +
                                  FormatNumber(temperatures_K[k]) + " after " +
                                  FormatNumber(temperatures_K[k - 1]));
  const std::size_t nt = temperatures_K.size();
  std::vector<float> sigma(nt * grid.size);
  std::vector<double> row(grid.size);
  for (std::size_t k = 0; k < nt; ++k) {
    GasConditions cond;
    cond.temperature_K = temperatures_K[k];
    cond.pressure_Pa = pressure_Pa;
    cond.self_fraction = self_fraction;
    RunControl sub;
    if (control) {
      sub.cancelled = control->cancelled;
      if (control->progress)
        sub.progress = [&, k](double f) {
          control->progress((static_cast<double>(k) + f) / static_cast<double>(nt));
        };
    }
    ComputeCrossSection(lines, cond, grid, options, row.data(), settings, control ? &sub : nullptr);
    for (std::size_t j = 0; j < grid.size; ++j)
      sigma[k * grid.size + j] = static_cast<float>(row[j]);
  }
  return XsecTable(grid, temperatures_K, pressure_Pa, self_fraction, options, std::move(sigma));
}

XsecTable::Stencil XsecTable::StencilAt(double temperature_K) const {
  const std::vector<double>& t = temperatures_;
  CheckInRange(temperature_K, t.front(), t.back(), "temperature_K (table range)", "K");
  Stencil s;
  const std::size_t nt = t.size();
  s.count = static_cast<int>(std::min<std::size_t>(4, nt));
  // Interval i with t[i] <= T <= t[i+1].
  std::size_t i =
      static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), temperature_K) - t.begin());
  i = i == 0 ? 0 : i - 1;
  if (i + 1 >= nt && nt >= 2) i = nt - 2;
  s.temperature_K = temperature_K;
  s.lower = i;
  if (nt >= 4)
    s.first = std::min(i == 0 ? 0 : i - 1, nt - 4);
  else
    s.first = 0;
  LagrangeWeights(t.data() + s.first, s.count, temperature_K, s.w, s.dw);
  return s;
}

void XsecTable::Interpolate(const Stencil& s, std::size_t b, std::size_t e, double* out,
                            double* dsigma_dT) const {
  const std::size_t n = grid_.size;
  const int c = s.count;
  const float* ls[4];
  const float* sg[4];
  for (int k = 0; k < c; ++k) {
    ls[k] = log_sigma_.data() + (s.first + k) * n;
    sg[k] = sigma_.data() + (s.first + k) * n;
  }
  // Linear interpolation between the two grid temperatures that bracket T,
  // for the points where ln sigma cannot be used (a zero among the four).
  const std::size_t lo = s.lower;
  const std::size_t hi = std::min(lo + 1, temperatures_.size() - 1);
  const double* t = temperatures_.data();
  const double f = hi == lo ? 0.0 : (s.temperature_K - t[lo]) / (t[hi] - t[lo]);
  const double inv_dt = hi == lo ? 0.0 : 1.0 / (t[hi] - t[lo]);
  for (std::size_t j = b; j < e; ++j) {
    bool positive = true;
    for (int k = 0; k < c; ++k) positive = positive && sg[k][j] > 0.0f;
    if (positive) {
      double l = log_offset_[j], dl = 0.0;  // sum of w = 1, sum of dw = 0
      for (int k = 0; k < c; ++k) {
        l += s.w[k] * ls[k][j];
        dl += s.dw[k] * ls[k][j];
      }
      const double v = std::exp(l);
      out[j - b] = v;
      if (dsigma_dT) dsigma_dT[j - b] = v * dl;
    } else {
      const double a = sigma_[lo * n + j], z = sigma_[hi * n + j];
      out[j - b] = a + f * (z - a);
      if (dsigma_dT) dsigma_dT[j - b] = (z - a) * inv_dt;
    }
  }
}

double XsecTable::Sigma(std::size_t inu, double temperature_K) const {
  if (inu >= grid_.size)
    throw std::invalid_argument("wavenumber index must be < " + std::to_string(grid_.size) +
                                "; got " + std::to_string(inu));
  double v;
  Interpolate(StencilAt(temperature_K), inu, inu + 1, &v, nullptr);
  return v;
}

void XsecTable::Spectrum(double temperature_K, double* out, double* dsigma_dT) const {
  Interpolate(StencilAt(temperature_K), 0, grid_.size, out, dsigma_dT);
}

std::vector<double> XsecTable::Spectrum(double temperature_K) const {
  std::vector<double> out(grid_.size);
  Spectrum(temperature_K, out.data());
  return out;
}

// ---------------------------------------------------------------------------
// File format (little-endian):
//   "QOGIXSEC" | u32 version | u32 0 | f64 nu0, step | u64 nnu, nT |
//   f64 pressure_Pa, self_fraction, wing_cm1, wing_half_widths, min_intensity |
//   u64 line_shift | u64 metadata bytes | metadata | f64 T[nT] |
//   f32 sigma[nT][nnu] | u64 FNV-1a checksum of everything before it.

namespace {

constexpr char kMagic[8] = {'Q', 'O', 'G', 'I', 'X', 'S', 'E', 'C'};

std::uint64_t Fnv1a(const char* p, std::size_t n, std::uint64_t h = 1469598103934665603ull) {
  for (std::size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(p[i]);
    h *= 1099511628211ull;
  }
  return h;
}

template <class T>
void Put(std::string& buf, const T& v) {
  buf.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

class Reader {
 public:
  Reader(const std::string& data, const std::string& path) : d_(data), path_(path) {}
  template <class T>
  T Get(const char* what) {
    T v;
    Need(sizeof(T), what);
    std::memcpy(&v, d_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  void Need(std::size_t n, const char* what) const {
    if (n > d_.size() - pos_)
      throw std::runtime_error("cross-section table '" + path_ + "' is truncated (while reading " +
                               what + ")");
  }
  const char* here() const { return d_.data() + pos_; }
  void Skip(std::size_t n) { pos_ += n; }
  std::size_t pos() const { return pos_; }

 private:
  const std::string& d_;
  const std::string& path_;
  std::size_t pos_ = 0;
};

}  // namespace

void XsecTable::Save(const std::string& path) const {
  std::string buf;
  buf.reserve(128 + metadata_.size() + temperatures_.size() * 8 + sigma_.size() * 4);
  buf.append(kMagic, 8);
  Put<std::uint32_t>(buf, kXsecTableFormatVersion);
  Put<std::uint32_t>(buf, 0);
  Put<double>(buf, grid_.nu0_cm1);
  Put<double>(buf, grid_.step_cm1);
  Put<std::uint64_t>(buf, grid_.size);
  Put<std::uint64_t>(buf, temperatures_.size());
  Put<double>(buf, pressure_Pa_);
  Put<double>(buf, self_fraction_);
  Put<double>(buf, options_.wing_cm1);
  Put<double>(buf, options_.wing_half_widths);
  Put<double>(buf, options_.min_intensity);
  Put<std::uint64_t>(buf, options_.line_shift ? 1 : 0);
  Put<std::uint64_t>(buf, metadata_.size());
  buf.append(metadata_);
  buf.append(reinterpret_cast<const char*>(temperatures_.data()), temperatures_.size() * 8);
  buf.append(reinterpret_cast<const char*>(sigma_.data()), sigma_.size() * 4);
  Put<std::uint64_t>(buf, Fnv1a(buf.data(), buf.size()));
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw std::runtime_error("cannot write cross-section table '" + path + "'");
  f.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  f.close();
  if (!f) throw std::runtime_error("failed writing cross-section table '" + path + "'");
}

XsecTable XsecTable::Load(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot open cross-section table '" + path + "'");
  std::string data((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  Reader r(data, path);
  if (data.size() < 8 || std::memcmp(data.data(), kMagic, 8) != 0)
    throw std::runtime_error("'" + path + "' is not a qogi cross-section table");
  r.Skip(8);
  const auto version = r.Get<std::uint32_t>("the format version");
  if (version != kXsecTableFormatVersion)
    throw std::runtime_error("cross-section table '" + path + "' has format version " +
                             std::to_string(version) + "; this qogi reads version " +
                             std::to_string(kXsecTableFormatVersion) + " (rebuild it)");
  r.Get<std::uint32_t>("the header");
  WavenumberGrid grid;
  grid.nu0_cm1 = r.Get<double>("the grid");
  grid.step_cm1 = r.Get<double>("the grid");
  const auto nnu = r.Get<std::uint64_t>("the grid");
  const auto nt = r.Get<std::uint64_t>("the temperatures");
  const double pressure = r.Get<double>("the conditions");
  const double self_fraction = r.Get<double>("the conditions");
  CrossSectionOptions opt;
  opt.wing_cm1 = r.Get<double>("the options");
  opt.wing_half_widths = r.Get<double>("the options");
  opt.min_intensity = r.Get<double>("the options");
  opt.line_shift = r.Get<std::uint64_t>("the options") != 0;
  const auto meta_size = r.Get<std::uint64_t>("the metadata");
  const std::size_t limit = data.size();
  if (meta_size > limit || nt > limit / 8 || (nt > 0 && nnu > limit / 4 / nt))
    throw std::runtime_error("cross-section table '" + path + "' is corrupt (bad sizes)");
  r.Need(meta_size, "the metadata");
  std::string meta(r.here(), meta_size);
  r.Skip(meta_size);
  std::vector<double> temps(nt);
  r.Need(nt * 8, "the temperatures");
  std::memcpy(temps.data(), r.here(), nt * 8);
  r.Skip(nt * 8);
  std::vector<float> sigma(nt * nnu);
  r.Need(sigma.size() * 4, "sigma");
  std::memcpy(sigma.data(), r.here(), sigma.size() * 4);
  r.Skip(sigma.size() * 4);
  const std::size_t body = r.pos();
  const auto sum = r.Get<std::uint64_t>("the checksum");
  if (r.pos() != data.size())
    throw std::runtime_error("cross-section table '" + path + "' has trailing bytes (corrupt)");
  if (sum != Fnv1a(data.data(), body))
    throw std::runtime_error("cross-section table '" + path + "' fails its checksum (corrupt)");
  grid.size = static_cast<std::size_t>(nnu);
  try {
    return XsecTable(grid, std::move(temps), pressure, self_fraction, opt, std::move(sigma),
                     std::move(meta));
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("cross-section table '" + path +
                             "' holds invalid values: " + e.what());
  }
}

}  // namespace qogi
