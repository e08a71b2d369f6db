#include "engine/inversion/full_model.h"

#include <ceres/ceres.h>

#include <memory>
#include <vector>

namespace qogi {
namespace {

constexpr int kStride = 8;
using Jet8 = ceres::Jet<double, kStride>;

// Residuals (Delta L_c(theta) - y_c) / n_c with every parameter its own block.
struct ContrastResidual {
  const FullModelProblem* p;
  template <typename T>
  bool operator()(T const* const* params, T* residuals) const {
    const std::size_t ns = p->num_species, nc = p->num_channels;
    std::vector<T> x(ns);
    for (std::size_t s = 0; s < ns; ++s) x[s] = params[s][0];
    if (p->tie_ref)
      for (std::size_t s = 0; s < ns; ++s)
        if (p->tie_ref[s] >= 0) x[s] = p->tie_ratio[s] * params[p->tie_ref[s]][0];
    const T tp = params[ns][0];
    const T sigma = params[ns + 1][0];
    const PathT<T> path = p->model->GaussianPath<T>(x.data(), tp, p->ambient_temperature_K, sigma);
    std::vector<T> tbg(nc), out(nc);
    for (std::size_t c = 0; c < nc; ++c) tbg[c] = T(p->background_temperature_K[c]);
    p->model->Contrast<T>(path, tbg.data(), out.data());
    for (std::size_t c = 0; c < nc; ++c)
      residuals[c] = (out[c] - p->measured_contrast[c]) / p->noise[c];
    return true;
  }
};

struct PriorResidual {
  double mean, sigma;
  template <typename T>
  bool operator()(const T* v, T* r) const {
    r[0] = (v[0] - mean) / sigma;
    return true;
  }
};

}  // namespace

void FullModelContrast(const BinnedModel& model, double t_amb, const double* theta,
                       const double* t_bg, double* contrast, double* jacobian) {
  const std::size_t ns = model.num_species(), nc = model.num_channels(), np = ns + 2;
  std::vector<Jet8> th(np);
  for (std::size_t k = 0; k < np; ++k) th[k] = Jet8(theta[k], static_cast<int>(k));
  const PathT<Jet8> path = model.GaussianPath<Jet8>(th.data(), th[ns], t_amb, th[ns + 1]);
  std::vector<Jet8> tbg(nc), out(nc);
  for (std::size_t c = 0; c < nc; ++c) tbg[c] = Jet8(t_bg[c]);
  model.Contrast<Jet8>(path, tbg.data(), out.data());
  for (std::size_t c = 0; c < nc; ++c) {
    contrast[c] = out[c].a;
    if (jacobian)
      for (std::size_t k = 0; k < np; ++k) jacobian[c * np + k] = out[c].v[k];
  }
}

bool SolveFullModel(const FullModelProblem& p, double* theta, int* iterations) {
  const std::size_t ns = p.num_species, np = ns + 2;
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  auto* cost =
      new ceres::DynamicAutoDiffCostFunction<ContrastResidual, kStride>(new ContrastResidual{&p});
  std::vector<double*> blocks(np);
  for (std::size_t k = 0; k < np; ++k) {
    cost->AddParameterBlock(1);
    blocks[k] = &theta[k];
  }
  cost->SetNumResiduals(static_cast<int>(p.num_channels));
  problem.AddResidualBlock(cost, nullptr, blocks);
  for (std::size_t k = 0; k < np; ++k) {
    if (!p.estimated[k]) {
      problem.SetParameterBlockConstant(&theta[k]);
      continue;
    }
    problem.SetParameterLowerBound(&theta[k], 0, p.lower[k]);
    problem.SetParameterUpperBound(&theta[k], 0, p.upper[k]);
    if (p.prior_sigma[k] > 0)
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PriorResidual, 1, 1>(
                                   new PriorResidual{p.prior_mean[k], p.prior_sigma[k]}),
                               nullptr, &theta[k]);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = p.max_iterations;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.function_tolerance = 1e-10;
  so.parameter_tolerance = 1e-10;
  so.gradient_tolerance = 1e-12;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  *iterations = static_cast<int>(summary.iterations.size());
  return summary.termination_type == ceres::CONVERGENCE;
}

}  // namespace qogi
