// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
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
  /// Standard errors of p from the Gauss-Newton covariance s^2 (J'J)^-1 at the solution,
  /// s^2 = (sum of squared plain residuals) / (n - kP). NaN when J'J is singular. With
  /// correlated residuals (model error on a time series) they are optimistic.
  std::array<double, kP> std_error{};
  std::array<bool, kP> at_bound{};  ///< p[k] within 1e-6 (relative) of a bound
};

/// Standard errors sqrt(diag(s^2 (J'J)^-1)) of a least-squares fit with Jacobian J (n x p)
/// and residual sum of squares rss, s^2 = rss / (n - p). NaN entries when J'J is singular
/// or n <= p.
inline Eigen::VectorXd LeastSquaresStdErrors(const Eigen::MatrixXd& J, double rss) {
  const auto n = J.rows(), p = J.cols();
  Eigen::VectorXd se = Eigen::VectorXd::Constant(p, std::numeric_limits<double>::quiet_NaN());
  if (n <= p || !J.allFinite()) return se;
  // Column scaling for conditioning; the covariance is scaled back.
  Eigen::VectorXd scale = J.colwise().norm().transpose();
  for (Eigen::Index k = 0; k < p; ++k) {
    if (!(scale[k] > 0.0)) return se;
  }
  const Eigen::MatrixXd Js = J * scale.cwiseInverse().asDiagonal();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Js);
  if (qr.rank() < p) return se;
  const Eigen::MatrixXd R =
      qr.matrixR().topLeftCorner(p, p).template triangularView<Eigen::Upper>();
  const Eigen::MatrixXd Rinv = R.inverse();
  const Eigen::MatrixXd cov_perm = Rinv * Rinv.transpose();
  const Eigen::MatrixXd cov = qr.colsPermutation() * cov_perm * qr.colsPermutation().transpose();
  const double s2 = rss / static_cast<double>(n - p);
  for (Eigen::Index k = 0; k < p; ++k) se[k] = std::sqrt(s2 * cov(k, k)) / scale[k];
  return se;
}

namespace internal {

// Simulates once per evaluation point (with Jets when Jacobians are needed) and caches the
// trajectory; the per-sample cost functions read the cache, so that a robust loss acts on
// every sample while the simulation runs only once per point.
template <int kP, class Sim>
class TrajectoryCache : public ceres::EvaluationCallback {
 public:
  TrajectoryCache(const Sim& sim, const double* params, double max_abs)
      : sim_(sim), params_(params), max_abs_(max_abs) {}
  void PrepareForEvaluation(bool evaluate_jacobians, bool new_point) override {
    if (!new_point && (!evaluate_jacobians || have_jacobians_)) return;
    Evaluate(evaluate_jacobians);
    // A simulation that diverged (non-finite values or derivatives, or beyond max_abs) is
    // not handed to the optimiser: every sample reports failure and Ceres rejects the step.
    valid = true;
    for (std::size_t i = 0; i < y.size() && valid; ++i) {
      valid = std::isfinite(y[i]) && std::abs(y[i]) <= max_abs_;
      if (evaluate_jacobians) {
        for (int k = 0; k < kP; ++k) valid = valid && std::isfinite(dy[i][k]);
      }
    }
  }
  std::vector<double> y;                   // simulated samples
  std::vector<std::array<double, kP>> dy;  // their derivatives
  bool valid = false;

 private:
  void Evaluate(bool evaluate_jacobians) {
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
  const Sim& sim_;
  const double* params_;
  double max_abs_;
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
    if (!cache_->valid || cache_->y.size() <= i_) return false;
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
/// a ceres::Jet). `lower`/`upper` bound the parameters; `p0` is the start. A point whose
/// simulation is not finite or exceeds `max_abs` in magnitude is rejected (Ceres shrinks
/// its step), so the optimiser never sees a diverged simulation; a start point that is
/// rejected makes the fit fail (converged = false). `use` (empty: every sample) marks the
/// samples that enter the fit with a non-zero entry; the simulation still runs over all of
/// them (samples left out, e.g. after a gap in the log, only carry no residual), and rms,
/// std_error are over the used samples.
template <int kP, class Sim>
TrajectoryFitResult<kP> FitTrajectory(const Sim& sim, const std::vector<double>& measured,
                                      const std::array<double, kP>& p0,
                                      const std::array<double, kP>& lower,
                                      const std::array<double, kP>& upper, double huber_scale,
                                      int max_iterations = 100,
                                      double max_abs = std::numeric_limits<double>::infinity(),
                                      const std::vector<unsigned char>& use = {}) {
  if (!use.empty() && use.size() != measured.size()) {
    throw std::invalid_argument("[FitTrajectory] the sample mask and the data differ in length");
  }
  auto used = [&](std::size_t i) { return use.empty() || use[i] != 0; };
  TrajectoryFitResult<kP> out;
  out.p = p0;
  out.std_error.fill(std::numeric_limits<double>::quiet_NaN());
  internal::TrajectoryCache<kP, Sim> cache(sim, out.p.data(), max_abs);
  ceres::Problem::Options po;
  po.evaluation_callback = &cache;
  ceres::Problem problem(po);
  problem.AddParameterBlock(out.p.data(), kP);
  std::size_t n_used = 0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    if (!used(i)) continue;
    ++n_used;
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
  out.converged = summary.IsSolutionUsable() && summary.termination_type != ceres::FAILURE;
  out.iterations = static_cast<int>(summary.iterations.size());
  cache.PrepareForEvaluation(true, true);
  if (!cache.valid || cache.y.size() != measured.size()) {
    out.converged = false;
    out.rms = std::numeric_limits<double>::quiet_NaN();
    return out;
  }
  double ss = 0.0;
  Eigen::MatrixXd J(static_cast<Eigen::Index>(n_used), kP);
  Eigen::Index row = 0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    if (!used(i)) continue;
    ss += (cache.y[i] - measured[i]) * (cache.y[i] - measured[i]);
    for (int k = 0; k < kP; ++k) J(row, k) = cache.dy[i][k];
    ++row;
  }
  out.rms = n_used == 0 ? 0.0 : std::sqrt(ss / static_cast<double>(n_used));
  const Eigen::VectorXd se = LeastSquaresStdErrors(J, ss);
  for (int k = 0; k < kP; ++k) {
    out.std_error[k] = se[k];
    const double tol = 1e-6 * std::max(1.0, std::abs(out.p[k]));
    out.at_bound[k] = out.p[k] - lower[k] <= tol || upper[k] - out.p[k] <= tol;
  }
  return out;
}

}  // namespace fnmpc::sysid
