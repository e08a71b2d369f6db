#include "engine/inversion/mixing_line.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "engine/inversion/inversion.h"
#include "engine/util/check.h"

namespace qogi {

void MixingLineOptions::Check(std::size_t num_species, std::size_t num_channels) const {
  Require(std::isfinite(slope_K_per_fraction), "slope_K_per_fraction must be finite");
  Require(composition.size() == num_species,
          "composition needs one weight per species of the table (" +
              std::to_string(num_species) + "); got " + std::to_string(composition.size()));
  double sum = 0;
  for (double w : composition) {
    Require(std::isfinite(w) && w >= 0, "composition weights must be finite and >= 0");
    sum += w;
  }
  Require(sum > 0, "composition weights must not all be zero");
  Require(netd_K.size() == 1 || netd_K.size() == num_channels,
          "netd_K needs one value or one per channel (" + std::to_string(num_channels) + ")");
  for (double v : netd_K) Require(std::isfinite(v) && v > 0, "netd_K values must be > 0");
  Require(std::isfinite(detection_sigma) && detection_sigma >= 0, "detection_sigma must be >= 0");
  Require(min_fraction > 0 && max_fraction > min_fraction && max_fraction <= 1.0,
          "fraction bounds must satisfy 0 < min_fraction < max_fraction <= 1");
  Require(max_iterations >= 1, "max_iterations must be >= 1");
}

namespace {

struct LinePixel {
  std::size_t nc = 0, ns = 0;
  const double* y = nullptr;      // measured contrast per channel
  const double* noise = nullptr;  // per channel
  const double* phi = nullptr;    // background coefficients
  double sigma = 0;
};

class LineModel {
 public:
  LineModel(const SceneTable& table, const MixingLineOptions& o)
      : table_(table), o_(o), nc_(table.num_channels()), ns_(table.num_species()),
        t_amb_(table.ambient_temperature_K()), t_lo_(table.min_peak_temperature_K()),
        t_hi_(table.max_peak_temperature_K()), x_(ns_), m_(nc_), jac_(nc_ * (ns_ + 2)) {}

  double Temperature(double big_x, bool* on_line) const {
    const double t = t_amb_ + o_.slope_K_per_fraction * big_x;
    *on_line = t > t_lo_ && t < t_hi_;
    return std::clamp(t, t_lo_, t_hi_);
  }

  // chi2 at X; with grad, also r_c and dr_c/d(ln X) into r and dr.
  double Chi2(const LinePixel& p, double big_x, double* r, double* dr) {
    bool on_line = false;
    const double t = Temperature(big_x, &on_line);
    for (std::size_t s = 0; s < ns_; ++s) x_[s] = o_.composition[s] * big_x;
    table_.Contrast(x_.data(), t, p.sigma, p.phi, m_.data(), dr ? jac_.data() : nullptr);
    double chi2 = 0;
    const std::size_t np = ns_ + 2;
    for (std::size_t c = 0; c < nc_; ++c) {
      const double rc = (m_[c] - p.y[c]) / p.noise[c];
      chi2 += rc * rc;
      if (r) r[c] = rc;
      if (dr) {
        double d = 0;
        for (std::size_t s = 0; s < ns_; ++s) d += jac_[c * np + s] * o_.composition[s];
        if (on_line) d += jac_[c * np + ns_] * o_.slope_K_per_fraction;
        dr[c] = d * big_x / p.noise[c];
      }
    }
    return chi2;
  }

 private:
  const SceneTable& table_;
  const MixingLineOptions& o_;
  std::size_t nc_, ns_;
  double t_amb_, t_lo_, t_hi_;
  std::vector<double> x_, m_, jac_;
};

}  // namespace

MixingLineInverter::MixingLineInverter(std::shared_ptr<const SceneTable> table)
    : table_(std::move(table)) {
  Require(table_ != nullptr, "MixingLineInverter needs a table");
  for (std::size_t c = 0; c < table_->num_channels(); ++c)
    bands_.emplace_back(table_->model().channels()[c], table_->options().min_background_K,
                        table_->options().max_background_K, 0.5);
}

void MixingLineInverter::Invert(const MixingLineOptions& options, std::size_t n,
                                const double* radiance, const double* background_radiance,
                                const double* sigma_m, const MixingLineOutput& out,
                                const RunControl* control) const {
  const SceneTable& table = *table_;
  const std::vector<BandTable>& bands = bands_;
  const std::size_t nc = table.num_channels(), ns = table.num_species();
  options.Check(ns, nc);
  Require(out.fraction && out.fraction_sigma && out.peak_temperature_K && out.chi2 &&
              out.status && out.iterations,
          "InvertOnMixingLine needs every output array");
  // Every x_s = w_s X must stay <= 1 too.
  double w_max = 0;
  for (double w : options.composition) w_max = std::max(w_max, w);
  const double x_hi = std::min(options.max_fraction, 1.0 / w_max);
  const double x_lo = std::min(options.min_fraction, 0.5 * x_hi);
  const double u_lo = std::log(x_lo), u_hi = std::log(x_hi);
  std::vector<double> netd(nc, options.netd_K[0]);
  if (options.netd_K.size() == nc) netd = options.netd_K;

  ParallelFor(
      n, 256,
      [&](std::size_t begin, std::size_t end) {
        LineModel model(table, options);
        std::vector<double> y(nc), noise(nc), tbg(nc), phi(table.background_size());
        std::vector<double> r(nc), dr(nc), rt(nc), drt(nc);
        constexpr int kScan = 9;
        for (std::size_t i = begin; i < end; ++i) {
          out.fraction[i] = 0;
          out.fraction_sigma[i] = 0;
          out.chi2[i] = 0;
          out.iterations[i] = 0;
          out.peak_temperature_K[i] = table.ambient_temperature_K();
          out.status[i] = static_cast<std::int32_t>(PixelStatus::kFailed);
          bool ok = std::isfinite(sigma_m[i]) && sigma_m[i] > 0 &&
                    sigma_m[i] <= table.options().max_sigma_m;
          bool detected = false;
          for (std::size_t c = 0; c < nc && ok; ++c) {
            const double l = radiance[i * nc + c], l_bg = background_radiance[i * nc + c];
            double t = 0;
            if (!(std::isfinite(l) && std::isfinite(l_bg) && bands[c].Temperature(l_bg, &t))) {
              ok = false;
              break;
            }
            tbg[c] = t;
            y[c] = l - l_bg;
            noise[c] = netd[c] * bands[c].Derivative(t);
            if (!(noise[c] > 0)) ok = false;
            detected = detected || std::abs(y[c]) >= options.detection_sigma * noise[c];
          }
          if (!ok) continue;
          table.Background(tbg.data(), phi.data());
          LinePixel p{nc, ns, y.data(), noise.data(), phi.data(), sigma_m[i]};
          if (!detected) {
            // The 1-sigma of X in the thin limit (the noise-equivalent column).
            double info = 0;
            for (std::size_t c = 0; c < nc; ++c) {
              double a = 0;
              for (std::size_t s = 0; s < ns; ++s)
                if (table.has_table(c, s))
                  a += options.composition[s] * p.sigma *
                       table.ThinSlope(c, s, table.ambient_temperature_K(), phi.data());
              info += (a / noise[c]) * (a / noise[c]);
            }
            out.fraction_sigma[i] = info > 0 ? 1.0 / std::sqrt(info) : 0.0;
            out.status[i] = static_cast<std::int32_t>(PixelStatus::kBelowDetection);
            continue;
          }
          // Coarse scan in ln X (the line's contrast need not be monotone in
          // X), then safeguarded Gauss-Newton from the best node.
          double best_u = u_hi, best = std::numeric_limits<double>::infinity();
          for (int k = 0; k < kScan; ++k) {
            const double u = u_lo + (u_hi - u_lo) * k / (kScan - 1);
            const double c2 = model.Chi2(p, std::exp(u), nullptr, nullptr);
            if (c2 < best) {
              best = c2;
              best_u = u;
            }
          }
          double u = best_u;
          double chi2 = model.Chi2(p, std::exp(u), r.data(), dr.data());
          int it = 0;
          bool converged = false;
          double jj = 0;
          for (; it < options.max_iterations; ++it) {
            double jr = 0;
            jj = 0;
            for (std::size_t c = 0; c < nc; ++c) {
              jr += dr[c] * r[c];
              jj += dr[c] * dr[c];
            }
            if (!(jj > 0)) break;
            double step = std::clamp(-jr / jj, -2.0, 2.0);
            // Held on a bound with the gradient pointing out: done there.
            if ((u <= u_lo && step <= 0) || (u >= u_hi && step >= 0)) {
              converged = true;
              break;
            }
            bool accepted = false;
            for (int h = 0; h < 30; ++h) {
              const double un = std::clamp(u + step, u_lo, u_hi);
              const double c2 = model.Chi2(p, std::exp(un), rt.data(), drt.data());
              if (c2 <= chi2) {
                const double du = un - u;
                u = un;
                chi2 = c2;
                r.swap(rt);
                dr.swap(drt);
                accepted = true;
                if (std::abs(du) < 1e-7) converged = true;
                break;
              }
              step *= 0.5;
              if (std::abs(step) < 1e-10) break;
            }
            if (!accepted) {  // no descent along the step: at the minimum to precision
              converged = true;
              break;
            }
            if (converged) break;
          }
          jj = 0;
          for (std::size_t c = 0; c < nc; ++c) jj += dr[c] * dr[c];
          const double big_x = std::exp(u);
          bool on_line = false;
          out.fraction[i] = big_x;
          out.peak_temperature_K[i] = model.Temperature(big_x, &on_line);
          out.chi2[i] = chi2;
          out.iterations[i] = it;
          // d(ln X) has variance 1 / jj: sigma_X = X / sqrt(jj).
          out.fraction_sigma[i] = jj > 0 ? big_x / std::sqrt(jj) : 0.0;
          const bool at_bound = u <= u_lo + 1e-12 || u >= u_hi - 1e-12;
          out.status[i] = static_cast<std::int32_t>(
              !converged ? PixelStatus::kFailed
                         : at_bound ? PixelStatus::kAtBound : PixelStatus::kConverged);
        }
      },
      options.num_threads, control);
}

}  // namespace qogi
