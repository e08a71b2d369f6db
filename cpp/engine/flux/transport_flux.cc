#include "engine/flux/transport_flux.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "engine/util/check.h"

namespace qogi {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

void CheckCancelled(const RunControl* control) {
  if (control && control->cancelled && control->cancelled()) throw Cancelled();
}

// Lines of the frames along the axis and across it.
std::size_t Lines(FluxAxis axis, std::size_t H, std::size_t W) { return AlongRows(axis) ? H : W; }

void CheckFrames(const float* frames, std::size_t T, std::size_t H, std::size_t W) {
  Require(T >= 3 && H >= 1 && W >= 1, "frames must be a (T, H, W) stack with T >= 3; got (" +
                                          std::to_string(T) + ", " + std::to_string(H) + ", " +
                                          std::to_string(W) + ")");
  Require(frames != nullptr, "frames must not be null");
}

// The source's line in the turned stack (n lines along the axis).
std::size_t SourceLine(double index, FluxAxis axis, std::size_t n) {
  if (std::isnan(index)) return n;
  const double i = std::nearbyint(index);  // half to even, as Python's round
  if (!(i >= 0 && i < double(n))) {
    const char* what = AlongRows(axis) ? "row" : "column";
    throw std::invalid_argument(std::string("source_index must be a ") + what +
                                " inside the frame, 0 ... " + std::to_string(n - 1) + "; got " +
                                FormatNumber(index));
  }
  const auto k = std::size_t(i);
  return axis == FluxAxis::kUp || axis == FluxAxis::kLeft ? k : n - 1 - k;
}

// Per line j, over the pairs: sums of a b, a a and b b with a = A_t(j + d)
// and b = A_{t+1}(j), A (T, H) the line-sum anomalies; each (H - d).
void ShiftProducts(const Matrix& A, std::size_t d, Eigen::VectorXd& ab, Eigen::VectorXd& aa,
                   Eigen::VectorXd& bb) {
  const std::size_t T = A.rows(), H = A.cols(), n = H - d;
  ab.setZero(n);
  aa.setZero(n);
  bb.setZero(n);
  for (std::size_t t = 0; t + 1 < T; ++t) {
    const double* a = A.row(t).data() + d;
    const double* b = A.row(t + 1).data();
    for (std::size_t j = 0; j < n; ++j) {
      ab[j] += a[j] * b[j];
      aa[j] += a[j] * a[j];
      bb[j] += b[j] * b[j];
    }
  }
}

// numpy.convolve(v, ones(L), "same") for odd L: the sum of v over a window
// of L entries; its length is max(len(v), L) (numpy's convention when v is
// the shorter).
Eigen::VectorXd BoxSum(const Eigen::VectorXd& v, std::size_t L) {
  const std::ptrdiff_t N = v.size(), M = std::ptrdiff_t(L);
  const std::ptrdiff_t out_n = std::max(N, M), off = (std::min(N, M) - 1) / 2;
  Eigen::VectorXd out(out_n);
  for (std::ptrdiff_t j = 0; j < out_n; ++j) {
    // full[j + off] = sum of v[i] with 0 <= j + off - i <= M - 1
    const std::ptrdiff_t hi = std::min(N - 1, j + off);
    const std::ptrdiff_t lo = std::max<std::ptrdiff_t>(0, j + off - M + 1);
    double sum = 0.0;
    for (std::ptrdiff_t i = lo; i <= hi; ++i) sum += v[i];
    out[j] = sum;
  }
  return out;
}

// Whole-pixel start values of the level displacements: per level K[i], the
// shift d (K[i] + d <= k_end) that maximises the correlation over time and
// over the lines within half_window of the level of I_{t+1}(j) and
// I_t(j + d) (their temporal anomalies). A plume carried by wind at 15 Hz
// moves tens of lines per frame: Gauss-Newton from d = 1 would stop in the
// first local minimum of the aliased misfit.
Eigen::VectorXd CoarseDisplacements(const Matrix& I, const std::vector<std::size_t>& K,
                                    std::size_t k_end, std::size_t half_window, int num_threads,
                                    const RunControl* control) {
  const std::size_t H = I.cols(), n = K.size();
  Matrix A = I.rowwise() - I.colwise().mean();
  const long span = std::max<long>(long(k_end) - long(K[0]), 1);
  const std::size_t d_max = std::size_t(std::min<long>(span, long(H) - 1));
  // Correlation per shift and level (-inf where not allowed), then the
  // first best shift per level.
  Matrix r(d_max + 1, n);
  ParallelFor(
      d_max + 1, 4,
      [&](std::size_t d0, std::size_t d1) {
        Eigen::VectorXd ab, aa, bb;
        for (std::size_t d = d0; d < d1; ++d) {
          ShiftProducts(A, d, ab, aa, bb);
          const Eigen::VectorXd wab = BoxSum(ab, 2 * half_window + 1);
          const Eigen::VectorXd waa = BoxSum(aa, 2 * half_window + 1);
          const Eigen::VectorXd wbb = BoxSum(bb, 2 * half_window + 1);
          for (std::size_t i = 0; i < n; ++i) {
            const std::size_t k = K[i];
            double v = -kInf;
            if (k < H - d && k + d <= k_end) {
              const double x = wab[k] / std::sqrt(waa[k] * wbb[k]);
              if (std::isfinite(x)) v = x;
            }
            r(d, i) = v;
          }
        }
      },
      num_threads, control);
  Eigen::VectorXd best = Eigen::VectorXd::Constant(n, -kInf), out = Eigen::VectorXd::Ones(n);
  for (std::size_t d = 0; d <= d_max; ++d)
    for (std::size_t i = 0; i < n; ++i)
      if (r(d, i) > best[i]) {
        best[i] = r(d, i);
        out[i] = double(d);
      }
  return out.cwiseMax(0.5);
}

// One whole-pixel displacement for every level: the shift d whose
// correlation of I_{t+1}(j) and I_t(j + d) (temporal anomalies) over all the
// lines j >= K[0] with j + d <= k_end is largest. Where the gas crosses a
// good part of the frame between frames (an 8 m/s wind at 15 Hz: ~52 px
// per frame of 1.3 cm), the levels near the source see little of the
// structures they must match and their own searches lock on slow changes
// (a few px); all the levels together still find the shift.
double CommonDisplacement(const Matrix& I, const std::vector<std::size_t>& K, std::size_t k_end) {
  const std::size_t H = I.cols();
  const Matrix A = I.rowwise() - I.colwise().mean();
  const std::size_t d_max = std::min<std::size_t>(k_end - std::min(K[0], k_end), H - 1);
  double best = -kInf, out = 1.0;
  Eigen::VectorXd ab, aa, bb;
  for (std::size_t d = 0; d <= d_max; ++d) {
    if (k_end < d + K[0] + 2) break;  // fewer than 3 lines left
    ShiftProducts(A, d, ab, aa, bb);
    const std::size_t lo = K[0], hi = std::min<std::size_t>(k_end - d, H - d - 1);
    const double sab = ab.segment(lo, hi - lo + 1).sum(), saa = aa.segment(lo, hi - lo + 1).sum(),
                 sbb = bb.segment(lo, hi - lo + 1).sum();
    const double x = sab / std::sqrt(saa * sbb);
    if (std::isfinite(x) && x > best) {
      best = x;
      out = double(d);
    }
  }
  return std::max(out, 0.5);
}

// The column summed over the lines before level y, C_t(y), and its slope
// dC_t/dy, between the levels by cubic Hermite interpolation: exact at the
// levels (C_t(k) = sum of lines 0 ... k - 1; C has one column more than I),
// with the slope at level k the mean of the two lines it separates (the
// line itself at the ends). C_t is then continuously differentiable in y, so
// the time-of-flight misfit has a continuous derivative in the level
// displacements (linear interpolation's slope, the line's own, jumps at each
// level: Gauss-Newton then stuck to whole-pixel displacements and jumped
// between them as the input moved by a fraction of a pixel). y is clamped to
// [0, n - 1e-9] with n = I.cols().
double Cumulative(const Matrix& C, const Matrix& I, Eigen::Index t, double y,
                  double* slope = nullptr) {
  const Eigen::Index n = I.cols();
  y = std::clamp(y, 0.0, double(n) - 1e-9);
  const double k0 = std::floor(y), f = y - k0;
  const auto k = Eigen::Index(k0);
  auto node_slope = [&](Eigen::Index j) {
    if (j <= 0) return I(t, 0);
    if (j >= n) return I(t, n - 1);
    return 0.5 * (I(t, j - 1) + I(t, j));
  };
  const double c0 = C(t, k), c1 = C(t, k + 1), m0 = node_slope(k), m1 = node_slope(k + 1);
  const double f2 = f * f, f3 = f2 * f;
  if (slope)
    *slope = (6 * f2 - 6 * f) * (c0 - c1) + (3 * f2 - 4 * f + 1) * m0 + (3 * f2 - 2 * f) * m1;
  return (2 * f3 - 3 * f2 + 1) * c0 + (f3 - 2 * f2 + f) * m0 + (-2 * f3 + 3 * f2) * c1 +
         (f3 - f2) * m1;
}

// Whether any of the lines k0 ... k_end - 1 of the line sums I (T, n)
// changes over time (its RMS about its mean > 1e-4 of its mean |value|).
bool Changes(const Matrix& I, std::size_t k0, std::size_t k_end) {
  for (std::size_t k = k0; k < k_end; ++k) {
    const double mean = I.col(k).mean();
    const double sd = std::sqrt((I.col(k).array() - mean).square().mean());
    if (sd > 1e-4 * I.col(k).cwiseAbs().mean()) return true;
  }
  return false;
}

double Median(std::vector<double> v) {
  const std::size_t n = v.size();
  std::sort(v.begin(), v.end());
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Gauss-Newton for the steady level displacements d_i (per nominal frame
// interval) and the outflows O_t in C_t(K_i + r_t d_i) = C_{t+1}(K_i) + O_t
// (r_t: pair t's duration in nominal intervals), each O_t fitted to the
// current levels (variable projection: the reduced system is the Schur
// complement of the O block). `ok`: the levels whose displacement stays
// within the lines before the source.
Eigen::VectorXd RefineLevels(const Matrix& Cs, const Matrix& Is, const Matrix& target,
                             const std::vector<std::size_t>& K, std::size_t k_end,
                             const std::vector<double>& r, const TransportFluxOptions& opt,
                             std::vector<char>& ok, const RunControl* control, Eigen::VectorXd d) {
  const Eigen::Index P = Is.rows() - 1, n = Eigen::Index(K.size());
  const double r_max = *std::max_element(r.begin(), r.end());
  ok.assign(n, 1);
  Matrix g(P, n), e(P, n);
  Eigen::VectorXd okv(n);
  for (int it = 0; it < opt.iterations; ++it) {
    CheckCancelled(control);
    for (Eigen::Index i = 0; i < n; ++i) {
      ok[i] = double(K[i]) + d[i] * r_max <= double(k_end);
      okv[i] = ok[i];
    }
    // d C_t(y) / dd = C_t'(y) r_t
    for (Eigen::Index t = 0; t < P; ++t)
      for (Eigen::Index i = 0; i < n; ++i) {
        double slope = 0.0;
        const double cb = Cumulative(Cs, Is, t, double(K[i]) + d[i] * r[t], &slope);
        g(t, i) = slope * r[t] * okv[i];
        e(t, i) = (cb - target(t, i)) * okv[i];
      }
    const double cnt = std::max(okv.sum(), 1.0);
    // The residual after the best outflows O_t.
    const Eigen::VectorXd mean_e = e.rowwise().sum() / cnt;
    const Matrix res = e - mean_e * okv.transpose();
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
    A.selfadjointView<Eigen::Lower>().rankUpdate(g.transpose(), -1.0 / cnt);
    A.triangularView<Eigen::StrictlyUpper>() = A.transpose();
    A.diagonal() += g.colwise().squaredNorm().transpose();
    A.diagonal().array() += 1e-9 * std::max(A.diagonal().maxCoeff(), 1e-300) + 1e-12;
    const Eigen::VectorXd rhs = -(g.cwiseProduct(res)).colwise().sum().transpose();
    const Eigen::VectorXd step = A.partialPivLu().solve(rhs).cwiseMax(-4.0).cwiseMin(4.0);
    d = (d + step).cwiseMax(0.0);
    if (step.cwiseAbs().maxCoeff() < 1e-4) break;
  }
  for (Eigen::Index i = 0; i < n; ++i) ok[i] = double(K[i]) + d[i] * r_max <= double(k_end);
  return d;
}

// The share of the solved levels' column anomaly that the displacements d
// leave unexplained (see TransportFluxResult): the fit's residual after each
// pair's outflow, squared, over the squared anomaly of its target about its
// mean over the pairs and, as the outflows do for the fit, about each pair's
// mean over the levels (the null model "nothing is carried" gets the same
// outflows), each per degree of freedom: m levels over P pairs leave
// m P - P - m to the residual and (m - 1)(P - 1) to the anomaly, so that few
// levels whose misfit the outflows absorb are not taken as explained. +inf
// with no level solved, or too few to tell.
double Unexplained(const Matrix& C, const Matrix& I, const std::vector<std::size_t>& K,
                   const std::vector<double>& r, const Eigen::VectorXd& d,
                   const std::vector<char>& ok, std::vector<double>* miss_sum = nullptr,
                   std::vector<double>* anomaly_sum = nullptr) {
  const Eigen::Index P = I.rows() - 1, m = Eigen::Index(K.size());
  Matrix e(P, m), a(P, m);
  Eigen::VectorXd outflow = Eigen::VectorXd::Zero(P), common = Eigen::VectorXd::Zero(P);
  double n_ok = 0.0;
  for (Eigen::Index i = 0; i < m; ++i) {
    if (!ok[i]) continue;
    n_ok += 1.0;
    double mean = 0.0;
    for (Eigen::Index t = 0; t < P; ++t) mean += C(t + 1, K[i]);
    mean /= double(P);
    for (Eigen::Index t = 0; t < P; ++t) {
      e(t, i) = Cumulative(C, I, t, double(K[i]) + d[i] * r[t]) - C(t + 1, K[i]);
      a(t, i) = C(t + 1, K[i]) - mean;
      outflow[t] += e(t, i);
      common[t] += a(t, i);
    }
  }
  const double dof = n_ok * double(P) - double(P) - n_ok;
  if (n_ok < 2.0 || dof <= 0.0) return kInf;
  const double per_dof = (n_ok - 1.0) * double(P - 1) / dof;
  outflow /= n_ok;
  common /= n_ok;
  double miss = 0.0, anomaly = 0.0;
  for (Eigen::Index i = 0; i < m; ++i) {
    if (!ok[i]) continue;
    double mi = 0.0, ai = 0.0;
    for (Eigen::Index t = 0; t < P; ++t) {
      mi += (e(t, i) - outflow[t]) * (e(t, i) - outflow[t]);
      ai += (a(t, i) - common[t]) * (a(t, i) - common[t]);
    }
    miss += mi * per_dof;
    anomaly += ai;
    if (miss_sum) (*miss_sum)[K[i]] += mi * per_dof;
    if (anomaly_sum) (*anomaly_sum)[K[i]] += ai;
  }
  return anomaly > 0 ? miss / anomaly : kInf;
}

// The level displacements from `start`, or, without one, from each level's
// own coarse search and from the levels' common shift
// (CommonDisplacement), whichever leaves less of the column unexplained.
Eigen::VectorXd SolveLevels(const Matrix& C, const Matrix& I, const std::vector<std::size_t>& K,
                            std::size_t k_end, const std::vector<double>& r,
                            const TransportFluxOptions& opt, std::vector<char>& ok,
                            const RunControl* control, const Eigen::VectorXd* start = nullptr) {
  const Eigen::Index P = I.rows() - 1, n = Eigen::Index(K.size());
  const double scale = std::max(I.cwiseAbs().maxCoeff(), 1e-300);
  const Matrix Cs = C / scale, Is = I / scale;
  Matrix target(P, n);
  for (Eigen::Index t = 0; t < P; ++t)
    for (Eigen::Index i = 0; i < n; ++i) target(t, i) = Cs(t + 1, K[i]);
  if (start) return RefineLevels(Cs, Is, target, K, k_end, r, opt, ok, control, *start);
  const double median_r = Median(r);
  const Eigen::VectorXd own =
      CoarseDisplacements(I, K, k_end, std::size_t(opt.half_window), opt.num_threads, control) /
      median_r;
  Eigen::VectorXd d = RefineLevels(Cs, Is, target, K, k_end, r, opt, ok, control, own);
  const Eigen::VectorXd common =
      Eigen::VectorXd::Constant(n, CommonDisplacement(I, K, k_end) / median_r);
  if ((common - own).cwiseAbs().maxCoeff() < 0.5) return d;
  std::vector<char> ok_common;
  Eigen::VectorXd d_common =
      RefineLevels(Cs, Is, target, K, k_end, r, opt, ok_common, control, common);
  // Compared on the levels both solved.
  std::vector<char> both(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) both[i] = ok[i] && ok_common[i];
  if (Unexplained(Cs, Is, K, r, d_common, both) < Unexplained(Cs, Is, K, r, d, both)) {
    ok.swap(ok_common);
    return d_common;
  }
  return d;
}

// One window's time of flight (all its frames, I and C (T_w, ...) with its
// T_w - 1 pair durations r): the flux through each level K_i, as the mass
// crossing it summed over the window's pairs, added to flux_sum[K_i] with the
// window's duration added to flux_w[K_i] (so that the flux over the windows
// is the mass crossing over the whole record per nominal interval), and the
// solved displacements likewise. Levels fed from the source take the flux of
// the nearest solved level plus the mean change of the mass between them.
// A window whose line sums do not change adds nothing.
void WindowFlux(const Matrix& I, const Matrix& C, const std::vector<double>& r,
                const std::vector<std::size_t>& K, std::size_t k_end,
                const TransportFluxOptions& options, const RunControl* control,
                const Eigen::VectorXd* start, std::vector<double>& flux_sum,
                std::vector<double>& flux_w, std::vector<double>& disp_sum,
                std::vector<double>& disp_w, std::vector<double>& miss_sum,
                std::vector<double>& anomaly_sum) {
  const Eigen::Index T = I.rows(), P = T - 1, m = Eigen::Index(K.size());
  if (!Changes(I, K[0], k_end)) return;
  std::vector<char> ok;
  const Eigen::VectorXd d = SolveLevels(C, I, K, k_end, r, options, ok, control, start);
  const double r_sum = std::accumulate(r.begin(), r.end(), 0.0);
  Eigen::VectorXd crossed(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    double s = 0.0;
    for (Eigen::Index t = 0; t < P; ++t)
      s += Cumulative(C, I, t, double(K[i]) + d[i] * r[t]) - C(t, K[i]);
    crossed[i] = s;
  }
  Eigen::Index jr = -1;
  for (Eigen::Index i = 0; i < m; ++i)
    if (ok[i]) jr = i;
  if (jr < 0) return;
  Unexplained(C, I, K, r, d, ok, &miss_sum, &anomaly_sum);
  for (Eigen::Index i = 0; i < m; ++i) {
    if (ok[i]) {
      flux_sum[K[i]] += crossed[i];
      disp_sum[K[i]] += d[i] * r_sum;
      disp_w[K[i]] += r_sum;
    } else {
      const double m0 = C(0, K[i]) - C(0, K[jr]), m1 = C(T - 1, K[i]) - C(T - 1, K[jr]);
      flux_sum[K[i]] += crossed[jr] + (m1 - m0);
    }
    flux_w[K[i]] += r_sum;
  }
}

}  // namespace

FluxAxis ParseFluxAxis(const std::string& name) {
  if (name == "up") return FluxAxis::kUp;
  if (name == "down") return FluxAxis::kDown;
  if (name == "left") return FluxAxis::kLeft;
  if (name == "right") return FluxAxis::kRight;
  throw std::invalid_argument(
      "axis must be one of ('up', 'down', 'left', 'right') (the direction the plume leaves "
      "the source in the image); got '" +
      name + "'");
}

const char* FluxAxisName(FluxAxis axis) {
  switch (axis) {
    case FluxAxis::kUp: return "up";
    case FluxAxis::kDown: return "down";
    case FluxAxis::kLeft: return "left";
    case FluxAxis::kRight: return "right";
  }
  return "?";
}

void TransportFluxOptions::Check(std::size_t T, std::size_t H, std::size_t W) const {
  if (!intervals.empty()) {
    bool good = intervals.size() + 1 == T;
    for (double x : intervals) good = good && std::isfinite(x) && x > 0;
    Require(good, "intervals must be " + std::to_string(T - 1) + " positive frame intervals; got " +
                      std::to_string(intervals.size()) + " values");
  }
  Require(window == 0 || window >= 4,
          "window must be 0 (the whole record) or >= 4 frame pairs; got " + std::to_string(window));
  Require(iterations >= 1, "iterations must be >= 1; got " + std::to_string(iterations));
  Require(half_window >= 0, "half_window must be >= 0; got " + std::to_string(half_window));
  Require(mask.empty() || mask.size() == H * W,
          "mask must be empty or hold the frames' " + std::to_string(H) + " x " +
              std::to_string(W) + " pixels; got " + std::to_string(mask.size()) + " values");
  SourceLine(source_index, axis, Lines(axis, H, W));
}

std::vector<double> LineSums(const float* frames, std::size_t T, std::size_t H, std::size_t W,
                             FluxAxis axis, int num_threads, const RunControl* control,
                             const std::uint8_t* mask) {
  // A pixel left out adds 0.0: the sums are those of the frames multiplied
  // by the mask, to the last bit.
  const auto value = [mask](const float* f, std::size_t i) {
    return mask == nullptr || mask[i] ? double(f[i]) : 0.0;
  };
  const std::size_t n = Lines(axis, H, W);
  const bool reversed = axis == FluxAxis::kDown || axis == FluxAxis::kRight;
  std::vector<double> out(T * n, 0.0);
  ParallelFor(
      T, 1,
      [&](std::size_t t0, std::size_t t1) {
        std::vector<double> acc(n);
        for (std::size_t t = t0; t < t1; ++t) {
          const float* f = frames + t * H * W;
          std::fill(acc.begin(), acc.end(), 0.0);
          if (AlongRows(axis)) {
            for (std::size_t y = 0; y < H; ++y) {
              double s = 0.0;
              for (std::size_t x = 0; x < W; ++x) s += value(f, y * W + x);
              acc[y] = s;
            }
          } else {
            for (std::size_t y = 0; y < H; ++y)
              for (std::size_t x = 0; x < W; ++x) acc[x] += value(f, y * W + x);
          }
          double* o = out.data() + t * n;
          for (std::size_t i = 0; i < n; ++i) o[i] = acc[reversed ? n - 1 - i : i];
        }
      },
      num_threads, control);
  return out;
}

TransportFluxResult TransportFlux(const float* frames, std::size_t T, std::size_t H, std::size_t W,
                                  const TransportFluxOptions& options, const RunControl* control) {
  CheckFrames(frames, T, H, W);
  options.Check(T, H, W);
  const FluxAxis axis = options.axis;
  const std::size_t n = Lines(axis, H, W);
  const std::size_t k_end = SourceLine(options.source_index, axis, n);
  bool finite = true;
  for (std::size_t i = 0; i < T * H * W; ++i) finite &= std::isfinite(frames[i]);
  Require(finite, "frames must be finite (replace NaN pixels by 0 or an estimate)");
  std::vector<double> r = options.intervals;
  if (r.empty()) r.assign(T - 1, 1.0);
  const std::vector<double> sums = LineSums(frames, T, H, W, axis, options.num_threads, control,
                                            options.mask.empty() ? nullptr : options.mask.data());
  const Matrix I = Eigen::Map<const Matrix>(sums.data(), T, n);

  // A plume that does not change fits any flux level.
  Require(Changes(I, 0, k_end),
          "the frames do not change over time (a steady plume): its flux level cannot be "
          "measured from the transport of its structures; give frames in which the plume "
          "fluctuates");

  // C_t(k): the column summed over the lines before level k (T, n + 1).
  Matrix C = Matrix::Zero(T, n + 1);
  for (std::size_t t = 0; t < T; ++t)
    for (std::size_t k = 0; k < n; ++k) C(t, k + 1) = C(t, k) + I(t, k);
  const Eigen::VectorXd mean_line = I.colwise().mean().transpose();
  double peak = 0.0;
  for (std::size_t k = 0; k < k_end; ++k) peak = std::max(peak, std::abs(mean_line[k]));
  std::size_t first_gas = k_end;
  for (std::size_t k = 0; k < k_end; ++k)
    if (mean_line[k] > 1e-3 * std::max(peak, 1e-300)) {
      first_gas = k;
      break;
    }

  // At the top of line k: the flux summed over the windows' durations, the
  // durations it was measured over, and the same for the displacement.
  std::vector<double> flux_sum(n + 1, 0.0), flux_w(n + 1, 0.0), disp_sum(n + 1, 0.0),
      disp_w(n + 1, 0.0), miss_sum(n + 1, 0.0), anomaly_sum(n + 1, 0.0);
  if (first_gas < k_end) {
    std::vector<std::size_t> K(k_end + 1 - first_gas);
    std::iota(K.begin(), K.end(), first_gas);
    const std::size_t P = T - 1;
    const std::size_t windows =
        options.window > 0
            ? std::max<std::size_t>(1, std::size_t(std::lround(double(P) / options.window)))
            : 1;
    // Each window's fit starts from the whole record's displacements: a
    // window's own coarse search, on a faint plume's few frames, found
    // displacements of tens of lines (the 2 g/h GF320 lab release read 3.7x).
    Eigen::VectorXd whole;
    if (windows > 1) {
      std::vector<char> ok;
      whole = SolveLevels(C, I, K, k_end, r, options, ok, control);
    }
    for (std::size_t w = 0; w < windows; ++w) {
      // Pairs a ... b - 1 (frames a ... b).
      const std::size_t a = w * P / windows, b = (w + 1) * P / windows;
      const std::vector<double> rw(r.begin() + long(a), r.begin() + long(b));
      WindowFlux(I.middleRows(a, b - a + 1), C.middleRows(a, b - a + 1), rw, K, k_end, options,
                 control, windows > 1 ? &whole : nullptr, flux_sum, flux_w, disp_sum, disp_w,
                 miss_sum, anomaly_sum);
    }
  }
  std::vector<double> flux_b(n + 1, kNaN), disp_b(n + 1, kNaN), miss_b(n + 1, kNaN);
  for (std::size_t k = 0; k <= n; ++k) {
    if (flux_w[k] > 0) flux_b[k] = flux_sum[k] / flux_w[k];
    if (disp_w[k] > 0) disp_b[k] = disp_sum[k] / disp_w[k];
    if (disp_w[k] > 0 && anomaly_sum[k] > 0) miss_b[k] = miss_sum[k] / anomaly_sum[k];
  }
  TransportFluxResult out;
  out.axis = axis;
  out.flux.resize(n);
  out.line_column.resize(n);
  out.velocity.resize(n);
  out.displacement.resize(n);
  out.unexplained.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double f = k < k_end ? 0.5 * (flux_b[k] + flux_b[k + 1]) : kNaN;
    out.flux[k] = f;
    out.line_column[k] = mean_line[k];
    out.velocity[k] = mean_line[k] > 0 ? f / mean_line[k] : kNaN;
    out.displacement[k] = 0.5 * (disp_b[k] + disp_b[k + 1]);
    out.unexplained[k] = 0.5 * (miss_b[k] + miss_b[k + 1]);
  }
  if (axis == FluxAxis::kDown || axis == FluxAxis::kRight)
    for (auto* a :
         {&out.flux, &out.line_column, &out.velocity, &out.displacement, &out.unexplained})
      std::reverse(a->begin(), a->end());
  return out;
}

double TypicalDisplacement(const float* frames, std::size_t T, std::size_t H, std::size_t W,
                           FluxAxis axis, int max_px, int num_threads) {
  CheckFrames(frames, T, H, W);
  Require(max_px >= 2, "max_px must be >= 2; got " + std::to_string(max_px));
  const std::size_t n = Lines(axis, H, W);
  Require(n >= 3, "frames must have at least 3 lines across the axis; got " + std::to_string(n));
  const std::vector<double> sums = LineSums(frames, T, H, W, axis, num_threads);
  const Matrix I = Eigen::Map<const Matrix>(sums.data(), T, n);
  const Matrix A = I.rowwise() - I.colwise().mean();
  const int top = int(std::min<std::size_t>(std::size_t(max_px), n - 2));
  std::vector<double> r(top + 1, -kInf);
  Eigen::VectorXd ab, aa, bb;
  for (int d = 0; d <= top; ++d) {
    ShiftProducts(A, std::size_t(d), ab, aa, bb);
    const double sab = ab.sum(), saa = aa.sum(), sbb = bb.sum();
    if (saa * sbb > 0) r[d] = sab / std::sqrt(saa * sbb);
  }
  const int k = int(std::max_element(r.begin(), r.end()) - r.begin());
  if (!std::isfinite(r[k]) || k >= top) return kNaN;
  if (k == 0) return 0.0;
  const double y0 = r[k - 1], y1 = r[k], y2 = r[k + 1], curv = y0 - 2 * y1 + y2;
  return k + (curv < 0 ? 0.5 * (y0 - y2) / curv : 0.0);
}

}  // namespace qogi
