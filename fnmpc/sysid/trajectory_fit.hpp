// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <vector>

namespace fnmpc::sysid {

/// Robust estimate of the white measurement noise of a sampled signal [unit of y]: the
/// median absolute first difference / (0.6745 sqrt 2). Insensitive to smooth motion and
/// outliers. Returns 0 for fewer than 3 samples.
double NoiseSigma(const std::vector<double>& y);

/// Outcome of FitTrajectory.
template <int kP>
struct TrajectoryFitResult {
  std::array<double, kP> p{};  ///< fitted parameters
  double rms = 0.0;            ///< RMS of the plain (non-robust) residuals [unit of y]
  bool converged = false;      ///< Ceres reported a usable solution
  int iterations = 0;          ///< Ceres iterations
};

namespace internal {

// Simulates once per evaluation point (with Jets when Jacobians are needed) and caches the
// trajectory; the per-sample cost functions read the cache, so that a robust loss acts on
// every sample while the simulation runs only once per point.
template <int kP, class Sim>
class TrajectoryCache : public ceres::EvaluationCallback {
 public:
  TrajectoryCache(const Sim& sim, const double* params) : sim_(sim), params_(params) {}
  void PrepareForEvaluation(bool evaluate_jacobians, bool new_point) override {
    if (!new_point && (!evaluate_jacobians || have_jacobians_)) return;
    if (evaluate_jacobians) {
      using J = ceres::Jet<double, kP>;
      std::array<J, kP> pj;
      for (int k = 0; k < kP; ++k) pj[k] = J(params_[k], k);
      sim_(pj.data(), &yj_);
      y.resize(yj_.size());
      dy.resize(yj_.size());
      for (std::size_t i = 0; i < yj_.size(); ++i) {
        y[i] = yj_[i].a;
        for (int k = 0; k < kP; ++k) dy[i][k] = yj_[i].v[k];
      }
      have_jacobians_ = true;
    } else {
      sim_(params_, &y);
      have_jacobians_ = false;
    }
  }
  std::vector<double> y;                   // simulated samples
  std::vector<std::array<double, kP>> dy;  // their derivatives

 private:
  const Sim& sim_;
  const double* params_;
  std::vector<ceres::Jet<double, kP>> yj_;
  bool have_jacobians_ = false;
};

template <int kP, class Sim>
class SampleCost : public ceres::SizedCostFunction<1, kP> {
 public:
  SampleCost(const TrajectoryCache<kP, Sim>* cache, std::size_t i, double measured)
      : cache_(cache), i_(i), measured_(measured) {}
  bool Evaluate(double const* const* /*parameters*/, double* residuals,
                double** jacobians) const override {
    if (cache_->y.size() <= i_ || !std::isfinite(cache_->y[i_])) return false;
    residuals[0] = cache_->y[i_] - measured_;
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      for (int k = 0; k < kP; ++k) jacobians[0][k] = cache_->dy[i_][k];
    }
    return true;
  }

 private:
  const TrajectoryCache<kP, Sim>* cache_;
  std::size_t i_;
  double measured_;
};

}  // namespace internal

/// Fits the kP parameters of a simulated trajectory to `measured` (same length) by
/// Levenberg-Marquardt with a Huber loss of scale `huber_scale` on every sample (<= 0:
/// plain least squares). `sim` is a functor `template <class T> void operator()(const T* p,
/// std::vector<T>* y) const` that fills y with one value per measured sample (T = double or
/// a ceres::Jet). `lower`/`upper` bound the parameters; `p0` is the start.
template <int kP, class Sim>
TrajectoryFitResult<kP> FitTrajectory(const Sim& sim, const std::vector<double>& measured,
                                      const std::array<double, kP>& p0,
                                      const std::array<double, kP>& lower,
                                      const std::array<double, kP>& upper, double huber_scale,
                                      int max_iterations = 100) {
  TrajectoryFitResult<kP> out;
  out.p = p0;
  internal::TrajectoryCache<kP, Sim> cache(sim, out.p.data());
  ceres::Problem::Options po;
  po.evaluation_callback = &cache;
  ceres::Problem problem(po);
  problem.AddParameterBlock(out.p.data(), kP);
  for (std::size_t i = 0; i < measured.size(); ++i) {
    ceres::LossFunction* loss = huber_scale > 0.0 ? new ceres::HuberLoss(huber_scale) : nullptr;
    problem.AddResidualBlock(new internal::SampleCost<kP, Sim>(&cache, i, measured[i]), loss,
                             out.p.data());
  }
  for (int k = 0; k < kP; ++k) {
    problem.SetParameterLowerBound(out.p.data(), k, lower[k]);
    problem.SetParameterUpperBound(out.p.data(), k, upper[k]);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = max_iterations;
  so.function_tolerance = 1e-10;
  so.parameter_tolerance = 1e-10;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  out.converged = summary.IsSolutionUsable();
  out.iterations = static_cast<int>(summary.iterations.size());
  std::vector<double> y;
  sim(out.p.data(), &y);
  double ss = 0.0;
  for (std::size_t i = 0; i < measured.size(); ++i)
    ss += (y[i] - measured[i]) * (y[i] - measured[i]);
  out.rms = measured.empty() ? 0.0 : std::sqrt(ss / static_cast<double>(measured.size()));
  return out;
}

}  // namespace fnmpc::sysid
