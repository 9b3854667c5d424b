// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/rti/condensed_qp.hpp"

#include <cmath>

#include "fnmpc/core/types.hpp"

namespace fnmpc::rti {

CondensedQp::CondensedQp(const RtiDimensions& dims, const RtiSettings& settings)
    : dims_nsl_(dims.nsl),
      qp_({dims.nz, dims.nc}),
      solution_({dims.nz, dims.nc}),
      solver_(std::make_unique<qp::DenseQpSolver>(qp::DenseQpDims{dims.nz, dims.nc}, settings.qp)) {
  qp_.A.setZero();
  qp_.H.setZero();
  qp_.L.setZero();
  if (dims.nsl > 0) {
    const int nv = dims.nv;
    const qp::DenseQpDims hard{nv, dims.nch};
    qp_no_slack_ = qp::DenseQp(hard);
    no_slack_solution_ = qp::QpSolution(hard);
    no_slack_solver_ = std::make_unique<qp::DenseQpSolver>(hard, settings.qp);
    qp_no_slack_.A.setZero();
    qp_no_slack_.H.setZero();
    qp_no_slack_.L.setZero();
    for (int s = 0; s < dims.nsl; ++s) {
      qp_.H(nv + s, nv + s) = settings.soft_quadratic_weight;
      qp_.L(nv + s, nv + s) = std::sqrt(settings.soft_quadratic_weight);
      qp_.g[nv + s] = settings.soft_linear_weight;
      qp_.lb[nv + s] = 0.0;
      qp_.ub[nv + s] = kInf;
    }
    for (int r = 0; r < dims.nc; ++r) {
      const BoundRow& row = dims.rows[r];
      if (row.kind != 0) qp_.A(r, nv + row.stage - 1) = row.kind == 1 ? 1.0 : -1.0;
    }
  }
}

void CondensedQp::SetFactorGiven(bool factor_given) {
  qp_.h_factor_given = factor_given;
  if (dims_nsl_ > 0) qp_no_slack_.h_factor_given = factor_given;
}

qp::QpStatus CondensedQp::Solve(const RtiDimensions& dims, const RtiSettings& settings) {
  if (dims.nsl == 0) return solver_->Solve(qp_, &solution_);
  if (SolveWithoutSlacks(dims, settings)) return qp::QpStatus::kOptimal;
  FillSoftQp(dims);
  return solver_->Solve(qp_, &solution_);
}

// Soft bounds are rarely violated, and then the QP without slack variables (soft bounds
// made hard) has the soft QP's solution with zero slacks, provided each stage's bound
// multipliers sum to at most the linear penalty (the exact-penalty condition). Trying it
// first saves the N slack variables and the N active-set additions that pin them at zero.
// Returns false (and the full soft QP is solved) when it is infeasible or the condition
// fails.
bool CondensedQp::SolveWithoutSlacks(const RtiDimensions& dims, const RtiSettings& settings) {
  const int nv = dims.nv, nsl = dims.nsl;
  if (no_slack_solver_->Solve(qp_no_slack_, &no_slack_solution_) != qp::QpStatus::kOptimal) {
    return false;
  }
  const qp::QpSolution& hard = no_slack_solution_;
  // Multipliers of the soft QP's rows: a two-sided hard row's goes to the soft row of its
  // active side. Slack bound multiplier of stage k (stationarity in s_k at s_k = 0): the
  // soft rows' multipliers enter with A = +1 (lower, y <= 0) and -1 (upper, y >= 0).
  auto slack_bound = solution_.y_bounds.tail(nsl);
  slack_bound.setConstant(-settings.soft_linear_weight);
  for (int r = 0; r < dims.nc; ++r) {
    const double y = hard.y_constraints[dims.soft_to_hard[r]];
    const int kind = dims.rows[r].kind;
    const double yr = kind == 0 || (kind == 1 && y < 0.0) || (kind == 2 && y > 0.0) ? y : 0.0;
    solution_.y_constraints[r] = yr;
    if (kind != 0) slack_bound[dims.rows[r].stage - 1] += std::abs(yr);
  }
  if (slack_bound.maxCoeff() > 0.0) return false;
  solution_.x.head(nv) = hard.x;
  solution_.x.tail(nsl).setZero();
  solution_.y_bounds.head(nv) = hard.y_bounds;
  solution_.iterations = hard.iterations;
  solution_.status = hard.status;
  solution_.objective = hard.objective;
  solution_.num_active = hard.num_active + nsl;
  solution_.num_drops = hard.num_drops;
  solution_.num_warm_start_adds = hard.num_warm_start_adds;
  return true;
}

// The soft QP from the hard one (its slack part is set in the constructor).
void CondensedQp::FillSoftQp(const RtiDimensions& dims) {
  const int nv = dims.nv;
  const qp::DenseQp& hard = qp_no_slack_;
  qp_.g.head(nv) = hard.g;
  qp_.lb.head(nv) = hard.lb;
  qp_.ub.head(nv) = hard.ub;
  for (int r = 0; r < dims.nc; ++r) {
    const int h = dims.soft_to_hard[r];
    qp_.lbA[r] = dims.rows[r].kind == 2 ? -kInf : hard.lbA[h];
    qp_.ubA[r] = dims.rows[r].kind == 1 ? kInf : hard.ubA[h];
    qp_.A.row(r).head(nv) = hard.A.row(h);
  }
  if (qp_.h_factor_given) {
    qp_.L.topLeftCorner(nv, nv) = hard.L;
  } else {
    qp_.H.topLeftCorner(nv, nv) = hard.H;
  }
}

void CondensedQp::ClearAfterUnconstrainedStep(const RtiDimensions& dims) {
  solution_.x.tail(dims.nsl).setZero();
  solution_.y_bounds.setZero();
  solution_.y_constraints.setZero();
  solution_.iterations = 0;
  solution_.status = qp::QpStatus::kOptimal;
  solution_.objective = kNaN;  // not computed on this path
  solution_.num_active = 0;
  solution_.num_drops = 0;
  solution_.num_warm_start_adds = 0;
  // What the active-set solvers would remember: an empty active set.
  solver_->ResetWarmStart();
  if (no_slack_solver_) no_slack_solver_->ResetWarmStart();
}

}  // namespace fnmpc::rti
