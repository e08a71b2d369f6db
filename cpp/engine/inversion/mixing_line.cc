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
          "composition needs one weight per species of the table (" + std::to_string(num_species) +
              "); got " + std::to_string(composition.size()));
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
  Require(
      line_nodes_per_unit >= 0 && line_nodes_per_unit <= 256,
      "line_nodes_per_unit must be within [0, 256]; got " + std::to_string(line_nodes_per_unit));
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
      : table_(table),
        o_(o),
        nc_(table.num_channels()),
        ns_(table.num_species()),
        t_amb_(table.ambient_temperature_K()),
        t_lo_(table.min_peak_temperature_K()),
        t_hi_(table.max_peak_temperature_K()),
        x_(ns_),
        m_(nc_),
        jac_(nc_ * (ns_ + 2)) {}

  double Temperature(double big_x, bool* on_line) const {
    const double t = t_amb_ + o_.slope_K_per_fraction * big_x;
    *on_line = t > t_lo_ && t < t_hi_;
    return std::clamp(t, t_lo_, t_hi_);
  }

  // Contrast m_c at X on the line in front of background coefficients phi
  // and, with dm, dm_c/d(ln X).
  void Contrast(double big_x, double sigma, const double* phi, double* m, double* dm) {
    bool on_line = false;
    const double t = Temperature(big_x, &on_line);
    for (std::size_t s = 0; s < ns_; ++s) x_[s] = o_.composition[s] * big_x;
    table_.Contrast(x_.data(), t, sigma, phi, m, dm ? jac_.data() : nullptr);
    if (!dm) return;
    const std::size_t np = ns_ + 2;
    for (std::size_t c = 0; c < nc_; ++c) {
      double d = 0;
      for (std::size_t s = 0; s < ns_; ++s) d += jac_[c * np + s] * o_.composition[s];
      if (on_line) d += jac_[c * np + ns_] * o_.slope_K_per_fraction;
      dm[c] = d * big_x;
    }
  }

  // chi2 at X; with grad, also r_c and dr_c/d(ln X) into r and dr.
  double Chi2(const LinePixel& p, double big_x, double* r, double* dr) {
    Contrast(big_x, p.sigma, p.phi, m_.data(), dr ? dm_.data() : nullptr);
    double chi2 = 0;
    for (std::size_t c = 0; c < nc_; ++c) {
      const double rc = (m_[c] - p.y[c]) / p.noise[c];
      chi2 += rc * rc;
      if (r) r[c] = rc;
      if (dr) dr[c] = dm_[c] / p.noise[c];
    }
    return chi2;
  }

 private:
  const SceneTable& table_;
  const MixingLineOptions& o_;
  std::size_t nc_, ns_;
  double t_amb_, t_lo_, t_hi_;
  std::vector<double> x_, m_, jac_, dm_ = std::vector<double>(nc_);
};

// The line's contrast for one plume depth, tabulated in v = ln X. The
// table's contrast is affine in the background coefficients phi,
// m_c = a_c0(v) + sum_j a_cj(v) phi_j, so each a_cj and its slope in v are
// stored at uniform nodes (from the table's own values and Jacobian) and
// interpolated by cubic Hermite polynomials.
class LineTable {
 public:
  LineTable(std::size_t nc, std::size_t nphi, double sigma, double v_lo, double v_hi, int per_unit)
      : nc_(nc),
        ne_(1 + nphi),
        sigma_(sigma),
        v_lo_(v_lo),
        n_(std::max(4, static_cast<int>(std::ceil((v_hi - v_lo) * per_unit)) + 1)),
        h_((v_hi - v_lo) / (n_ - 1)),
        val_(static_cast<std::size_t>(n_) * nc_ * ne_),
        der_(val_.size()) {}

  int num_nodes() const { return n_; }
  double sigma() const { return sigma_; }
  double node(int k) const { return v_lo_ + k * h_; }

  // Fills node k (thread-safe for distinct k): per (channel, species) table
  // its contribution with the background coefficients at zero, then with each
  // of its own coefficients at one (the others do not enter it).
  void Fill(int k, const SceneTable& table, const MixingLineOptions& o, std::vector<double>* phi) {
    const double big_x = std::exp(node(k));
    const double t_raw = table.ambient_temperature_K() + o.slope_K_per_fraction * big_x;
    const bool on_line =
        t_raw > table.min_peak_temperature_K() && t_raw < table.max_peak_temperature_K();
    const double tp =
        std::clamp(t_raw, table.min_peak_temperature_K(), table.max_peak_temperature_K());
    const double dt_dv = on_line ? o.slope_K_per_fraction * big_x : 0.0;
    double* pv = &val_[static_cast<std::size_t>(k) * nc_ * ne_];
    double* pd = &der_[static_cast<std::size_t>(k) * nc_ * ne_];
    std::fill(pv, pv + nc_ * ne_, 0.0);
    std::fill(pd, pd + nc_ * ne_, 0.0);
    std::fill(phi->begin(), phi->end(), 0.0);
    for (std::size_t s = 0; s < table.num_species(); ++s) {
      const double xs = o.composition[s] * big_x, u = xs * sigma_;
      for (std::size_t c = 0; c < nc_; ++c) {
        if (!table.has_table(c, s)) continue;
        // value and d value / d ln X along the line.
        auto eval = [&](double* value, double* slope) {
          double v, d_du, d_dx, d_dt;
          table.SpeciesContrast(c, s, u, xs, tp, phi->data(), &v, &d_du, &d_dx, &d_dt);
          *value = v;
          *slope = (d_du * sigma_ + d_dx) * xs + d_dt * dt_dv;
        };
        double v0, d0;
        eval(&v0, &d0);
        pv[c * ne_] += v0;
        pd[c * ne_] += d0;
        const std::size_t off = table.phi_offset(c, s);
        for (int r = 0; r < table.basis_rank(c, s); ++r) {
          (*phi)[off + r] = 1.0;
          double v1, d1;
          eval(&v1, &d1);
          (*phi)[off + r] = 0.0;
          pv[c * ne_ + 1 + off + r] += v1 - v0;
          pd[c * ne_ + 1 + off + r] += d1 - d0;
        }
      }
    }
  }

  // Contrast (and dm/dv) at v for e = (1, phi...).
  void Eval(double v, const double* e, double* m, double* dm) const {
    const double s = (v - v_lo_) / h_;
    const int k = std::clamp(static_cast<int>(std::floor(s)), 0, n_ - 2);
    const double t = std::clamp(s - k, 0.0, 1.0), t2 = t * t, t3 = t2 * t;
    const double h00 = 2 * t3 - 3 * t2 + 1, h10 = (t3 - 2 * t2 + t) * h_, h01 = -2 * t3 + 3 * t2,
                 h11 = (t3 - t2) * h_;
    const double g00 = (6 * t2 - 6 * t) / h_, g10 = 3 * t2 - 4 * t + 1,
                 g01 = (-6 * t2 + 6 * t) / h_, g11 = 3 * t2 - 2 * t;
    const double* v0 = &val_[static_cast<std::size_t>(k) * nc_ * ne_];
    const double* d0 = &der_[static_cast<std::size_t>(k) * nc_ * ne_];
    const double* v1 = v0 + nc_ * ne_;
    const double* d1 = d0 + nc_ * ne_;
    for (std::size_t c = 0; c < nc_; ++c) {
      double p0 = 0, q0 = 0, p1 = 0, q1 = 0;
      for (std::size_t j = 0; j < ne_; ++j) {
        const std::size_t i = c * ne_ + j;
        p0 += v0[i] * e[j];
        q0 += d0[i] * e[j];
        p1 += v1[i] * e[j];
        q1 += d1[i] * e[j];
      }
      m[c] = h00 * p0 + h10 * q0 + h01 * p1 + h11 * q1;
      if (dm) dm[c] = g00 * p0 + g10 * q0 + g01 * p1 + g11 * q1;
    }
  }

  // Contrast at node k for e (the scan).
  void AtNode(int k, const double* e, double* m) const {
    const double* v0 = &val_[static_cast<std::size_t>(k) * nc_ * ne_];
    for (std::size_t c = 0; c < nc_; ++c) {
      double p = 0;
      for (std::size_t j = 0; j < ne_; ++j) p += v0[c * ne_ + j] * e[j];
      m[c] = p;
    }
  }

 private:
  std::size_t nc_, ne_;
  double sigma_, v_lo_;
  int n_;
  double h_;
  std::vector<double> val_, der_;
};

}  // namespace

MixingLineInverter::MixingLineInverter(std::shared_ptr<const SceneTable> table)
    : table_(std::move(table)) {
  Require(table_ != nullptr, "MixingLineInverter needs a table");
  // One band table per channel, built in parallel over the channels.
  const std::size_t nc = table_->num_channels();
  std::vector<std::unique_ptr<RadiometricTable>> built(nc);
  ParallelFor(nc, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t c = b; c < e; ++c)
      built[c] = std::make_unique<RadiometricTable>(
          BackgroundBandTable(table_->model().channels()[c], table_->options().min_background_K,
                              table_->options().max_background_K, /*num_threads=*/1));
  });
  for (auto& t : built) bands_.push_back(std::move(*t));
}

void MixingLineInverter::Invert(const MixingLineOptions& options, std::size_t n,
                                const double* radiance, const double* background_radiance,
                                const double* sigma_m, const MixingLineOutput& out,
                                const RunControl* control) const {
  const SceneTable& table = *table_;
  const std::vector<RadiometricTable>& bands = bands_;
  const std::size_t nc = table.num_channels(), ns = table.num_species();
  options.Check(ns, nc);
  Require(out.fraction && out.fraction_sigma && out.peak_temperature_K && out.chi2 && out.status &&
              out.iterations,
          "InvertOnMixingLine needs every output array");
  // Every x_s = w_s X must stay <= 1 too.
  double w_max = 0;
  for (double w : options.composition) w_max = std::max(w_max, w);
  const double x_hi = std::min(options.max_fraction, 1.0 / w_max);
  const double x_lo = std::min(options.min_fraction, 0.5 * x_hi);
  const double u_lo = std::log(x_lo), u_hi = std::log(x_hi);
  std::vector<double> netd(nc, options.netd_K[0]);
  if (options.netd_K.size() == nc) netd = options.netd_K;

  // The coarse scan's nodes: two per unit of ln X (a factor 1.65 in X). A
  // sparser scan (9 nodes over the range, a factor 13) can start in the
  // wrong basin where the line's contrast crosses zero and end on the lower
  // bound.
  const int scan_nodes = static_cast<int>(std::ceil(2.0 * (u_hi - u_lo))) + 1;
  // Line tables for the distinct plume depths, when building them (a table
  // evaluation per background coefficient and node) costs less than half the
  // per-pixel table evaluations they replace (the scan's and ~10 more).
  const std::size_t ne = 1 + table.background_size();
  std::vector<double> depths;
  std::vector<LineTable> lines;
  if (options.line_nodes_per_unit > 0) {
    for (std::size_t i = 0; i < n; ++i)
      if (std::isfinite(sigma_m[i]) && sigma_m[i] > 0 && sigma_m[i] <= table.options().max_sigma_m)
        depths.push_back(sigma_m[i]);
    std::sort(depths.begin(), depths.end());
    depths.erase(std::unique(depths.begin(), depths.end()), depths.end());
    const double nodes = std::ceil((u_hi - u_lo) * options.line_nodes_per_unit) + 1;
    // A node costs one evaluation per background coefficient and table, of
    // one (channel, species) table each: ~(P + tables) / tables Contrast()s.
    std::size_t num_tables = 0;
    for (std::size_t c = 0; c < nc; ++c)
      for (std::size_t s = 0; s < ns; ++s) num_tables += table.has_table(c, s);
    const double per_node =
        static_cast<double>(ne - 1 + num_tables) / std::max<std::size_t>(1, num_tables);
    if (depths.empty() ||
        static_cast<double>(depths.size()) * nodes * per_node > 0.5 * n * (scan_nodes + 10.0))
      depths.clear();
    for (double d : depths)
      lines.emplace_back(nc, ne - 1, d, u_lo, u_hi, options.line_nodes_per_unit);
    if (!lines.empty()) {
      const std::size_t per = static_cast<std::size_t>(lines[0].num_nodes());
      ParallelFor(
          lines.size() * per, 16,
          [&](std::size_t b, std::size_t e) {
            std::vector<double> phi(ne - 1);
            for (std::size_t i = b; i < e; ++i)
              lines[i / per].Fill(static_cast<int>(i % per), table, options, &phi);
          },
          options.num_threads, nullptr);
    }
  }

  ParallelFor(
      n, 256,
      [&](std::size_t begin, std::size_t end) {
        LineModel model(table, options);
        std::vector<double> y(nc), noise(nc), tbg(nc), e(ne), mm(nc), dm(nc);
        double* phi = e.data() + 1;
        e[0] = 1.0;
        std::vector<double> r(nc), dr(nc), rt(nc), drt(nc);
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
            const double t = bands[c].Temperature(l_bg);
            if (!(std::isfinite(l) && t >= bands[c].t_min_K() && t <= bands[c].t_max_K())) {
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
          table.Background(tbg.data(), phi);
          LinePixel p{nc, ns, y.data(), noise.data(), phi, sigma_m[i]};
          if (!detected) {
            // The 1-sigma of X in the thin limit (the noise-equivalent column).
            double info = 0, proj = 0;  // proj: sum_c (y_c / n_c)(a_c / n_c)
            for (std::size_t c = 0; c < nc; ++c) {
              double a = 0;
              for (std::size_t s = 0; s < ns; ++s)
                if (table.has_table(c, s))
                  a += options.composition[s] * p.sigma *
                       table.ThinSlope(c, s, table.ambient_temperature_K(), phi);
              info += (a / noise[c]) * (a / noise[c]);
              proj += (y[c] / noise[c]) * (a / noise[c]);
            }
            out.fraction_sigma[i] = info > 0 ? 1.0 / std::sqrt(info) : 0.0;
            if (options.signed_below_detection && info > 0) out.fraction[i] = proj / info;
            out.status[i] = static_cast<std::int32_t>(PixelStatus::kBelowDetection);
            continue;
          }
          // The pixel's line table, if any.
          const LineTable* line = nullptr;
          if (!lines.empty()) {
            const auto it = std::lower_bound(depths.begin(), depths.end(), sigma_m[i]);
            if (it != depths.end() && *it == sigma_m[i]) line = &lines[it - depths.begin()];
          }
          // chi2 at u = ln X; with rr and drr, the residuals and their slopes.
          auto chi2_at = [&](double u, double* rr, double* drr) {
            if (!line) return model.Chi2(p, std::exp(u), rr, drr);
            line->Eval(u, e.data(), mm.data(), drr ? dm.data() : nullptr);
            double c2 = 0;
            for (std::size_t c = 0; c < nc; ++c) {
              const double rc = (mm[c] - y[c]) / noise[c];
              c2 += rc * rc;
              if (rr) rr[c] = rc;
              if (drr) drr[c] = dm[c] / noise[c];
            }
            return c2;
          };
          // Coarse scan in ln X (the line's contrast need not be monotone in
          // X), at the line table's nodes when there is one; then safeguarded
          // Gauss-Newton from the best node.
          double best_u = u_hi, best = std::numeric_limits<double>::infinity();
          if (line) {
            const int stride =
                std::max(1, static_cast<int>((line->num_nodes() - 1) / (scan_nodes - 1)));
            for (int k = 0;; k = std::min(k + stride, line->num_nodes() - 1)) {
              line->AtNode(k, e.data(), mm.data());
              double c2 = 0;
              for (std::size_t c = 0; c < nc; ++c) {
                const double rc = (mm[c] - y[c]) / noise[c];
                c2 += rc * rc;
              }
              if (c2 < best) {
                best = c2;
                best_u = line->node(k);
              }
              if (k == line->num_nodes() - 1) break;
            }
          } else {
            for (int k = 0; k < scan_nodes; ++k) {
              const double u = u_lo + (u_hi - u_lo) * k / (scan_nodes - 1);
              const double c2 = model.Chi2(p, std::exp(u), nullptr, nullptr);
              if (c2 < best) {
                best = c2;
                best_u = u;
              }
            }
          }
          double u = best_u;
          double chi2 = chi2_at(u, r.data(), dr.data());
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
              const double c2 = chi2_at(un, rt.data(), drt.data());
              if (c2 <= chi2) {
                const double du = un - u;
                u = un;
                chi2 = c2;
                r.swap(rt);
                dr.swap(drt);
                accepted = true;
                // Converged when the step is below 1e-7 in ln X, or below a
                // millionth of ln X's own 1-sigma (1 / sqrt(jj)): on a pixel
                // with no information (sigma_X >> X) the flat chi2 otherwise
                // lets the last bits decide between converged and failed.
                if (std::abs(du) < 1e-7 || std::abs(du) * std::sqrt(jj) < 1e-6) converged = true;
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
          out.status[i] = static_cast<std::int32_t>(!converged ? PixelStatus::kFailed
                                                    : at_bound ? PixelStatus::kAtBound
                                                               : PixelStatus::kConverged);
        }
      },
      options.num_threads, control);
}

}  // namespace qogi
