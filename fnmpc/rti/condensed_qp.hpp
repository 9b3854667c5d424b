// SPDX-License-Identifier: BSD-3-Clause
// The interface to the QP solver (fnmpc/qp): the condensed QP, its solution and solvers.
// With soft state bounds there are two QPs: the QP without slacks (soft bounds made hard),
// which condensing writes and which is tried first, and the soft QP with one slack per stage.
#pragma once

#include <memory>
#include <vector>

#include "fnmpc/qp/dense_qp.hpp"
#include "fnmpc/rti/dimensions.hpp"
#include "fnmpc/rti/rti_settings.hpp"

namespace fnmpc::rti {

class CondensedQp {
 public:
  /// Allocates both QPs, their solutions and solvers, and sets the soft QP's slack part
  /// (slack weights and bounds, the slack columns of the soft rows), which never changes.
  CondensedQp(const RtiDimensions& dims, const RtiSettings& settings);

  /// The QP without slack variables: the one condensing writes (with soft bounds it is
  /// tried first, see Solve), else the only QP.
  qp::DenseQp& hard() { return dims_nsl_ > 0 ? qp_no_slack_ : qp_; }

  /// Whether condensing writes the Cholesky factor L instead of the Hessian H.
  void SetFactorGiven(bool factor_given);

  /// Solves the QP written into hard(): without soft bounds directly; with them the QP
  /// without slacks first, then, when it is infeasible or violates the exact-penalty
  /// condition, the soft QP. The solution (in the soft QP's variables and rows) is
  /// solution().
  qp::QpStatus Solve(const RtiDimensions& dims, const RtiSettings& settings);

  /// Records the unconstrained step du (stage k's increment du[k]) as the QP's solution,
  /// with zero slacks and multipliers, and forgets the solvers' active sets.
  template <class U>
  void SetUnconstrainedSolution(const RtiDimensions& dims, const std::vector<U>& du) {
    for (int k = 0; k < dims.n; ++k) {
      solution_.x.template segment<U::RowsAtCompileTime>(dims.UPos(k)) = du[k];
    }
    ClearAfterUnconstrainedStep(dims);
  }

  [[nodiscard]] const qp::QpSolution& solution() const { return solution_; }

 private:
  bool SolveWithoutSlacks(const RtiDimensions& dims, const RtiSettings& settings);
  void FillSoftQp(const RtiDimensions& dims);
  void ClearAfterUnconstrainedStep(const RtiDimensions& dims);

  int dims_nsl_ = 0;
  qp::DenseQp qp_;
  qp::QpSolution solution_;
  std::unique_ptr<qp::DenseQpSolver> solver_;
  // The QP without slack variables, tried first (SolveWithoutSlacks); only with soft bounds.
  qp::DenseQp qp_no_slack_;
  qp::QpSolution no_slack_solution_;
  std::unique_ptr<qp::DenseQpSolver> no_slack_solver_;
};

}  // namespace fnmpc::rti
