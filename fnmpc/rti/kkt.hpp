// SPDX-License-Identifier: BSD-3-Clause
// The KKT value of the benchmark spec (docs/benchmark-spec.md) for an RtiSolver's
// iterate with the last QP's multipliers.
#pragma once

#include <algorithm>
#include <cmath>

#include "fnmpc/qp/dense_qp.hpp"
#include "fnmpc/rti/dimensions.hpp"
#include "fnmpc/rti/iterate.hpp"
#include "fnmpc/rti/rti_settings.hpp"
#include "fnmpc/rti/stage_data.hpp"
#include "fnmpc/rti/stage_qp.hpp"
#include "fnmpc/rti/workspace.hpp"

namespace fnmpc::rti {

/// The largest of Lagrangian stationarity, dynamics and initial-state defects, bound
/// violation and complementarity (infinity norms) at the iterate *it, with the QP
/// solution's multipliers; the dynamics multipliers (it->lambda, it->mu) are recovered by a
/// backward recursion on the last linearisation sq. Linearises again at the iterate.
template <class Problem>
double KktValue(const Problem& problem, const RtiSettings& settings, const RtiDimensions& dims,
                const StageData<Problem>& data, const StageQp<Problem>& sq,
                const qp::QpSolution& sol, const Vec<Problem::kNx>& x0, Iterate<Problem>* it,
                RtiWorkspace<Problem>* ws) {
  constexpr int kNx = Problem::kNx, kNu = Problem::kNu, kNy = Problem::kNy, kNyN = Problem::kNyN;
  using X = Vec<kNx>;
  using U = Vec<kNu>;
  using Y = Vec<kNy>;
  using YN = Vec<kNyN>;
  using MX = Mat<kNx, kNx>;
  using MU = Mat<kNx, kNu>;
  const int n = dims.n;
  const std::vector<X>& x = it->x;
  const std::vector<U>& u = it->u;
  std::vector<X>& lambda = it->lambda;
  std::vector<X>& mu = it->mu;
  // Dynamics multipliers from the QP (at its linearisation point).
  std::fill(mu.begin(), mu.end(), X::Zero());
  for (int r = 0; r < dims.nc; ++r)
    mu[dims.rows[r].stage][dims.rows[r].index] += sol.y_constraints[r];
  lambda[n] = sq.q_mat[n] * it->dx[n] + sq.q_vec[n] + mu[n];
  for (int k = n - 1; k >= 1; --k) {
    X l = sq.q_vec[k] + mu[k];
    l.noalias() += sq.q_mat[k] * it->dx[k];
    l.noalias() += sq.s_mat[k].transpose() * it->du[k];
    l.noalias() += sq.a[k].transpose() * lambda[k + 1];
    lambda[k] = l;
  }
  double kkt = (x[0] - x0).template lpNorm<Eigen::Infinity>();
  Y y;
  Mat<kNy, kNx>& yx = *ws->yx;
  Mat<kNy, kNu>& yu = *ws->yu;
  MX a = MX::Zero();  // Discretise writes only the structural nonzeros
  MU b = MU::Zero();
  for (int k = 0; k < n; ++k) {
    const X next = problem.Discretise(x[k], u[k], data.params[k], settings.sample_time,
                                      settings.integrator_steps, &a, &b);
    kkt = std::max(kkt, (next - x[k + 1]).template lpNorm<Eigen::Infinity>());
    problem.StageResidual(x[k], u[k], data.params[k], &y, &yx, &yu);
    const Y wr = data.w.cwiseProduct(y - data.yref[k]);
    // lazyProduct: coefficient-based (GCC 12 reports a false -Waggressive-loop-optimizations
    // in Eigen's GEMV kernel for the larger residuals of the extended problems).
    U gu = yu.transpose().lazyProduct(wr) + b.transpose().lazyProduct(lambda[k + 1]) +
           sol.y_bounds.template segment<kNu>(dims.UPos(k));
    kkt = std::max(kkt, gu.template lpNorm<Eigen::Infinity>());
    if (k >= 1) {
      X gx = yx.transpose().lazyProduct(wr) - lambda[k] + a.transpose().lazyProduct(lambda[k + 1]) +
             mu[k];
      kkt = std::max(kkt, gx.template lpNorm<Eigen::Infinity>());
    }
    for (int i = 0; i < kNu; ++i) {
      kkt = std::max({kkt, data.lbu[k][i] - u[k][i], u[k][i] - data.ubu[k][i]});
      const double yb = sol.y_bounds[dims.UPos(k) + i];
      const double gap = yb > 0 ? data.ubu[k][i] - u[k][i] : u[k][i] - data.lbu[k][i];
      if (yb != 0.0 && std::isfinite(gap)) kkt = std::max(kkt, std::abs(yb * gap));
    }
  }
  {
    YN yn;
    Mat<kNyN, kNx>& ynx = *ws->ynx;
    problem.TerminalResidual(x[n], data.params[n], &yn, &ynx);
    const YN wrn = data.w_n.cwiseProduct(yn - data.yref_n);
    X gx = ynx.transpose().lazyProduct(wrn) - lambda[n] + mu[n];
    kkt = std::max(kkt, gx.template lpNorm<Eigen::Infinity>());
  }
  for (int r = 0; r < dims.nc; ++r) {
    const BoundRow& row = dims.rows[r];
    const double v = x[row.stage][row.index];
    const double lb = data.lbx[row.stage][row.index], ub = data.ubx[row.stage][row.index];
    const double slack = dims.nsl > 0 ? sol.x[dims.nv + row.stage - 1] : 0.0;
    if (row.kind == 0) kkt = std::max({kkt, lb - v, v - ub});
    const double yc = sol.y_constraints[r];
    const double relax = row.kind == 0 ? 0.0 : slack;
    const double gap = yc > 0 ? ub + relax - v : v - (lb - relax);
    if (yc != 0.0 && std::isfinite(gap)) kkt = std::max(kkt, std::abs(yc * gap));
  }
  return kkt;
}

}  // namespace fnmpc::rti
