// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <memory>
#include <string_view>

#include "fnmpc/core/eigen_abi.hpp"
#include "fnmpc/core/serialize.hpp"

namespace fnmpc::qp {

/// Sizes of a dense QP, frozen at construction.
struct DenseQpDims {
  int nv = 0;  ///< number of variables
  int nc = 0;  ///< number of general (two-sided) linear constraints
};

/// Dense strictly convex QP
///   minimise   0.5 x' H x + g' x
///   subject to lb  <= x   <= ub      (bounds; +-infinity = absent)
///              lbA <= A x <= ubA     (general constraints; +-infinity = absent)
/// H (nv x nv) symmetric positive definite; A is nc x nv. lb == ub (or lbA == ubA) is
/// an equality. H must be stored full (both triangles).
///
/// Instead of H a caller may give a Cholesky factor of it (h_factor_given = true): the
/// lower triangle of L with H = L L' (the upper triangle and H are then not read). A
/// structure-exploiting caller can form it for less than the factorisation costs (the
/// Riccati condensing of fnmpc/rti does). A diagonal entry of L that is not positive
/// means H is not positive definite (status kNotConvex).
struct DenseQp {
  Eigen::MatrixXd H;
  Eigen::VectorXd g;
  Eigen::MatrixXd A;
  Eigen::VectorXd lb, ub, lbA, ubA;
  Eigen::MatrixXd L;            ///< nv x nv, read only when h_factor_given
  bool h_factor_given = false;  ///< use L instead of H

  explicit DenseQp(const DenseQpDims& dims = {});
  [[nodiscard]] DenseQpDims dims() const {
    return {static_cast<int>(g.size()), static_cast<int>(A.rows())};
  }
};

enum class QpStatus : int {
  kOptimal = 0,         ///< KKT conditions hold to the tolerance
  kInfeasible = 1,      ///< the constraints admit no point (detected by the dual method)
  kMaxIterations = 2,   ///< the iteration limit was reached
  kNotConvex = 3,       ///< H is not (numerically) positive definite
  kNumericalError = 4,  ///< NaN/Inf in the data or a breakdown of the factorisation
  kInvalidInput = 5,    ///< inconsistent bounds (lb > ub) or wrong sizes
};
std::string_view ToString(QpStatus s);

/// Solution and multipliers. Sign convention: the Lagrangian stationarity reads
///   H x + g + y_bounds + A' y_constraints = 0,
/// with y_i >= 0 when the upper side of constraint i is active, y_i <= 0 when the lower
/// side is active, and y_i = 0 when inactive.
struct QpSolution {
  Eigen::VectorXd x;
  Eigen::VectorXd y_bounds;       ///< nv
  Eigen::VectorXd y_constraints;  ///< nc
  int iterations = 0;             ///< active-set changes (adds + drops) in the last solve
  QpStatus status = QpStatus::kNumericalError;
  double objective = 0.0;
  int num_active = 0;           ///< constraints in the final active set (equalities included)
  int num_drops = 0;            ///< drops among `iterations`
  int num_warm_start_adds = 0;  ///< adds among `iterations` taken from the previous active set

  explicit QpSolution(const DenseQpDims& dims = {});
};

/// Settings of the QP solver (scenario keys `controller.qp.*`, docs/scenarios.md; the
/// documentation of each field is in Serialize).
struct QpSettings {
  int max_iterations = 500;
  double tolerance = 1e-10;
  bool warm_start = true;
  bool warm_start_batch = true;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("max_iterations", &max_iterations, IntIn(1, 100000),
             "active-set changes per QP solve");
    a->Visit("tolerance", &tolerance, Positive(), "primal feasibility / dual sign tolerance");
    a->Visit("warm_start", &warm_start, AnyValue(), "start from the previous solve's active set");
    a->Visit("warm_start_batch", &warm_start_batch, AnyValue(),
             "warm start: true = make the whole previous active set active at once and drop "
             "negative multipliers; false = add the previous constraints one by one while each "
             "is a full dual-feasible step");
  }
};

/// Dual active-set solver (Goldfarb-Idnani) for DenseQp, warm-started from the previous
/// active set. Workspace is sized at construction: Solve() performs no heap allocation.
/// Never throws in Solve(): every failure is a status, and x is never NaN on kOptimal.
///
/// Inputs: a DenseQp of the constructor's dims. Outputs: x, multipliers (sign convention
/// of QpSolution), objective and counters. On kInfeasible / kMaxIterations x holds the
/// last (finite) iterate and the multipliers are zero; on the other failures x is zero.
/// Equalities (lb == ub) are made active first and never dropped; linearly dependent,
/// consistent equalities are skipped. The warm start (settings.warm_start) reuses the
/// inequalities active at the end of the last kOptimal solve, see
/// QpSettings::warm_start_batch; the GI iterations that follow make the result
/// independent of the warm start (up to degenerate ties).
class DenseQpSolver {
 public:
  DenseQpSolver(const DenseQpDims& dims, const QpSettings& settings = {});
  QpStatus Solve(const DenseQp& qp, QpSolution* solution);
  /// Forget the active set: the next solve starts cold.
  void ResetWarmStart();
  [[nodiscard]] const DenseQpDims& dims() const { return dims_; }
  [[nodiscard]] const QpSettings& settings() const { return settings_; }

 private:
  DenseQpDims dims_;
  QpSettings settings_;
  // Implementation workspace (factorisations, active set, ...) lives below.
  struct Workspace;
  // Owned workspace, allocated once in the constructor.
  std::unique_ptr<Workspace> ws_;

 public:
  ~DenseQpSolver();
  DenseQpSolver(DenseQpSolver&&) noexcept;
  DenseQpSolver& operator=(DenseQpSolver&&) noexcept;
};

/// Infinity norms of the KKT residuals of (x, y) for qp, for tests and diagnostics:
/// stationarity, primal violation, dual sign violation, complementarity.
struct KktResiduals {
  double stationarity = 0.0;
  double primal = 0.0;
  double dual = 0.0;
  double complementarity = 0.0;
  [[nodiscard]] double Max() const;
};
KktResiduals ComputeKktResiduals(const DenseQp& qp, const QpSolution& solution);

}  // namespace fnmpc::qp
