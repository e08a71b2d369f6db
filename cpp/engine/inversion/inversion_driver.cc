// The Inverter's set-up (per-parameter specs, band tables, the path chosen),
// the per-pixel preparation, the merging of two minima, and the row loop
// that tries the guesses, solves and keeps the best.
#include "engine/inversion/inversion.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "engine/inversion/bounded_lm_internal.h"
#include "engine/inversion/full_model.h"
#include "engine/inversion/inversion_internal.h"
#include "engine/optics/planck.h"
#include "engine/util/check.h"

namespace qogi {

using namespace inversion_detail;  // NOLINT: the module's own internals

Inverter::Inverter(std::shared_ptr<const BinnedModel> model,
                   std::shared_ptr<const SceneTable> table, double t_amb, InversionOptions options)
    : model_(std::move(model)),
      table_(std::move(table)),
      t_amb_(t_amb),
      options_(std::move(options)) {
  Require(model_ != nullptr, "the inversion needs a forward model");
  const std::size_t ns = model_->num_species(), nc = model_->num_channels();
  options_.Check(ns, nc);
  CheckInRange(t_amb, model_->min_temperature_K(), model_->max_temperature_K(),
               "ambient_temperature_K (within the cross-section tables)", "K");
  if (table_) {
    Require(&table_->model() == model_.get(), "the scene table was built from another model");
    Require(std::abs(table_->ambient_temperature_K() - t_amb) <= 1e-9 * t_amb,
            "the scene table was built for ambient temperature " +
                FormatNumber(table_->ambient_temperature_K()) + " K, not " + FormatNumber(t_amb) +
                " K; build one for this scene");
  }
  switch (options_.solver) {
    case SolverKind::kAuto: use_table_ = table_ != nullptr; break;
    case SolverKind::kTable:
      Require(table_ != nullptr,
              "solver 'table' needs a scene table (the species overlap "
              "spectrally or none was built); use solver 'full_model'");
      use_table_ = true;
      break;
    case SolverKind::kFullModel: use_table_ = false; break;
  }
  // Resolve the parameter specs.
  const double t_lo = table_ ? table_->min_peak_temperature_K() : model_->min_temperature_K();
  const double t_hi = table_ ? table_->max_peak_temperature_K() : model_->max_temperature_K();
  const double s_hi = table_ ? table_->options().max_sigma_m : 1e3;
  specs_.resize(ns + 2);
  for (std::size_t s = 0; s < ns; ++s) {
    ParameterSpec p = options_.fractions.empty()
                          ? ParameterSpec{ParameterMode::kFree, 1e-3, 0.0, 0.0, 1.0}
                          : options_.fractions[s];
    if (p.lower == 0 && p.upper == 0) p.upper = 1.0;
    specs_[s] = p;
  }
  ParameterSpec& tp = specs_[ns];
  tp = options_.temperature;
  if (tp.value == 0) tp.value = t_amb;
  if (tp.lower == 0 && tp.upper == 0) {
    tp.lower = t_lo;
    tp.upper = t_hi;
  }
  Require(tp.lower >= t_lo - 1e-9 && tp.upper <= t_hi + 1e-9,
          "temperature bounds [" + FormatNumber(tp.lower) + ", " + FormatNumber(tp.upper) +
              "] K must lie inside the tabulated range [" + FormatNumber(t_lo) + ", " +
              FormatNumber(t_hi) + "] K");
  Require(tp.value >= t_lo && tp.value <= t_hi,
          "temperature value " + FormatNumber(tp.value) + " K is outside the tabulated range [" +
              FormatNumber(t_lo) + ", " + FormatNumber(t_hi) + "] K");
  ParameterSpec& sg = specs_[ns + 1];
  sg = options_.sigma;
  if (sg.lower == 0 && sg.upper == 0) {
    sg.lower = 1e-4;
    sg.upper = s_hi;
  }
  Require(sg.upper <= s_hi * (1 + 1e-12),
          "sigma upper bound " + FormatNumber(sg.upper) + " m exceeds the table's max_sigma_m " +
              FormatNumber(s_hi) + " m; build the table with a larger max_sigma_m");
  Require(sg.value <= s_hi * (1 + 1e-12), "sigma value " + FormatNumber(sg.value) +
                                              " m exceeds the table's max_sigma_m " +
                                              FormatNumber(s_hi) + " m");

  // Per-channel band tables and noise.
  const double bg_lo = table_ ? table_->options().min_background_K : 150.0;
  const double bg_hi = table_ ? table_->options().max_background_K : 700.0;
  for (std::size_t c = 0; c < nc; ++c)
    bands_.push_back(BackgroundBandTable(model_->channels()[c], bg_lo, bg_hi));
  netd_.assign(nc, options_.netd_K[0]);
  if (options_.netd_K.size() == nc) netd_ = options_.netd_K;
  for (std::size_t s = 0; s < ns; ++s)
    column_factor_.push_back(model_->molar_masses()[s] * model_->pressure_Pa() /
                             (constants::kAvogadro * constants::kBoltzmann));

  // The one-unknown Newton path: one channel, one free fraction, nothing else estimated.
  int n_est = 0, which = -1;
  for (std::size_t p = 0; p < ns + 2; ++p)
    if (specs_[p].mode == ParameterMode::kFree || specs_[p].mode == ParameterMode::kPrior) {
      ++n_est;
      which = static_cast<int>(p);
    }
  bool ties = false;
  for (std::size_t s = 0; s < ns; ++s) ties = ties || specs_[s].mode == ParameterMode::kTied;
  newton_ = use_table_ && nc == 1 && n_est == 1 && !ties && which < static_cast<int>(ns) &&
            specs_[which].mode == ParameterMode::kFree;
  newton_param_ = which < 0 ? 0 : static_cast<std::size_t>(which);
  // The profile's temperatures: the bounds of T_peak and the table's nodes
  // strictly between them.
  if (use_table_ && !newton_ && options_.cold_start == ColdStart::kProfile &&
      (tp.mode == ParameterMode::kFree || tp.mode == ParameterMode::kPrior)) {
    const double lo = tp.lower, hi = tp.upper;
    const int nt = table_->num_temperature_nodes();
    const double t0 = table_->min_peak_temperature_K();
    const double h = (table_->max_peak_temperature_K() - t0) / (nt - 1);
    slices_.push_back(table_->MakeSlice(lo));
    for (int k = 0; k < nt; ++k) {
      const double tk = t0 + k * h;
      if (tk > lo + 0.25 * h && tk < hi - 0.25 * h) slices_.push_back(table_->MakeSlice(tk));
    }
    slices_.push_back(table_->MakeSlice(hi));
  }
}

double Inverter::ChannelNoise(std::size_t c, double t_bg) const {
  return netd_[c] * bands_[c].Derivative(t_bg);
}

bool Inverter::PreparePixel(const PixelBatch& b, std::size_t f, std::size_t i, Pixel* px) const {
  const std::size_t nc = model_->num_channels(), ns = model_->num_species(), np = ns + 2;
  const std::size_t n = b.num_pixels;
  px->nc = nc;
  px->ns = ns;
  px->np = np;
  // Parameters.
  for (std::size_t p = 0; p < np; ++p) {
    const ParameterSpec& sp = specs_[p];
    double v = sp.value;
    if (p == ns && b.peak_temperature_K) v = b.peak_temperature_K[i];
    if (p == ns + 1 && b.sigma_m) v = b.sigma_m[i];
    px->nominal[p] = v;
    px->est[p] = sp.mode == ParameterMode::kFree || sp.mode == ParameterMode::kPrior;
    px->prior_sigma[p] = sp.mode == ParameterMode::kPrior ? sp.prior_sigma : 0.0;
    px->lower[p] = px->est[p] ? sp.lower : v;
    px->upper[p] = px->est[p] ? sp.upper : v;
    px->theta[p] = v;
  }
  px->has_ties = false;
  for (std::size_t s2 = 0; s2 < ns; ++s2) {
    px->tie_ref[s2] = -1;
    px->tie_ratio[s2] = 0.0;
    if (specs_[s2].mode != ParameterMode::kTied) continue;
    px->has_ties = true;
    px->tie_ref[s2] = specs_[s2].tied_to;
    px->tie_ratio[s2] = specs_[s2].value;
    px->est[s2] = false;
    px->prior_sigma[s2] = 0.0;
  }
  for (std::size_t s2 = 0; s2 < ns; ++s2) {
    const int r = px->tie_ref[s2];
    if (r < 0) continue;
    // The tied fraction must stay <= 1 too.
    px->upper[r] = std::min(px->upper[r], 1.0 / px->tie_ratio[s2]);
  }
  for (std::size_t s2 = 0; s2 < ns; ++s2) {
    const int r = px->tie_ref[s2];
    if (r < 0) continue;
    px->nominal[s2] = px->tie_ratio[s2] * px->nominal[r];
    px->lower[s2] = px->tie_ratio[s2] * px->lower[r];
    px->upper[s2] = px->tie_ratio[s2] * px->upper[r];
    px->theta[s2] = px->nominal[s2];
  }
  bool ok = true;
  const double tp = px->nominal[ns], sg = px->nominal[ns + 1];
  if (!(std::isfinite(tp) && tp >= specs_[ns].lower && tp <= specs_[ns].upper)) ok = false;
  if (!(std::isfinite(sg) && sg > 0 && sg <= specs_[ns + 1].upper)) ok = false;
  // Measured contrast, background and noise.
  const std::size_t fb = b.background_per_frame ? f : 0;
  for (std::size_t c = 0; c < nc; ++c) {
    const double l = b.radiance[(f * nc + c) * n + i];
    double t_bg = 0, l_bg = 0, dl_dt = 0;
    if (b.background_temperature_K) {
      t_bg = b.background_temperature_K[(fb * nc + c) * n + i];
      if (!(std::isfinite(t_bg) && t_bg >= bands_[c].t_min_K() && t_bg <= bands_[c].t_max_K())) {
        ok = false;
        t_bg = bands_[c].t_min_K();
      }
      bands_[c].RadianceAndDerivative(t_bg, &l_bg, &dl_dt);
    } else {
      l_bg = b.background_radiance[(fb * nc + c) * n + i];
      t_bg = bands_[c].Temperature(l_bg);  // NaN when no blackbody gives l_bg
      if (!(t_bg >= bands_[c].t_min_K() && t_bg <= bands_[c].t_max_K())) {
        ok = false;
        t_bg = bands_[c].t_min_K();
      }
      dl_dt = bands_[c].Derivative(t_bg);
    }
    const double y = l - l_bg;
    if (!std::isfinite(y)) ok = false;
    px->y[c] = std::isfinite(y) ? y : 0.0;
    px->tbg[c] = t_bg;
    double noise = netd_[c] * dl_dt;
    if (options_.model_error_fraction > 0) {
      const double me = options_.model_error_fraction * px->y[c];
      noise = std::sqrt(noise * noise + me * me);
    }
    px->noise[c] = noise;
  }
  // Scales: fractions by their start magnitude, T_peak by 10 K, sigma by itself.
  for (std::size_t s = 0; s < ns; ++s) px->scale[s] = 1e-3;
  px->scale[ns] = 10.0;
  px->scale[ns + 1] = std::max(sg, 1e-6);
  return ok;
}

bool Inverter::Distinct(const Pixel& a, const Pixel& b) {
  for (std::size_t p = 0; p < a.np; ++p) {
    if (!a.est[p]) continue;
    const double s = std::sqrt(a.psig[p] * a.psig[p] + b.psig[p] * b.psig[p]);
    if (std::abs(a.theta[p] - b.theta[p]) > 0.5 * s) return true;
  }
  return false;
}

void Inverter::MergeModes(Pixel* a, const Pixel& b) const {
  const std::size_t ns = a->ns, np = a->np;
  if (!Distinct(*a, b)) return;  // the same minimum reached twice
  const double da = a->chi2 + a->prior_chi2, db = b.chi2 + b.prior_chi2;
  if (db - da < 4.0) a->flags |= kFlagAmbiguous;
  // The two minima weighted by their likelihoods exp(-chi2 / 2).
  const double lw = -0.5 * (db - da);
  if (lw < -40) return;
  const double wb = 1.0 / (1.0 + std::exp(-lw)), wa = 1.0 - wb;
  auto spread = [&](double sa, double sb, double va, double vb) {
    return std::sqrt(wa * sa * sa + wb * (sb * sb + (vb - va) * (vb - va)));
  };
  double d[kMaxParams];
  for (std::size_t p = 0; p < np; ++p) d[p] = b.theta[p] - a->theta[p];
  for (std::size_t i = 0; i < np; ++i)
    for (std::size_t j = 0; j < np; ++j)
      a->cov[i * np + j] = wa * a->cov[i * np + j] + wb * (b.cov[i * np + j] + d[i] * d[j]);
  for (std::size_t p = 0; p < np; ++p)
    if (a->est[p] || (p < ns && a->tie_ref[p] >= 0))
      a->psig[p] = std::min(spread(a->psig[p], b.psig[p], a->theta[p], b.theta[p]),
                            std::max(a->upper[p] - a->lower[p], a->psig[p]));
  for (std::size_t s = 0; s < ns; ++s) {
    a->col_sig[s] = spread(a->col_sig[s], b.col_sig[s], a->col[s], b.col[s]);
    a->ppm_sig[s] = spread(a->ppm_sig[s], b.ppm_sig[s], a->ppm[s], b.ppm[s]);
  }
}

void Inverter::WritePixel(const Pixel& px, const InversionOutput& o, std::size_t idx) const {
  const std::size_t ns = px.ns, np = px.np;
  o.status[idx] = static_cast<std::uint8_t>(px.status);
  if (o.bound_mask) o.bound_mask[idx] = px.bound_mask;
  if (o.flags) o.flags[idx] = px.flags;
  if (o.parameters) std::copy(px.theta, px.theta + np, o.parameters + idx * np);
  if (o.parameter_sigma) std::copy(px.psig, px.psig + np, o.parameter_sigma + idx * np);
  if (o.covariance) std::copy(px.cov, px.cov + np * np, o.covariance + idx * np * np);
  if (o.column_density) std::copy(px.col, px.col + ns, o.column_density + idx * ns);
  if (o.column_density_sigma)
    std::copy(px.col_sig, px.col_sig + ns, o.column_density_sigma + idx * ns);
  if (o.path_concentration) std::copy(px.ppm, px.ppm + ns, o.path_concentration + idx * ns);
  if (o.path_concentration_sigma)
    std::copy(px.ppm_sig, px.ppm_sig + ns, o.path_concentration_sigma + idx * ns);
  if (o.chi2) o.chi2[idx] = px.chi2;
  if (o.condition_number) o.condition_number[idx] = px.cond;
  if (o.iterations) o.iterations[idx] = px.iterations;
}

void Inverter::InvertRow(const PixelBatch& b, const InversionOutput& out, std::size_t begin,
                         std::size_t end, Workspace* ws) const {
  const std::size_t nc = model_->num_channels(), np = model_->num_species() + 2;
  const std::size_t n = b.num_pixels;
  for (std::size_t f = 0; f < b.num_frames; ++f) {
    ws->last_ok = false;
    for (std::size_t i = begin; i < end; ++i) {
      const std::size_t idx = f * n + i;
      Pixel px;
      px.iterations = 0;
      std::fill(px.cov, px.cov + kMaxParams * kMaxParams, 0.0);
      std::fill(px.psig, px.psig + kMaxParams, 0.0);
      std::fill(px.col, px.col + kMaxParams, 0.0);
      std::fill(px.col_sig, px.col_sig + kMaxParams, 0.0);
      std::fill(px.ppm, px.ppm + kMaxParams, 0.0);
      std::fill(px.ppm_sig, px.ppm_sig + kMaxParams, 0.0);
      const bool ok = PreparePixel(b, f, i, &px);
      if (!ok) {
        FillFailed(&px);
        WritePixel(px, out, idx);
        ws->last_ok = false;
        continue;
      }
      if (use_table_) {
        table_->Background(px.tbg, ws->phi.data());
        px.phi = ws->phi.data();
      }
      bool below = true;
      for (std::size_t c = 0; c < nc; ++c)
        below = below && std::abs(px.y[c]) < options_.detection_sigma * px.noise[c];
      if (below) {
        FillBelowDetection(&px, ws);
        WritePixel(px, out, idx);
        ws->last_ok = false;
        continue;
      }
      double start[kMaxParams];
      bool warm = false;
      switch (options_.initial_guess) {
        case InitialGuess::kNeighbour:
          if (ws->last_ok && i > begin) {
            std::copy(ws->last_theta, ws->last_theta + np, start);
            warm = true;
          }
          break;
        case InitialGuess::kPrevious:
          if (f > 0 && out.parameters) {
            const std::size_t prev = (f - 1) * n + i;
            const auto st = static_cast<PixelStatus>(out.status[prev]);
            if (st == PixelStatus::kConverged || st == PixelStatus::kAtBound) {
              std::copy(out.parameters + prev * np, out.parameters + (prev + 1) * np, start);
              warm = true;
            }
          }
          break;
        case InitialGuess::kGiven:
          std::copy(b.initial + i * np, b.initial + (i + 1) * np, start);
          warm = std::all_of(start, start + np, [](double v) { return std::isfinite(v); });
          break;
        case InitialGuess::kTable: break;
      }
      if (newton_) {
        SolveNewton(&px, ws);
      } else if (use_table_) {
        const Pixel fresh = px;
        const bool profile = !slices_.empty() && px.est[model_->num_species()];
        auto cold = [&](Pixel* out) {
          // Full solves from the profile's minima (or the coarse lookup's
          // best candidates); the best fit is kept and a distinct second
          // minimum widens the uncertainty.
          int total = 0;
          std::size_t starts = 0;
          if (profile) {
            ProfileGuess(*out, &ws->guesses, &total, ws);
            starts = ws->guesses.size();
          } else {
            TableGuess(*out, &ws->guesses, ws);
            starts = options_.num_starts == 0
                         ? ws->guesses.size()
                         : std::min<std::size_t>(ws->guesses.size(),
                                                 static_cast<std::size_t>(options_.num_starts));
          }
          if (starts == 0) {
            out->status = PixelStatus::kFailed;
            out->iterations = total;
            return;
          }
          const Pixel base = *out;
          std::vector<Pixel>& sol = ws->solutions;
          sol.assign(starts, base);
          for (std::size_t k = 0; k < starts; ++k) {
            SolveTable(&sol[k], ws->guesses[k].th, ws, starts == 1, ws->guesses[k].curvature);
            total += sol[k].iterations;
          }
          std::size_t best = 0;
          for (std::size_t k = 1; k < starts; ++k)
            if (sol[k].solved() &&
                (!sol[best].solved() ||
                 sol[k].chi2 + sol[k].prior_chi2 < sol[best].chi2 + sol[best].prior_chi2))
              best = k;
          if (starts > 1 && sol[best].solved()) {
            // The best minimum converged to full precision, and so is any
            // distinct one within the tolerance of it (which of the two fits
            // best is decided only at full precision).
            const double best_cost = sol[best].chi2 + sol[best].prior_chi2;
            std::size_t chosen = best;
            for (std::size_t k = 0; k < starts; ++k) {
              if (!sol[k].solved()) continue;
              if (k != best &&
                  !(sol[k].chi2 + sol[k].prior_chi2 < best_cost + options_.tolerance_chi2 &&
                    Distinct(sol[k], sol[best])))
                continue;
              Pixel precise = base;
              SolveTable(&precise, sol[k].theta, ws, true, sol[k].curvature);
              total += precise.iterations;
              if (!precise.solved()) continue;
              sol[k] = precise;  // (before the comparison: k may be the chosen one)
              if (precise.chi2 + precise.prior_chi2 < sol[chosen].chi2 + sol[chosen].prior_chi2)
                chosen = k;
            }
            best = chosen;
          }
          *out = sol[best];
          if (out->solved()) {
            // The best other minimum (distinct from the best one), if any.
            for (std::size_t k = 0; k < starts; ++k) {
              if (k == best || !sol[k].solved()) continue;
              MergeModes(out, sol[k]);
              if (out->flags & kFlagAmbiguous) break;
            }
          }
          out->iterations = total;
        };
        if (warm) {
          SolveTable(&px, start, ws, true, ws->last_curvature);
          // A warm start that fails, or whose fit is improbable (it may have
          // reached a local minimum), is retried cold.
          if (!px.solved() || px.chi2 + px.prior_chi2 > FitThreshold(px)) {
            Pixel alt = fresh;
            cold(&alt);
            alt.iterations += px.iterations;
            if (alt.solved() && (!px.solved() || alt.chi2 < px.chi2))
              px = alt;
            else
              px.iterations = alt.iterations;
          }
        } else {
          cold(&px);
        }
      } else {
        SolveFull(&px, warm ? start : nullptr, ws);
      }
      if (px.status == PixelStatus::kFailed) {
        const int it = px.iterations;
        FillFailed(&px);
        px.iterations = it;
      }
      WritePixel(px, out, idx);
      ws->last_ok = px.solved();
      std::copy(px.theta, px.theta + np, ws->last_theta);
      ws->last_curvature = px.curvature;
    }
  }
}

void Inverter::Invert(const PixelBatch& b, const InversionOutput& out,
                      const RunControl* control) const {
  Require(b.num_pixels > 0, "the batch has no pixels");
  Require(b.num_frames >= 1, "num_frames must be >= 1");
  Require(b.radiance != nullptr, "radiance is missing");
  Require((b.background_radiance != nullptr) != (b.background_temperature_K != nullptr),
          "give exactly one of background_radiance and background_temperature_K");
  Require(out.status != nullptr, "the status output is required");
  Require(options_.initial_guess != InitialGuess::kGiven || b.initial != nullptr,
          "initial_guess 'given' needs per-pixel start parameters (initial)");
  const std::size_t chunk = b.row_length > 0 ? b.row_length : 256;
  ParallelFor(
      b.num_pixels, chunk,
      [&](std::size_t lo, std::size_t hi) {
        Workspace ws;
        ws.phi.assign(use_table_ ? table_->background_size() : 0, 0.0);
        InvertRow(b, out, lo, hi, &ws);
      },
      options_.num_threads, control);
}

}  // namespace qogi
