#include "engine/velocimetry/variational.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "engine/util/portability.h"
#include "engine/velocimetry/image_ops.h"

namespace qogi {
namespace flow_ops {

namespace {

// Smallest Jacobian det(1 + grad w) accepted: below it the map folds over
// and the pixel's data term is dropped for this warp.
constexpr float kMinJacobian = 0.05f;

using Partials = std::array<double, kMaxStripes>;

double Sum(const Partials& p) {
  double s = 0;
  for (double v : p) s += v;
  return s;
}

// Row kernels. Pointers are row starts; the loops run over the row's
// interior [1, n-1) (neighbours up / down are the rows above / below). Plain
// functions with QOGI_RESTRICT parameters so that the compiler vectorises them.

// g = 0.5 c div(a p) (continuity data term, central differences).
QOGI_VELOCIMETRY_KERNEL
void ForwardContRow(int n, const float* QOGI_RESTRICT c, const float* QOGI_RESTRICT a,
                    const float* QOGI_RESTRICT a_up, const float* QOGI_RESTRICT a_dn,
                    const float* QOGI_RESTRICT pu, const float* QOGI_RESTRICT pv_up,
                    const float* QOGI_RESTRICT pv_dn, float* QOGI_RESTRICT g) {
  for (int i = 1; i < n - 1; ++i)
    g[i] = 0.5f * c[i] *
           (a[i + 1] * pu[i + 1] - a[i - 1] * pu[i - 1] + a_dn[i] * pv_dn[i] - a_up[i] * pv_up[i]);
}

// del = ad div p, kap = ac curl p (kap skipped when null).
QOGI_VELOCIMETRY_KERNEL
void DivCurlRow(int n, float ad, float ac, const float* QOGI_RESTRICT pu,
                const float* QOGI_RESTRICT pu_up, const float* QOGI_RESTRICT pu_dn,
                const float* QOGI_RESTRICT pv, const float* QOGI_RESTRICT pv_up,
                const float* QOGI_RESTRICT pv_dn, float* QOGI_RESTRICT del,
                float* QOGI_RESTRICT kap) {
  const float hd = 0.5f * ad, hc = 0.5f * ac;
  for (int i = 1; i < n - 1; ++i) del[i] = hd * (pu[i + 1] - pu[i - 1] + pv_dn[i] - pv_up[i]);
  if (kap)
    for (int i = 1; i < n - 1; ++i) kap[i] = hc * (pv[i + 1] - pv[i - 1] - pu_dn[i] + pu_up[i]);
}

// (ou, ov) = D^T del + C^T kap on the row interior (kap may be null).
QOGI_VELOCIMETRY_KERNEL
void DivCurlAdjointRow(int n, const float* QOGI_RESTRICT del, const float* QOGI_RESTRICT del_up,
                       const float* QOGI_RESTRICT del_dn, const float* QOGI_RESTRICT kap,
                       const float* QOGI_RESTRICT kap_up, const float* QOGI_RESTRICT kap_dn,
                       float* QOGI_RESTRICT ou, float* QOGI_RESTRICT ov) {
  for (int i = 1; i < n - 1; ++i) {
    ou[i] = 0.5f * (del[i - 1] - del[i + 1]);
    ov[i] = 0.5f * (del_up[i] - del_dn[i]);
  }
  if (kap)
    for (int i = 1; i < n - 1; ++i) {
      ou[i] += 0.5f * (kap_dn[i] - kap_up[i]);
      ov[i] += 0.5f * (kap[i - 1] - kap[i + 1]);
    }
}

// (ou, ov) (+)= A^T g + alpha L p on the row interior; returns <p, o> there.
template <bool kContinuity, bool kAccumulate>
QOGI_ALWAYS_INLINE float AdjointRowBody(
    int n, float alpha, const float* QOGI_RESTRICT a, const float* QOGI_RESTRICT b,
    const float* QOGI_RESTRICT g, const float* QOGI_RESTRICT g_up, const float* QOGI_RESTRICT g_dn,
    const float* QOGI_RESTRICT pu, const float* QOGI_RESTRICT pu_up,
    const float* QOGI_RESTRICT pu_dn, const float* QOGI_RESTRICT pv,
    const float* QOGI_RESTRICT pv_up, const float* QOGI_RESTRICT pv_dn, float* QOGI_RESTRICT ou,
    float* QOGI_RESTRICT ov) {
  float dot = 0.f;
  for (int i = 1; i < n - 1; ++i) {
    float su, sv;
    if (kContinuity) {
      su = 0.5f * a[i] * (g[i - 1] - g[i + 1]);
      sv = 0.5f * a[i] * (g_up[i] - g_dn[i]);
    } else {
      su = a[i] * g[i];
      sv = b[i] * g[i];
    }
    su += alpha * (4.f * pu[i] - pu[i - 1] - pu[i + 1] - pu_up[i] - pu_dn[i]);
    sv += alpha * (4.f * pv[i] - pv[i - 1] - pv[i + 1] - pv_up[i] - pv_dn[i]);
    if (kAccumulate) {
      su += ou[i];
      sv += ov[i];
    }
    ou[i] = su;
    ov[i] = sv;
    dot += pu[i] * su + pv[i] * sv;
  }
  return dot;
}

// AdjointRowBody for the data model and accumulation given at run time.
QOGI_VELOCIMETRY_KERNEL
float AdjointRow(bool continuity, bool accumulate, int n, float alpha, const float* QOGI_RESTRICT a,
                 const float* QOGI_RESTRICT b, const float* QOGI_RESTRICT g,
                 const float* QOGI_RESTRICT g_up, const float* QOGI_RESTRICT g_dn,
                 const float* QOGI_RESTRICT pu, const float* QOGI_RESTRICT pu_up,
                 const float* QOGI_RESTRICT pu_dn, const float* QOGI_RESTRICT pv,
                 const float* QOGI_RESTRICT pv_up, const float* QOGI_RESTRICT pv_dn,
                 float* QOGI_RESTRICT ou, float* QOGI_RESTRICT ov) {
  if (continuity)
    return accumulate ? AdjointRowBody<true, true>(n, alpha, a, b, g, g_up, g_dn, pu, pu_up, pu_dn,
                                                   pv, pv_up, pv_dn, ou, ov)
                      : AdjointRowBody<true, false>(n, alpha, a, b, g, g_up, g_dn, pu, pu_up, pu_dn,
                                                    pv, pv_up, pv_dn, ou, ov);
  return accumulate ? AdjointRowBody<false, true>(n, alpha, a, b, g, g_up, g_dn, pu, pu_up, pu_dn,
                                                  pv, pv_up, pv_dn, ou, ov)
                    : AdjointRowBody<false, false>(n, alpha, a, b, g, g_up, g_dn, pu, pu_up, pu_dn,
                                                   pv, pv_up, pv_dn, ou, ov);
}

// The continuity data term's linearisation on one row (see Linearise):
// a = rho1(x + w0), b = det(1 + grad w0) (at least kMinJacobian, else the
// pixel's weight is 0), r = a b - rho0, w the weight (inside the frame x
// the source mask x row_weight, 0 on the frame's first and last column),
// c = w b^2.
template <bool kSource>
QOGI_ALWAYS_INLINE void ContinuityDataRowBody(
    int n, float row_weight, const uchar* QOGI_RESTRICT pin, const float* QOGI_RESTRICT ps,
    const float* QOGI_RESTRICT ux, const float* QOGI_RESTRICT uy, const float* QOGI_RESTRICT vx,
    const float* QOGI_RESTRICT vy, const float* QOGI_RESTRICT pw, const float* QOGI_RESTRICT p0,
    float* QOGI_RESTRICT a, float* QOGI_RESTRICT b, float* QOGI_RESTRICT r, float* QOGI_RESTRICT w,
    float* QOGI_RESTRICT c) {
  for (int x = 0; x < n; ++x) {
    float weight = pin[x] ? 1.f : 0.f;
    if (kSource) weight *= ps[x];
    float jac = (1.f + ux[x]) * (1.f + vy[x]) - uy[x] * vx[x];
    const bool folded = !(jac > kMinJacobian);
    jac = folded ? kMinJacobian : jac;
    weight = folded ? 0.f : weight * row_weight;
    a[x] = pw[x];
    b[x] = jac;
    r[x] = pw[x] * jac - p0[x];
    w[x] = weight;
    c[x] = weight * jac * jac;
  }
  w[0] = w[n - 1] = c[0] = c[n - 1] = 0.f;
}

// ContinuityDataRowBody with or without a source mask.
QOGI_VELOCIMETRY_KERNEL
void ContinuityDataRow(bool source, int n, float row_weight, const uchar* QOGI_RESTRICT pin,
                       const float* QOGI_RESTRICT ps, const float* QOGI_RESTRICT ux,
                       const float* QOGI_RESTRICT uy, const float* QOGI_RESTRICT vx,
                       const float* QOGI_RESTRICT vy, const float* QOGI_RESTRICT pw,
                       const float* QOGI_RESTRICT p0, float* QOGI_RESTRICT a,
                       float* QOGI_RESTRICT b, float* QOGI_RESTRICT r, float* QOGI_RESTRICT w,
                       float* QOGI_RESTRICT c) {
  if (source)
    ContinuityDataRowBody<true>(n, row_weight, pin, ps, ux, uy, vx, vy, pw, p0, a, b, r, w, c);
  else
    ContinuityDataRowBody<false>(n, row_weight, pin, ps, ux, uy, vx, vy, pw, p0, a, b, r, w, c);
}

// out = 1 where (x, y) + (u, v) lies in [0, wmax] x [0, hmax], else 0
// (NaN: 0), on one row.
QOGI_VELOCIMETRY_KERNEL
void InsideRow(int n, int y, float wmax, float hmax, const float* QOGI_RESTRICT pu,
               const float* QOGI_RESTRICT pv, uchar* QOGI_RESTRICT out) {
  const float fy = static_cast<float>(y);
  for (int x = 0; x < n; ++x) {
    const float px = static_cast<float>(x) + pu[x], py = fy + pv[x];
    out[x] = (px >= 0.f && px <= wmax && py >= 0.f && py <= hmax) ? 1 : 0;
  }
}

// Inverse of the symmetric 2 x 2 block [[d11, d12], [d12, d22]] into (pa, pb,
// pc); a near-singular block falls back to the inverse of its diagonal.
QOGI_ALWAYS_INLINE void InvertBlock(float d11, float d12, float d22, float& pa, float& pb,
                                    float& pc) {
  const float det = d11 * d22 - d12 * d12;
  if (det > 1e-6f * d11 * d22 && det > 0.f) {
    pa = d22 / det;
    pb = -d12 / det;
    pc = d11 / det;
  } else {
    pa = d11 > 0 ? 1.f / d11 : 1.f;
    pb = 0.f;
    pc = d22 > 0 ? 1.f / d22 : 1.f;
  }
}

// The preconditioner's blocks (inverse diagonal blocks of A^T W A + R) on
// columns [x0, x1) of a row, neither of them on the frame's border; reg is the
// regularisation's diagonal there, c_up / c_dn the rows above and below (a
// zero row beyond the frame).
template <bool kContinuity>
QOGI_ALWAYS_INLINE void BlockInverseRowBody(
    int x0, int x1, float reg, const float* QOGI_RESTRICT a, const float* QOGI_RESTRICT b,
    const float* QOGI_RESTRICT w, const float* QOGI_RESTRICT c, const float* QOGI_RESTRICT c_up,
    const float* QOGI_RESTRICT c_dn, float* QOGI_RESTRICT pa, float* QOGI_RESTRICT pb,
    float* QOGI_RESTRICT pc) {
  for (int x = x0; x < x1; ++x) {
    float d11, d12, d22;
    if (!kContinuity) {
      d11 = w[x] * a[x] * a[x];
      d12 = w[x] * a[x] * b[x];
      d22 = w[x] * b[x] * b[x];
    } else {
      const float a2 = a[x] * a[x] * 0.25f;
      d11 = a2 * (c[x - 1] + c[x + 1]);
      d22 = a2 * (c_up[x] + c_dn[x]);
      d12 = 0.f;
    }
    InvertBlock(d11 + reg, d12, d22 + reg, pa[x], pb[x], pc[x]);
  }
}

// BlockInverseRowBody for the data model given at run time.
QOGI_VELOCIMETRY_KERNEL
void BlockInverseRow(bool continuity, int x0, int x1, float reg, const float* QOGI_RESTRICT a,
                     const float* QOGI_RESTRICT b, const float* QOGI_RESTRICT w,
                     const float* QOGI_RESTRICT c, const float* QOGI_RESTRICT c_up,
                     const float* QOGI_RESTRICT c_dn, float* QOGI_RESTRICT pa,
                     float* QOGI_RESTRICT pb, float* QOGI_RESTRICT pc) {
  if (continuity)
    BlockInverseRowBody<true>(x0, x1, reg, a, b, w, c, c_up, c_dn, pa, pb, pc);
  else
    BlockInverseRowBody<false>(x0, x1, reg, a, b, w, c, c_up, c_dn, pa, pb, pc);
}

// Gaussian of the auxiliary fields (G(w), xi, zeta), truncated at 3 sigma
// (OpenCV's default for float images is 4 sigma: a third more taps for
// 0.3 % of the weight).
void GaussianAux(const cv::Mat& src, cv::Mat& dst, double sigma) {
  const int k = 2 * static_cast<int>(std::ceil(3.0 * sigma)) + 1;
  cv::GaussianBlur(src, dst, cv::Size(k, k), sigma, sigma, cv::BORDER_REPLICATE);
}

// res -= step q; returns <res, P res> and <res, res> in rz, rr. kDiagonal:
// the preconditioner's off-diagonal pb is zero (continuity), not read.
template <bool kDiagonal>
QOGI_ALWAYS_INLINE void UpdateResidualBody(int n, float step, const float* QOGI_RESTRICT qu,
                                           const float* QOGI_RESTRICT qv,
                                           const float* QOGI_RESTRICT pa,
                                           const float* QOGI_RESTRICT pb,
                                           const float* QOGI_RESTRICT pc, float* QOGI_RESTRICT ru,
                                           float* QOGI_RESTRICT rv, float& rz, float& rr) {
  float sz = 0.f, sr = 0.f;
  for (int i = 0; i < n; ++i) {
    const float a = ru[i] - step * qu[i], b = rv[i] - step * qv[i];
    ru[i] = a;
    rv[i] = b;
    if (kDiagonal)
      sz += a * (pa[i] * a) + b * (pc[i] * b);
    else
      sz += a * (pa[i] * a + pb[i] * b) + b * (pb[i] * a + pc[i] * b);
    sr += a * a + b * b;
  }
  rz = sz;
  rr = sr;
}

// x += step p; p = P res + beta p.
template <bool kDiagonal>
QOGI_ALWAYS_INLINE void UpdateDirectionBody(
    int n, float step, float beta, const float* QOGI_RESTRICT ru, const float* QOGI_RESTRICT rv,
    const float* QOGI_RESTRICT pa, const float* QOGI_RESTRICT pb, const float* QOGI_RESTRICT pc,
    float* QOGI_RESTRICT xu, float* QOGI_RESTRICT xv, float* QOGI_RESTRICT pu,
    float* QOGI_RESTRICT pv) {
  for (int i = 0; i < n; ++i) {
    xu[i] += step * pu[i];
    xv[i] += step * pv[i];
    if (kDiagonal) {
      pu[i] = pa[i] * ru[i] + beta * pu[i];
      pv[i] = pc[i] * rv[i] + beta * pv[i];
    } else {
      pu[i] = pa[i] * ru[i] + pb[i] * rv[i] + beta * pu[i];
      pv[i] = pb[i] * ru[i] + pc[i] * rv[i] + beta * pv[i];
    }
  }
}

// The two updates for a preconditioner that is diagonal (pb == 0) or not.
// (The kernels with clones are these non-templates: clang's target_clones
// does not take function templates.)
QOGI_VELOCIMETRY_KERNEL
void UpdateResidual(bool diagonal, int n, float step, const float* qu, const float* qv,
                    const float* pa, const float* pb, const float* pc, float* ru, float* rv,
                    float& rz, float& rr) {
  if (diagonal)
    UpdateResidualBody<true>(n, step, qu, qv, pa, pb, pc, ru, rv, rz, rr);
  else
    UpdateResidualBody<false>(n, step, qu, qv, pa, pb, pc, ru, rv, rz, rr);
}

QOGI_VELOCIMETRY_KERNEL
void UpdateDirection(bool diagonal, int n, float step, float beta, const float* ru, const float* rv,
                     const float* pa, const float* pb, const float* pc, float* xu, float* xv,
                     float* pu, float* pv) {
  if (diagonal)
    UpdateDirectionBody<true>(n, step, beta, ru, rv, pa, pb, pc, xu, xv, pu, pv);
  else
    UpdateDirectionBody<false>(n, step, beta, ru, rv, pa, pb, pc, xu, xv, pu, pv);
}

}  // namespace

void VariationalSolver::Solve(const cv::Mat& prev, const cv::Mat& next, const cv::Mat& mask,
                              const cv::Mat& source, bool warm, const VariationalSettings& s,
                              FlowField& flow) {
  data_ = s.data;
  alpha_ = s.alpha;
  alpha_div_ = s.alpha_div;
  alpha_curl_ = s.alpha_curl;
  div_curl_scale_ = s.div_curl_scale;
  smoothness_scale_ = s.smoothness_scale;
  const cv::Size full = prev.size();
  if (!NormalisePair(prev, next, s.scale_over_mask ? mask : cv::Mat(), i0n_, i1n_, flow)) return;
  const int levels = NumLevels(full, s.levels, s.min_level_size);
  const int finest = std::min(s.finest_level, levels - 1);
  BuildPyramid(i0n_, levels, p0_);
  BuildPyramid(i1n_, levels, p1_);
  if (!mask.empty()) {
    cv::Mat m01 = mask != 0;
    m01.convertTo(maskf_, CV_32F, 1.0 / 255.0);
    BuildPyramid(maskf_, levels, pm_);
  } else {
    pm_.clear();
  }
  if (!source.empty()) {
    // Gas may appear where the source mask is: drop the data term on it and
    // on its 4-neighbours (the stencil of div reaches one pixel).
    cv::Mat s01 = source != 0;
    const cv::Mat cross = cv::getStructuringElement(cv::MORPH_CROSS, cv::Size(3, 3));
    cv::dilate(s01, s01, cross);
    s01.convertTo(sourcef_, CV_32F, -1.0 / 255.0, 1.0);  // 0 on the source, 1 elsewhere
    BuildPyramid(sourcef_, levels, ps_);
    for (auto& m : ps_) cv::threshold(m, m, 0.999, 1.0, cv::THRESH_TOZERO);
  } else {
    ps_.clear();
  }
  // With a warm start the large motion is known: only the finest
  // warm_levels levels refine it (all levels when 0).
  const int top =
      (warm && s.warm_levels > 0) ? std::min(levels - 1, finest + s.warm_levels - 1) : levels - 1;
  coarsest_ = levels - 1;
  const cv::Size top_size = p0_[top].size();
  if (warm) {
    ResampleFlow(flow.u, flow.v, top_size, 1.0 / (1 << top), u_, v_);
  } else {
    u_.create(top_size, CV_32FC1);
    v_.create(top_size, CV_32FC1);
    u_.setTo(0);
    v_.setTo(0);
  }
  for (int l = top; l >= finest; --l) {
    if (l < top) {
      ResampleFlow(u_, v_, p0_[l].size(), 2.0, un_, vn_);
      std::swap(u_, un_);
      std::swap(v_, vn_);
    }
    SolveLevel(l, finest, s);
  }
  if (finest > 0) {
    ResampleFlow(u_, v_, full, static_cast<double>(1 << finest), flow.u, flow.v);
  } else {
    u_.copyTo(flow.u);
    v_.copyTo(flow.v);
  }
  FinalResidual(finest, flow, mask);
}

void VariationalSolver::SolveLevel(int level, int finest, const VariationalSettings& s) {
  // Coarser levels cost a quarter per level: give them twice the iterations
  // per level (at most 8x), which carries information across the image (a
  // flux through a featureless stretch of plume) at little cost.
  const int scale = 1 << std::min(3, level - finest);
  const int iterations = s.iterations * scale;
  // The coarsest level sees the largest motion relative to its pixels and
  // costs next to nothing: three times the warps there.
  const int warps = level == coarsest_ ? 3 * s.warps : s.warps;
  W_ = p0_[level].cols;
  H_ = p0_[level].rows;
  const int W = W_, H = H_;
  const std::size_t n = static_cast<std::size_t>(W) * H;
  for (auto* vec : {&a_, &b_, &w_, &r_, &c_, &g_, &del_, &kap_, &pre_a_, &pre_b_, &pre_c_})
    vec->resize(n);
  // Without the curl term the passes neither write kap nor add it (it stays 0).
  if (!(alpha_curl_ > 0)) std::fill(kap_.begin(), kap_.end(), 0.f);
  for (auto* vec : {&x_, &res_, &p_, &q_}) vec->resize(2 * n);
  zero_row_.assign(W, 0.f);
  std::fill(q_.begin(), q_.end(), 0.f);
  float* xu = x_.data();
  float* xv = xu + n;
  float* ru = res_.data();
  float* rv = ru + n;
  float* pu = p_.data();
  float* pv = pu + n;
  float* qu = q_.data();
  float* qv = qu + n;
  const float* pa = pre_a_.data();
  const float* pb = pre_b_.data();
  // The continuity blocks are diagonal (pre_b_ = 0): the updates skip it.
  const bool diagonal = data_ == DataModel::kContinuity;
  const float* pc = pre_c_.data();

  for (int warp = 0; warp < warps; ++warp) {
    Linearise(level, s);
    // res = -(A^T W r0 + R'(w0)), x = 0, p = P res.
    ForwardPass(u_.ptr<float>(), v_.ptr<float>(), /*rhs=*/true);
    if (smoothness_scale_ > 0) {
      // The smoothness acts on w - G(w0): its gradient at w = w0 is alpha L
      // (w0 - G(w0)), which AdjointPass forms from its argument (the data and
      // div-curl parts come from g, del, kap of the pass above).
      const double sigma = smoothness_scale_ / static_cast<double>(1 << level);
      GaussianAux(u_, smooth_u_, sigma);
      GaussianAux(v_, smooth_v_, sigma);
      cv::subtract(u_, smooth_u_, smooth_u_);
      cv::subtract(v_, smooth_v_, smooth_v_);
      AdjointPass(smooth_u_.ptr<float>(), smooth_v_.ptr<float>(), ru, rv);
    } else {
      AdjointPass(u_.ptr<float>(), v_.ptr<float>(), ru, rv);
    }
    Partials prz{}, prr{};
    ParallelStripes(H, W, [&](int st, int y0, int y1) {
      const std::size_t b = static_cast<std::size_t>(y0) * W;
      const int len = (y1 - y0) * W;
      for (int i = 0; i < len; ++i) {
        ru[b + i] = -ru[b + i];
        rv[b + i] = -rv[b + i];
      }
      std::fill(xu + b, xu + b + len, 0.f);
      std::fill(xv + b, xv + b + len, 0.f);
      std::fill(pu + b, pu + b + len, 0.f);
      std::fill(pv + b, pv + b + len, 0.f);
      float rz = 0.f, rr = 0.f;
      UpdateResidual(diagonal, len, 0.f, qu + b, qv + b, pa + b, pb + b, pc + b, ru + b, rv + b, rz,
                     rr);
      UpdateDirection(diagonal, len, 0.f, 0.f, ru + b, rv + b, pa + b, pb + b, pc + b, xu + b,
                      xv + b, pu + b, pv + b);
      prz[st] = rz;
      prr[st] = rr;
    });
    double rz = Sum(prz);
    const double bb = Sum(prr);
    if (!(bb > 0)) continue;
    const double stop = s.tolerance * s.tolerance * bb;
    for (int it = 0; it < iterations; ++it) {
      ForwardPass(pu, pv, /*rhs=*/false);
      const double pq = AdjointPass(pu, pv, qu, qv);
      if (!(pq > 0)) break;
      const float step = static_cast<float>(rz / pq);
      Partials pz{}, pr{};
      ParallelStripes(H, W, [&](int st, int y0, int y1) {
        const std::size_t b = static_cast<std::size_t>(y0) * W;
        float z = 0.f, r = 0.f;
        UpdateResidual(diagonal, (y1 - y0) * W, step, qu + b, qv + b, pa + b, pb + b, pc + b,
                       ru + b, rv + b, z, r);
        pz[st] = z;
        pr[st] = r;
      });
      const bool done = Sum(pr) < stop || it + 1 == iterations;
      const double rz_new = Sum(pz);
      const float beta = done ? 0.f : static_cast<float>(rz_new / rz);
      rz = rz_new;
      // x += step p (and, unless done, the next search direction).
      ParallelStripes(H, W, [&](int, int y0, int y1) {
        const std::size_t b = static_cast<std::size_t>(y0) * W;
        UpdateDirection(diagonal, (y1 - y0) * W, step, beta, ru + b, rv + b, pa + b, pb + b, pc + b,
                        xu + b, xv + b, pu + b, pv + b);
      });
      if (done) break;
    }
    float* fu = u_.ptr<float>();
    float* fv = v_.ptr<float>();
    ParallelStripes(H, W, [&](int, int y0, int y1) {
      for (std::size_t k = static_cast<std::size_t>(y0) * W; k < static_cast<std::size_t>(y1) * W;
           ++k) {
        fu[k] += xu[k];
        fv[k] += xv[k];
      }
    });
  }
}

void VariationalSolver::Linearise(int level, const VariationalSettings& s) {
  const cv::Mat& i0 = p0_[level];
  const cv::Mat& i1 = p1_[level];
  const int W = W_, H = H_;
  Warp(i1, u_, v_, warped_, &inside_);
  if (data_ == DataModel::kBrightness) {
    FivePointGradient(i0, g0x_, g0y_);
    FivePointGradient(warped_, gx_, gy_);
  } else {
    CentralGradient(u_, ux_, uy_);
    CentralGradient(v_, vx_, vy_);
  }
  // Data weights. Brightness: inside the gas mask. Continuity: everywhere
  // (the equation holds wherever the gas is or is not, so the mask only
  // marks the valid output) except on the source and the frame's border ring,
  // where gas may enter or leave the image.
  const bool cont = data_ == DataModel::kContinuity;
  const bool has_mask = !pm_.empty() && !cont;
  const bool has_source = !ps_.empty() && cont;
  ParallelRows(H, W, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* p0 = i0.ptr<float>(y);
      const float* pw = warped_.ptr<float>(y);
      const uchar* pin = inside_.ptr<uchar>(y);
      const float* pm = has_mask ? pm_[level].ptr<float>(y) : nullptr;
      const float* ps = has_source ? ps_[level].ptr<float>(y) : nullptr;
      const std::size_t row = static_cast<std::size_t>(y) * W;
      float* a = a_.data() + row;
      float* b = b_.data() + row;
      float* r = r_.data() + row;
      float* w = w_.data() + row;
      float* c = c_.data() + row;
      if (!cont) {
        const float* g0x = g0x_.ptr<float>(y);
        const float* g0y = g0y_.ptr<float>(y);
        const float* gx = gx_.ptr<float>(y);
        const float* gy = gy_.ptr<float>(y);
        for (int x = 0; x < W; ++x) {
          float weight = pin[x] ? 1.f : 0.f;
          if (pm) weight *= pm[x];
          a[x] = 0.5f * (g0x[x] + gx[x]);
          b[x] = 0.5f * (g0y[x] + gy[x]);
          r[x] = pw[x] - p0[x];
          w[x] = weight;
          c[x] = weight * b[x] * b[x];
        }
        continue;
      }
      const float* ux = ux_.ptr<float>(y);
      const float* uy = uy_.ptr<float>(y);
      const float* vx = vx_.ptr<float>(y);
      const float* vy = vy_.ptr<float>(y);
      const float row_weight = (y == 0 || y == H - 1) ? 0.f : 1.f;
      ContinuityDataRow(ps != nullptr, W, row_weight, pin, ps, ux, uy, vx, vy, pw, p0, a, b, r, w,
                        c);
    }
  });
  // Inverse of the 2 x 2 diagonal blocks of A^T W A + R.
  const bool has_div = alpha_div_ > 0, has_curl = alpha_curl_ > 0;
  const float half_ad = static_cast<float>(0.5 * alpha_div_);
  const float half_ac = static_cast<float>(0.5 * alpha_curl_);
  const float alpha = static_cast<float>(alpha_);
  const float* zero = zero_row_.data();
  ParallelRows(H, W, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const std::size_t row = static_cast<std::size_t>(y) * W;
      const float* a = a_.data() + row;
      const float* b = b_.data() + row;
      const float* w = w_.data() + row;
      const float* c = c_.data() + row;  // w b^2 (continuity)
      const float* c_up = y > 0 ? c - W : zero;
      const float* c_dn = y < H - 1 ? c + W : zero;
      float* pa = pre_a_.data() + row;
      float* pb = pre_b_.data() + row;
      float* pc = pre_c_.data() + row;
      const int row_nbrs = (y > 0) + (y < H - 1);
      // Interior columns, then the frame's first and last.
      const float reg = alpha * (row_nbrs + 2) + half_ad + half_ac;
      BlockInverseRow(cont, 1, W - 1, reg, a, b, w, c, c_up, c_dn, pa, pb, pc);
      for (const int x : {0, W - 1}) {
        const int nbrs = (x > 0) + (x < W - 1) + row_nbrs;
        const float reg_x = alpha * nbrs + half_ad + half_ac;
        float d11, d12, d22;
        if (!cont) {
          d11 = w[x] * a[x] * a[x];
          d12 = w[x] * a[x] * b[x];
          d22 = w[x] * b[x] * b[x];
        } else {
          const float a2 = a[x] * a[x] * 0.25f;
          d11 = a2 * ((x > 0 ? c[x - 1] : 0.f) + (x < W - 1 ? c[x + 1] : 0.f));
          d22 = a2 * (c_up[x] + c_dn[x]);
          d12 = 0.f;
        }
        InvertBlock(d11 + reg_x, d12, d22 + reg_x, pa[x], pb[x], pc[x]);
      }
    }
  });
  if (!has_div && !has_curl) return;
  // Smooth divergence and vorticity of the current flow: the targets.
  xi_.create(H, W, CV_32FC1);
  zeta_.create(H, W, CV_32FC1);
  const float* fu = u_.ptr<float>();
  const float* fv = v_.ptr<float>();
  ParallelRows(H, W, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      float* pxi = xi_.ptr<float>(y);
      float* pze = zeta_.ptr<float>(y);
      if (y == 0 || y == H - 1) {
        std::fill(pxi, pxi + W, 0.f);
        std::fill(pze, pze + W, 0.f);
        continue;
      }
      pxi[0] = pxi[W - 1] = pze[0] = pze[W - 1] = 0.f;
      const std::size_t row = static_cast<std::size_t>(y) * W;
      DivCurlRow(W, 1.f, 1.f, fu + row, fu + row - W, fu + row + W, fv + row, fv + row - W,
                 fv + row + W, pxi, has_curl ? pze : nullptr);
    }
  });
  const double sigma = div_curl_scale_ / static_cast<double>(1 << level);
  if (sigma >= 0.3) {
    if (has_div) GaussianAux(xi_, xi_, sigma);
    if (has_curl) GaussianAux(zeta_, zeta_, sigma);
  }
}

void VariationalSolver::ForwardPass(const float* pu, const float* pv, bool rhs) {
  const int W = W_, H = H_;
  const bool cont = data_ == DataModel::kContinuity;
  const bool has_div = alpha_div_ > 0, has_curl = alpha_curl_ > 0;
  const bool dc = has_div || has_curl;
  const float ad = static_cast<float>(alpha_div_), ac = static_cast<float>(alpha_curl_);
  const float* a = a_.data();
  const float* b = b_.data();
  const float* c = c_.data();
  const float* w = w_.data();
  const float* r = r_.data();
  float* g = g_.data();
  float* del = del_.data();
  float* kap = kap_.data();
  ParallelStripes(H, W, [&](int, int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const std::size_t row = static_cast<std::size_t>(y) * W;
      float* gr = g + row;
      if (!cont) {
        // Brightness: pointwise, the border included.
        if (rhs) {
          for (int x = 0; x < W; ++x) gr[x] = w[row + x] * r[row + x];
        } else {
          for (int x = 0; x < W; ++x)
            gr[x] = w[row + x] * (a[row + x] * pu[row + x] + b[row + x] * pv[row + x]);
        }
      }
      if (y == 0 || y == H - 1) {
        if (cont) std::fill(gr, gr + W, 0.f);
        if (dc) std::fill(del + row, del + row + W, 0.f);
        if (has_curl) std::fill(kap + row, kap + row + W, 0.f);
        continue;
      }
      if (cont) {
        gr[0] = gr[W - 1] = 0.f;
        if (rhs) {
          for (int x = 1; x < W - 1; ++x) gr[x] = w[row + x] * b[row + x] * r[row + x];
        } else {
          ForwardContRow(W, c + row, a + row, a + row - W, a + row + W, pu + row, pv + row - W,
                         pv + row + W, gr);
        }
      }
      if (dc) {
        // Without the curl term kap stays as SolveLevel zeroed it.
        float* dr = del + row;
        float* kr = has_curl ? kap + row : nullptr;
        dr[0] = dr[W - 1] = 0.f;
        if (kr) kr[0] = kr[W - 1] = 0.f;
        DivCurlRow(W, ad, ac, pu + row, pu + row - W, pu + row + W, pv + row, pv + row - W,
                   pv + row + W, dr, kr);
        if (rhs) {
          const float* pxi = xi_.ptr<float>(y);
          for (int x = 1; x < W - 1; ++x) dr[x] -= ad * pxi[x];
          if (kr) {
            const float* pze = zeta_.ptr<float>(y);
            for (int x = 1; x < W - 1; ++x) kr[x] -= ac * pze[x];
          }
        }
      }
    }
  });
}

double VariationalSolver::AdjointPass(const float* pu, const float* pv, float* ou, float* ov) {
  const int W = W_, H = H_;
  const bool cont = data_ == DataModel::kContinuity;
  const bool has_curl = alpha_curl_ > 0;
  const bool dc = alpha_div_ > 0 || has_curl;
  const float alpha = static_cast<float>(alpha_);
  const float* a = a_.data();
  const float* b = b_.data();
  const float* g = g_.data();
  const float* del = del_.data();
  const float* kap = kap_.data();
  const float* zero = zero_row_.data();
  // Pyramid levels are >= 4 px a side (min_level_size), so every row has an
  // interior and two frame columns.
  CV_Assert(W >= 3 && H >= 2 && static_cast<int>(zero_row_.size()) >= W);
  Partials partial{};
  ParallelStripes(H, W, [&](int st, int y0, int y1) {
    double dot = 0;
    for (int y = y0; y < y1; ++y) {
      const std::size_t row = static_cast<std::size_t>(y) * W;
      // The rows above and below: beyond the frame, a zero row for g, del
      // and kap (the forward pass leaves them 0 on the frame's border ring)
      // and the row itself for p (its difference to the missing neighbour,
      // the Laplacian's natural boundary condition, is 0).
      const bool top = y == 0, bottom = y == H - 1;
      const float* g_up = top ? zero : g + row - W;
      const float* g_dn = bottom ? zero : g + row + W;
      const float* del_up = top ? zero : del + row - W;
      const float* del_dn = bottom ? zero : del + row + W;
      const float* kap_up = top ? zero : kap + row - W;
      const float* kap_dn = bottom ? zero : kap + row + W;
      const float* pu_up = pu + (top ? row : row - W);
      const float* pu_dn = pu + (bottom ? row : row + W);
      const float* pv_up = pv + (top ? row : row - W);
      const float* pv_dn = pv + (bottom ? row : row + W);
      if (dc) {
        DivCurlAdjointRow(W, del + row, del_up, del_dn, has_curl ? kap + row : nullptr, kap_up,
                          kap_dn, ou + row, ov + row);
      }
      const float d =
          AdjointRow(cont, dc, W, alpha, a + row, b + row, g + row, g_up, g_dn, pu + row, pu_up,
                     pu_dn, pv + row, pv_up, pv_dn, ou + row, ov + row);
      dot += d;
      // The frame's first and last column.
      for (const int x : {0, W - 1}) {
        const std::size_t k = row + x;
        const bool left = x > 0, right = x < W - 1;
        float su, sv;
        if (cont) {
          const float gl = left ? g[k - 1] : 0.f, gr = right ? g[k + 1] : 0.f;
          su = 0.5f * a[k] * (gl - gr);
          sv = 0.5f * a[k] * (g_up[x] - g_dn[x]);
        } else {
          su = a[k] * g[k];
          sv = b[k] * g[k];
        }
        float lu = 0.f, lv = 0.f;
        if (left) {
          lu += pu[k] - pu[k - 1];
          lv += pv[k] - pv[k - 1];
        }
        if (right) {
          lu += pu[k] - pu[k + 1];
          lv += pv[k] - pv[k + 1];
        }
        lu += pu[k] - pu_up[x];
        lv += pv[k] - pv_up[x];
        lu += pu[k] - pu_dn[x];
        lv += pv[k] - pv_dn[x];
        su += alpha * lu;
        sv += alpha * lv;
        if (dc) {
          const float dl = left ? del[k - 1] : 0.f, dr = right ? del[k + 1] : 0.f;
          const float kl = left ? kap[k - 1] : 0.f, kr = right ? kap[k + 1] : 0.f;
          su += 0.5f * (dl - dr) + 0.5f * (kap_dn[x] - kap_up[x]);
          sv += 0.5f * (del_up[x] - del_dn[x]) + 0.5f * (kl - kr);
        }
        ou[k] = su;
        ov[k] = sv;
        dot += static_cast<double>(pu[k]) * su + static_cast<double>(pv[k]) * sv;
      }
    }
    partial[st] = dot;
  });
  return Sum(partial);
}

void VariationalSolver::FinalResidual(int level, FlowField& flow, const cv::Mat& mask) {
  // Residual and quality on the finest level solved (cheaper than at full
  // resolution when finest_level > 0), quality interpolated to full size.
  const cv::Mat& i0 = p0_[level];
  const cv::Mat& i1 = p1_[level];
  Warp(i1, u_, v_, warped_, &inside_);
  cv::Mat residual(i0.size(), CV_32FC1);
  cv::Mat valid(i0.size(), CV_8UC1);
  const bool cont = data_ == DataModel::kContinuity;
  if (cont) {
    CentralGradient(u_, ux_, uy_);
    CentralGradient(v_, vx_, vy_);
  }
  const bool has_mask = !pm_.empty();
  const bool has_source = !ps_.empty() && cont;
  double sum_after = 0, sum_before = 0;
  for (int y = 0; y < i0.rows; ++y) {
    const float* p0 = i0.ptr<float>(y);
    const float* p1 = i1.ptr<float>(y);
    const float* pw = warped_.ptr<float>(y);
    const uchar* pin = inside_.ptr<uchar>(y);
    const float* pm = has_mask ? pm_[level].ptr<float>(y) : nullptr;
    const float* ps = has_source ? ps_[level].ptr<float>(y) : nullptr;
    float* pr = residual.ptr<float>(y);
    uchar* pv = valid.ptr<uchar>(y);
    const float* ux = cont ? ux_.ptr<float>(y) : nullptr;
    const float* uy = cont ? uy_.ptr<float>(y) : nullptr;
    const float* vx = cont ? vx_.ptr<float>(y) : nullptr;
    const float* vy = cont ? vy_.ptr<float>(y) : nullptr;
    for (int x = 0; x < i0.cols; ++x) {
      float r;
      if (cont) {
        const float jac = (1.f + ux[x]) * (1.f + vy[x]) - uy[x] * vx[x];
        r = pw[x] * jac - p0[x];
      } else {
        r = pw[x] - p0[x];
      }
      pr[x] = r;
      pv[x] = (pin[x] && (!pm || pm[x] >= 0.5f) && (!ps || ps[x] > 0.f)) ? 1 : 0;
      if (pv[x]) {
        sum_after += std::abs(r);
        sum_before += std::abs(p1[x] - p0[x]);
      }
    }
  }
  flow.residual_ratio =
      sum_before > 0 ? sum_after / sum_before : std::numeric_limits<double>::quiet_NaN();
  if (level == 0) {
    QualityFromResidual(residual, valid, flow.quality);
  } else {
    QualityFromResidual(residual, valid, quality_level_);
    cv::resize(quality_level_, flow.quality, flow.u.size(), 0, 0, cv::INTER_LINEAR);
  }
  // Validity at full resolution: x + w inside the frame, inside the mask.
  const int W = flow.u.cols, H = flow.u.rows;
  for (int y = 0; y < H; ++y)
    InsideRow(W, y, static_cast<float>(W - 1), static_cast<float>(H - 1), flow.u.ptr<float>(y),
              flow.v.ptr<float>(y), flow.valid.ptr<uchar>(y));
  ApplyMask(mask, flow.u, flow.v, flow.valid);
}

}  // namespace flow_ops
}  // namespace qogi
