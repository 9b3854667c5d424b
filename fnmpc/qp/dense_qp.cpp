// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/qp/dense_qp.hpp"

#include <Eigen/Householder>
#include <Eigen/Jacobi>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

// Dual active-set method of Goldfarb and Idnani (Math. Programming 27, 1983).
//
// Every half-space is written as n' x >= b:
//   lower bound   x_j >= lb_j    ->  n =  e_j,   b =  lb_j   (sign +1)
//   upper bound   x_j <= ub_j    ->  n = -e_j,   b = -ub_j   (sign -1)
//   general rows  likewise with n = +-A_i'.
// Constraint ids are 0..nv-1 for bounds and nv..nv+nc-1 for general rows. The GI
// multipliers u >= 0 satisfy H x + g = N u, hence y_id = -sign * u.
//
// With H = L L' the method works with J = L^-T Q (Q orthogonal) and an upper triangular R
// such that J' N_active = [R; 0]; J1 = J(:, 0:q), J2 = J(:, q:n). For a candidate
// constraint p: d = J' n_p, primal step z = J2 d2, dual step r = R^-1 d1, and
// n_p' z = |d2|^2. Adding a constraint multiplies Q by one Householder reflection,
// dropping one by Givens rotations (R is updated alike). J is never formed: L^-1, L^-T are
// applied by triangular solves, and Q is kept as the product of its reflections and
// rotations (ProductFormQ). This avoids the O(n^3) inverse of L and the O(n^2) update of a
// dense Q per change when only a few constraints become active, as in MPC.

namespace fnmpc::qp {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// |d2| <= kDependencyTol * |d| means that the new normal lies (numerically) in the span
// of the active normals (measured in the metric of H).
constexpr double kDependencyTol = 1e-10;
// A Cholesky pivot L_ii^2 below kPivotTol * max_i H_ii means H is not numerically PD.
constexpr double kPivotTol = 1e-14;
// Recomputations of (x, u) from the factorisation when no violated constraint remains.
constexpr int kMaxRefinements = 3;

// A full scan of the constraints remembers this many most violated ones; they are tried
// (exact slack re-checked) before the next full scan, which saves passes over A.
constexpr int kCandidates = 8;

// Per-constraint state.
constexpr signed char kInactive = 0;
constexpr signed char kActive = 1;
constexpr signed char kRedundant = 2;  // equality implied by other active equalities
constexpr signed char kDeferred = 3;   // inequality implied by the active set until a drop

// Outcome of an attempt to add one constraint.
enum class AddResult { kAdded, kSkipped, kInfeasible, kMaxIterations };

// An n x n orthogonal matrix Q = Q_d T_1 ... T_s, with Q_d dense (or the identity) and T_t
// Householder reflections diag(I_start, I - tau v v'), v = [1; essential], or Givens
// rotations of the plane (j, j+1). Appending a transform costs O(n - start); applying Q or
// Q' to a vector costs O(sum of the transforms' lengths) while that is below n^2, which is
// when the list is folded into Q_d. A GI solve of an MPC QP typically has a handful of
// active constraints among dozens of variables, so Q is far cheaper in product form than
// updated densely (two passes over n x (n - q) per added constraint).
class ProductFormQ {
 public:
  explicit ProductFormQ(int n)
      : n_(n), dense_(n, n), essentials_(n, 2 * n), transforms_(2 * n), tmp_(n) {}

  /// Q = I.
  void Reset() {
    identity_ = true;
    count_ = 0;
    cost_ = 0;
  }
  /// Q <- Q diag(I_start, I - tau v v'), v = [1; essential] (essential has n - start - 1
  /// entries).
  void AppendReflector(int start, const Eigen::Ref<const Eigen::VectorXd>& essential, double tau) {
    if (count_ == static_cast<int>(transforms_.size())) Fold();
    Transform& t = transforms_[count_];
    t.reflector = true;
    t.start = start;
    t.tau = tau;
    essentials_.col(count_).head(n_ - start - 1) = essential;
    ++count_;
    cost_ += 2 * (n_ - start);
    if (cost_ > n_ * n_) Fold();
  }
  /// Q <- Q G, G the rotation rot of the plane (j, j+1) (Eigen's applyOnTheRight).
  void AppendRotation(int j, const Eigen::JacobiRotation<double>& rot) {
    if (count_ == static_cast<int>(transforms_.size())) Fold();
    Transform& t = transforms_[count_];
    t.reflector = false;
    t.start = j;
    t.rot = rot;
    ++count_;
    cost_ += 6;
    if (cost_ > n_ * n_) Fold();
  }
  /// x <- Q' x = T_s' ... T_1' Q_d' x.
  void ApplyTransposed(Eigen::VectorXd* x) {
    if (!identity_) {
      tmp_.noalias() = dense_.transpose() * *x;
      x->swap(tmp_);
    }
    for (int t = 0; t < count_; ++t) ApplyOne(t, x, /*transposed=*/true);
  }
  /// x <- Q x = Q_d T_1 ... T_s x.
  void Apply(Eigen::VectorXd* x) {
    for (int t = count_ - 1; t >= 0; --t) ApplyOne(t, x, /*transposed=*/false);
    if (!identity_) {
      tmp_.noalias() = dense_ * *x;
      x->swap(tmp_);
    }
  }

 private:
  struct Transform {
    bool reflector = true;
    int start = 0;  // first index of a reflection; j of a rotation
    double tau = 0.0;
    Eigen::JacobiRotation<double> rot;
  };

  // Reflections are symmetric; a rotation's transpose is its adjoint.
  void ApplyOne(int t, Eigen::VectorXd* x, bool transposed) const {
    const Transform& tr = transforms_[t];
    if (tr.reflector) {
      const int m = n_ - tr.start - 1;
      const auto ess = essentials_.col(t).head(m);
      auto tail = x->tail(m);
      const double alpha = tr.tau * ((*x)[tr.start] + ess.dot(tail));
      (*x)[tr.start] -= alpha;
      tail -= alpha * ess;
    } else {
      x->applyOnTheLeft(tr.start, tr.start + 1, transposed ? tr.rot.adjoint() : tr.rot);
    }
  }

  // Q_d <- Q_d T_1 ... T_s, and the list is emptied.
  void Fold() {
    if (identity_) dense_.setIdentity();
    identity_ = false;
    for (int t = 0; t < count_; ++t) {
      const Transform& tr = transforms_[t];
      if (tr.reflector) {
        const int m = n_ - tr.start;
        dense_.rightCols(m).applyHouseholderOnTheRight(essentials_.col(t).head(m - 1), tr.tau,
                                                       tmp_.data());
      } else {
        dense_.applyOnTheRight(tr.start, tr.start + 1, tr.rot);
      }
    }
    count_ = 0;
    cost_ = 0;
  }

  int n_;
  Eigen::MatrixXd dense_;       // Q_d (not read while identity_)
  Eigen::MatrixXd essentials_;  // column t: essential part of reflection t
  std::vector<Transform> transforms_;
  Eigen::VectorXd tmp_;
  bool identity_ = true;
  int count_ = 0;
  int cost_ = 0;  // flops of one application of T_1 ... T_s, roughly
};

}  // namespace

std::string_view ToString(QpStatus s) {
  switch (s) {
    case QpStatus::kOptimal:
      return "optimal";
    case QpStatus::kInfeasible:
      return "infeasible";
    case QpStatus::kMaxIterations:
      return "max_iterations";
    case QpStatus::kNotConvex:
      return "not_convex";
    case QpStatus::kNumericalError:
      return "numerical_error";
    case QpStatus::kInvalidInput:
      return "invalid_input";
  }
  return "unknown";
}

DenseQp::DenseQp(const DenseQpDims& dims)
    : H(Eigen::MatrixXd::Zero(dims.nv, dims.nv)),
      g(Eigen::VectorXd::Zero(dims.nv)),
      A(Eigen::MatrixXd::Zero(dims.nc, dims.nv)),
      lb(Eigen::VectorXd::Constant(dims.nv, -kInfinity)),
      ub(Eigen::VectorXd::Constant(dims.nv, kInfinity)),
      lbA(Eigen::VectorXd::Constant(dims.nc, -kInfinity)),
      ubA(Eigen::VectorXd::Constant(dims.nc, kInfinity)),
      L(Eigen::MatrixXd::Identity(dims.nv, dims.nv)) {}

QpSolution::QpSolution(const DenseQpDims& dims)
    : x(Eigen::VectorXd::Zero(dims.nv)),
      y_bounds(Eigen::VectorXd::Zero(dims.nv)),
      y_constraints(Eigen::VectorXd::Zero(dims.nc)) {}

double KktResiduals::Max() const {
  return std::max(std::max(stationarity, primal), std::max(dual, complementarity));
}

struct DenseQpSolver::Workspace {
  Workspace(const DenseQpDims& dims, const QpSettings& settings);

  QpStatus Run(const DenseQp& qp, QpSolution* sol);

  // Data checks; kOptimal means "valid".
  QpStatus Validate(const DenseQp& qp) const;
  // Lower / upper bound value of constraint id.
  double Lower(int id) const { return id < nv ? problem->lb[id] : problem->lbA[id - nv]; }
  double Upper(int id) const { return id < nv ? problem->ub[id] : problem->ubA[id - nv]; }
  bool IsEquality(int id) const { return Lower(id) == Upper(id); }
  // Right-hand side b of the half-space n' x >= b with n = sign * (e_id or A_id').
  double Rhs(int id, int sign) const { return sign > 0 ? Lower(id) : -Upper(id); }
  double ViolationTol(double b) const { return settings.tolerance * (1.0 + std::abs(b)); }
  // n' x - b at the current x.
  double Slack(int id, int sign) const {
    const double nx = id < nv ? x[id] : problem->A.row(id - nv).dot(x);
    return sign * nx - Rhs(id, sign);
  }

  // Q = I at the first use in a solve.
  void InitQ();
  // d = J' n, z = J2 d2, r = R^-1 d1; returns |d2|^2 and |d|^2. With steps == false
  // only d is computed (enough to append the constraint).
  void ComputeStep(int id, int sign, double* zn, double* dn2, bool steps = true);
  // Index of the blocking active inequality (smallest u_k / r_k with r_k > 0), or -1.
  int BlockingConstraint(double* t1) const;
  void AppendActive(int id, int sign, double u_p);
  void DropActive(int k);
  // One GI major step for constraint (id, sign): partial steps/drops until added.
  // With warm_only no drop is allowed: the constraint is skipped instead.
  AddResult Add(int id, int sign, bool equality, bool warm_only);
  // Most violated inactive constraint (full scan); returns false if none. Also fills the
  // candidate list with the next most violated ones.
  bool MostViolated(int* id, int* sign);
  // Next candidate of the last scan that is still inactive and violated.
  bool NextCandidate(int* id, int* sign);
  // Round-off: inequality multipliers that went below zero are set to zero.
  void ClampMultipliers() {
    for (int j = 0; j < q; ++j) {
      if (!active_eq[j] && u[j] < 0.0) u[j] = 0.0;
    }
  }
  // Recompute x and u from the factorisation of the active set; with clamp, negative
  // inequality multipliers (round-off) are set to zero.
  void Refine(bool clamp);
  // Warm start, batch variant: all previous constraints, then drop negative multipliers.
  AddResult WarmStartBatch();
  // Warm start, sequential variant: previous constraints in order while dual feasible.
  AddResult WarmStartSequential();
  void WriteSolution(QpSolution* sol);

  int nv;
  int nc;
  QpSettings settings;
  const DenseQp* problem = nullptr;  // QP of the current solve

  // Cholesky factor of H (lower triangle; the upper one is not referenced): Factorize's
  // result or the caller's DenseQp::L.
  Eigen::MatrixXd chol;
  const Eigen::MatrixXd* factor = &chol;
  // H = L L' by columns (left-looking); false when a pivot is not positive. Unblocked:
  // for the few dozen variables of a condensed MPC QP, Eigen's blocked LLT spends most of
  // its time in GEMM set-up.
  bool Factorize(const Eigen::MatrixXd& h);
  ProductFormQ Q;     // nv x nv orthogonal, J = L^-T Q
  Eigen::MatrixXd R;  // nv x nv, upper triangular block q x q is used
  Eigen::VectorXd x, d, z, r, u, w, v, lt;
  Eigen::VectorXd lg;  // L^-1 g of the current solve
  Eigen::VectorXd ax;  // nc, A x at the last scan
  std::array<int, kCandidates> cand_id{};
  std::array<int, kCandidates> cand_sign{};
  std::array<double, kCandidates> cand_violation{};
  int cand_count = 0;

  int q = 0;  // number of active constraints
  bool q_ready = false;
  bool has_deferred = false;  // some state is kDeferred
  std::vector<int> active_id, active_sign;
  std::vector<signed char> active_eq;
  std::vector<signed char> state;  // nv + nc

  // Previous solve's active inequalities (warm start).
  std::vector<int> prev_id, prev_sign;
  int prev_count = 0;

  int iterations = 0;
  int drops = 0;
  int warm_adds = 0;
};

DenseQpSolver::Workspace::Workspace(const DenseQpDims& dims, const QpSettings& s)
    : nv(dims.nv),
      nc(dims.nc),
      settings(s),
      chol(dims.nv, dims.nv),
      Q(dims.nv),
      R(dims.nv, dims.nv),
      x(dims.nv),
      d(dims.nv),
      z(dims.nv),
      r(dims.nv),
      u(dims.nv),
      w(dims.nv),
      v(dims.nv),
      lt(dims.nv),
      lg(dims.nv),
      ax(dims.nc),
      active_id(dims.nv),
      active_sign(dims.nv),
      active_eq(dims.nv),
      state(dims.nv + dims.nc),
      prev_id(dims.nv),
      prev_sign(dims.nv) {
  R.setZero();
  x.setZero();
  d.setZero();
  z.setZero();
  r.setZero();
  u.setZero();
  w.setZero();
  v.setZero();
  lt.setZero();
  lg.setZero();
  ax.setZero();
  chol.setIdentity();
}

QpStatus DenseQpSolver::Workspace::Validate(const DenseQp& qp) const {
  if ((!qp.h_factor_given && (qp.H.rows() != nv || qp.H.cols() != nv)) || qp.g.size() != nv ||
      qp.A.rows() != nc || (nc > 0 && qp.A.cols() != nv) || qp.lb.size() != nv ||
      qp.ub.size() != nv || qp.lbA.size() != nc || qp.ubA.size() != nc) {
    return QpStatus::kInvalidInput;
  }
  // Fast path: a vectorised sum is finite iff no entry is NaN/Inf (barring overflow,
  // in which case the exact element-wise check decides).
  const auto finite = [](const auto& m) { return std::isfinite(m.sum()) || m.allFinite(); };
  if (qp.h_factor_given) {
    if (qp.L.rows() != nv || qp.L.cols() != nv) return QpStatus::kInvalidInput;
    for (int j = 0; j < nv; ++j) {
      if (!finite(qp.L.col(j).tail(nv - j))) return QpStatus::kNumericalError;
    }
  } else if (!finite(qp.H)) {
    return QpStatus::kNumericalError;
  }
  if (!finite(qp.g) || (nc > 0 && !finite(qp.A))) return QpStatus::kNumericalError;
  const auto check_sides = [](double lo, double hi) {
    if (std::isnan(lo) || std::isnan(hi)) return QpStatus::kNumericalError;
    if (lo > hi || lo == kInfinity || hi == -kInfinity) return QpStatus::kInvalidInput;
    return QpStatus::kOptimal;
  };
  for (int j = 0; j < nv; ++j) {
    const QpStatus s = check_sides(qp.lb[j], qp.ub[j]);
    if (s != QpStatus::kOptimal) return s;
  }
  for (int i = 0; i < nc; ++i) {
    const QpStatus s = check_sides(qp.lbA[i], qp.ubA[i]);
    if (s != QpStatus::kOptimal) return s;
  }
  return QpStatus::kOptimal;
}

bool DenseQpSolver::Workspace::Factorize(const Eigen::MatrixXd& h) {
  for (int j = 0; j < nv; ++j) {
    const int m = nv - j;
    auto col = chol.col(j).tail(m);
    col = h.col(j).tail(m);
    if (j > 0) col.noalias() -= chol.bottomLeftCorner(m, j) * chol.row(j).head(j).transpose();
    const double pivot = col[0];
    if (!(pivot > 0.0)) return false;
    const double root = std::sqrt(pivot);
    col[0] = root;
    col.tail(m - 1) /= root;
  }
  return true;
}

void DenseQpSolver::Workspace::InitQ() {
  Q.Reset();
  q_ready = true;
}

void DenseQpSolver::Workspace::ComputeStep(int id, int sign, double* zn, double* dn2, bool steps) {
  // lt = L^-1 n; with the leading zeros of n, lt has them too and only the trailing block
  // of L is used (n = +-e_j: rows j..; condensed MPC rows: the inputs before their stage).
  // d = Q' lt.
  const auto& l = *factor;
  int first = 0;
  if (id < nv) {
    lt.setZero();
    lt[id] = static_cast<double>(sign);
    first = id;
  } else {
    lt = static_cast<double>(sign) * problem->A.row(id - nv).transpose();
    while (first < nv - 1 && lt[first] == 0.0) ++first;
  }
  l.bottomRightCorner(nv - first, nv - first)
      .triangularView<Eigen::Lower>()
      .solveInPlace(lt.tail(nv - first));
  d = lt;
  Q.ApplyTransposed(&d);
  const int m = nv - q;
  *dn2 = d.squaredNorm();
  if (!steps) {
    *zn = m > 0 ? d.tail(m).squaredNorm() : 0.0;
    return;
  }
  if (m > 0) {
    z.head(q).setZero();
    z.tail(m) = d.tail(m);
    Q.Apply(&z);
    l.transpose().triangularView<Eigen::Upper>().solveInPlace(z);
    *zn = d.tail(m).squaredNorm();
  } else {
    z.setZero();
    *zn = 0.0;
  }
  if (q > 0) {
    r.head(q) = d.head(q);
    R.topLeftCorner(q, q).triangularView<Eigen::Upper>().solveInPlace(r.head(q));
  }
}

int DenseQpSolver::Workspace::BlockingConstraint(double* t1) const {
  int k = -1;
  double best = kInfinity;
  for (int j = 0; j < q; ++j) {
    if (active_eq[j] || !(r[j] > 0.0)) continue;
    const double t = u[j] / r[j];
    if (t < best) {
      best = t;
      k = j;
    }
  }
  *t1 = best;
  return k;
}

void DenseQpSolver::Workspace::AppendActive(int id, int sign, double u_p) {
  // One Householder reflection P maps d(q:n) onto beta e_1; Q2 <- Q2 P keeps J' n_p = d
  // (one transform appended instead of n - q Givens rotations).
  const int m = nv - q;
  if (m > 1) {
    double tau = 0.0;
    double beta = 0.0;
    d.tail(m).makeHouseholderInPlace(tau, beta);
    Q.AppendReflector(q, d.tail(m - 1), tau);
    d[q] = beta;
    d.tail(m - 1).setZero();
  }
  R.col(q).head(q + 1) = d.head(q + 1);
  active_id[q] = id;
  active_sign[q] = sign;
  active_eq[q] = IsEquality(id) ? 1 : 0;
  u[q] = u_p;
  state[id] = kActive;
  ++q;
  ++iterations;
}

void DenseQpSolver::Workspace::DropActive(int k) {
  state[active_id[k]] = kInactive;
  if (has_deferred) {
    // Implied inequalities may matter again once the active set shrinks.
    for (auto& st : state) {
      if (st == kDeferred) st = kInactive;
    }
    has_deferred = false;
  }
  // Remove column k of R: columns k+1.. shift left and form an upper Hessenberg block.
  for (int c = k; c < q - 1; ++c) {
    R.col(c).head(c + 2) = R.col(c + 1).head(c + 2);
    active_id[c] = active_id[c + 1];
    active_sign[c] = active_sign[c + 1];
    active_eq[c] = active_eq[c + 1];
    u[c] = u[c + 1];
  }
  // Restore the triangle with rotations of rows (j, j+1); Q <- Q G keeps J' N = [R; 0].
  for (int j = k; j < q - 1; ++j) {
    Eigen::JacobiRotation<double> rot;
    double rho = 0.0;
    rot.makeGivens(R(j, j), R(j + 1, j), &rho);
    R(j, j) = rho;
    R(j + 1, j) = 0.0;
    const int tail = q - 2 - j;
    if (tail > 0) R.middleCols(j + 1, tail).applyOnTheLeft(j, j + 1, rot.adjoint());
    Q.AppendRotation(j, rot);
  }
  --q;
  R.col(q).setZero();
  u[q] = 0.0;
  ++iterations;
  ++drops;
}

AddResult DenseQpSolver::Workspace::Add(int id, int sign, bool equality, bool warm_only) {
  double u_p = 0.0;
  while (true) {
    if (iterations >= settings.max_iterations) return AddResult::kMaxIterations;
    const double s = Slack(id, sign);
    double zn = 0.0;
    double dn2 = 0.0;
    ComputeStep(id, sign, &zn, &dn2);
    double t1 = kInfinity;
    const int k = BlockingConstraint(&t1);
    const bool dependent = !(zn > kDependencyTol * kDependencyTol * dn2) || !(zn > 0.0);
    if (dependent) {
      if (k < 0) {
        // n_p = N r with r <= 0 on the active inequalities, so every feasible x has
        // n_p' x <= r' b_A. The certificate uses the data only (not the drifting x):
        // r' b_A < b_p means infeasible, otherwise p is implied by the active set.
        const double b_p = Rhs(id, sign);
        double rho = -b_p;
        double scale = 1.0 + std::abs(b_p);
        for (int j = 0; j < q; ++j) {
          const double term = r[j] * Rhs(active_id[j], active_sign[j]);
          rho += term;
          scale += std::abs(term);
        }
        // For an equality both sides count: it is consistent only if rho ~ 0.
        const double limit = settings.tolerance * scale;
        if (equality ? std::abs(rho) <= limit : rho >= -limit) {
          if (equality) {
            state[id] = kRedundant;
          } else {
            state[id] = kDeferred;
            has_deferred = true;
          }
          return AddResult::kSkipped;
        }
        return AddResult::kInfeasible;
      }
      if (warm_only) return AddResult::kSkipped;
      // Pure dual step, then drop the blocking constraint.
      u.head(q) -= t1 * r.head(q);
      ClampMultipliers();
      u_p += t1;
      DropActive(k);
      continue;
    }
    const double t2 = -s / zn;
    if (warm_only && !(t2 >= 0.0 && t2 <= t1)) return AddResult::kSkipped;
    const double t = std::min(t1, t2);
    x += t * z;
    u.head(q) -= t * r.head(q);
    ClampMultipliers();
    u_p += t;
    if (t2 <= t1) {
      AppendActive(id, sign, u_p);
      return AddResult::kAdded;
    }
    DropActive(k);
  }
}

bool DenseQpSolver::Workspace::MostViolated(int* id, int* sign) {
  cand_count = 0;
  // Keeps cand_* sorted by decreasing violation (insertion into a short list).
  const auto push = [this](int c, int sgn, double violation) {
    if (cand_count == kCandidates && violation <= cand_violation[kCandidates - 1]) return;
    int k = cand_count < kCandidates ? cand_count++ : kCandidates - 1;
    for (; k > 0 && cand_violation[k - 1] < violation; --k) {
      cand_id[k] = cand_id[k - 1];
      cand_sign[k] = cand_sign[k - 1];
      cand_violation[k] = cand_violation[k - 1];
    }
    cand_id[k] = c;
    cand_sign[k] = sgn;
    cand_violation[k] = violation;
  };
  const auto consider = [&](int c, double value, double lo, double hi) {
    if (state[c] != kInactive) return;
    const double below = lo - value;
    if (below > ViolationTol(lo)) push(c, 1, below);
    const double above = value - hi;
    if (above > ViolationTol(hi)) push(c, -1, above);
  };
  const DenseQp& qp = *problem;
  for (int j = 0; j < nv; ++j) consider(j, x[j], qp.lb[j], qp.ub[j]);
  if (nc > 0) {
    ax.noalias() = qp.A * x;
    for (int i = 0; i < nc; ++i) consider(nv + i, ax[i], qp.lbA[i], qp.ubA[i]);
  }
  if (cand_count == 0) return false;
  *id = cand_id[0];
  *sign = cand_sign[0];
  return true;
}

bool DenseQpSolver::Workspace::NextCandidate(int* id, int* sign) {
  // Most violated of the remembered candidates at the current x (exact slacks).
  double best = 0.0;
  int best_k = -1;
  for (int k = 0; k < cand_count; ++k) {
    const int c = cand_id[k];
    if (c < 0 || state[c] != kInactive) continue;
    const double s = Slack(c, cand_sign[k]);
    if (-s > ViolationTol(Rhs(c, cand_sign[k])) && -s > best) {
      best = -s;
      best_k = k;
    } else if (!(-s > 0.0)) {
      cand_id[k] = -1;  // satisfied now: forget it until the next scan
    }
  }
  if (best_k < 0) return false;
  *id = cand_id[best_k];
  *sign = cand_sign[best_k];
  return true;
}

void DenseQpSolver::Workspace::Refine(bool clamp) {
  // x = J1 R^-T b_A - J2 J2' g and u = R^-1 (R^-T b_A + J1' g).
  for (int k = 0; k < q; ++k) v[k] = Rhs(active_id[k], active_sign[k]);
  R.topLeftCorner(q, q).transpose().triangularView<Eigen::Lower>().solveInPlace(v.head(q));
  const auto& l = *factor;
  w = lg;
  Q.ApplyTransposed(&w);
  const int m = nv - q;
  x.head(q) = v.head(q);
  x.tail(m) = -w.tail(m);
  Q.Apply(&x);
  l.transpose().triangularView<Eigen::Upper>().solveInPlace(x);
  u.head(q) = v.head(q) + w.head(q);
  R.topLeftCorner(q, q).triangularView<Eigen::Upper>().solveInPlace(u.head(q));
  if (clamp) ClampMultipliers();
}

AddResult DenseQpSolver::Workspace::WarmStartBatch() {
  // Make every previous constraint active (linearly independent ones only), whatever
  // its slack: (x, u) is then the minimiser on that working set.
  const int q0 = q;
  for (int k = 0; k < prev_count; ++k) {
    const int id = prev_id[k];
    const int sign = prev_sign[k];
    if (state[id] != kInactive || IsEquality(id) || !std::isfinite(Rhs(id, sign))) continue;
    if (iterations >= settings.max_iterations) return AddResult::kMaxIterations;
    if (!q_ready) InitQ();
    double zn = 0.0;
    double dn2 = 0.0;
    ComputeStep(id, sign, &zn, &dn2, /*steps=*/false);
    if (!(zn > kDependencyTol * kDependencyTol * dn2) || !(zn > 0.0)) continue;
    AppendActive(id, sign, 0.0);
    ++warm_adds;
  }
  if (q == q0) return AddResult::kSkipped;
  // Dual feasibility: drop the most negative inequality multiplier until none is left.
  while (true) {
    Refine(/*clamp=*/false);
    const double scale = 1.0 + u.head(q).lpNorm<Eigen::Infinity>();
    int worst = -1;
    double worst_u = -1e-12 * scale;
    for (int j = 0; j < q; ++j) {
      if (!active_eq[j] && u[j] < worst_u) {
        worst_u = u[j];
        worst = j;
      }
    }
    if (worst < 0) break;
    if (iterations >= settings.max_iterations) return AddResult::kMaxIterations;
    DropActive(worst);
  }
  ClampMultipliers();
  return AddResult::kAdded;
}

AddResult DenseQpSolver::Workspace::WarmStartSequential() {
  for (int k = 0; k < prev_count; ++k) {
    const int id = prev_id[k];
    const int sign = prev_sign[k];
    if (state[id] != kInactive || IsEquality(id)) continue;
    const double b = Rhs(id, sign);
    if (!std::isfinite(b)) continue;
    if (!(Slack(id, sign) < -ViolationTol(b))) continue;
    if (!q_ready) InitQ();
    const AddResult a = Add(id, sign, /*equality=*/false, /*warm_only=*/true);
    if (a == AddResult::kAdded) ++warm_adds;
    if (a == AddResult::kInfeasible || a == AddResult::kMaxIterations) return a;
  }
  return AddResult::kSkipped;
}

void DenseQpSolver::Workspace::WriteSolution(QpSolution* sol) {
  sol->y_bounds.setZero();
  sol->y_constraints.setZero();
  for (int k = 0; k < q; ++k) {
    const int id = active_id[k];
    const double y = -static_cast<double>(active_sign[k]) * u[k];
    if (id < nv) {
      sol->y_bounds[id] = y;
    } else {
      sol->y_constraints[id - nv] = y;
    }
  }
  sol->x = x;
  // 0.5 x' H x = 0.5 |L' x|^2.
  w.noalias() = factor->transpose().triangularView<Eigen::Upper>() * x;
  sol->objective = 0.5 * w.squaredNorm() + problem->g.dot(x);
  sol->num_active = q;
}

QpStatus DenseQpSolver::Workspace::Run(const DenseQp& qp, QpSolution* sol) {
  problem = &qp;
  q = 0;
  q_ready = false;
  has_deferred = false;
  cand_count = 0;
  iterations = 0;
  drops = 0;
  warm_adds = 0;
  std::fill(state.begin(), state.end(), kInactive);

  if (const QpStatus s = Validate(qp); s != QpStatus::kOptimal) return s;

  // Unconstrained minimiser.
  double max_h = 0.0;  // max_i H_ii
  if (qp.h_factor_given) {
    factor = &qp.L;
    if (!(qp.L.diagonal().minCoeff() > 0.0)) return QpStatus::kNotConvex;
    w.setZero();  // H_ii = sum_j L_ij^2, accumulated by columns
    for (int j = 0; j < nv; ++j) w.tail(nv - j) += qp.L.col(j).tail(nv - j).cwiseAbs2();
    max_h = w.maxCoeff();
  } else {
    factor = &chol;
    if (!Factorize(qp.H)) return QpStatus::kNotConvex;
    max_h = qp.H.diagonal().cwiseAbs().maxCoeff();
  }
  const double min_pivot = factor->diagonal().cwiseAbs2().minCoeff();
  if (!(min_pivot > kPivotTol * max_h)) return QpStatus::kNotConvex;
  lg = qp.g;
  factor->triangularView<Eigen::Lower>().solveInPlace(lg);
  x = -lg;
  factor->transpose().triangularView<Eigen::Upper>().solveInPlace(x);
  u.setZero();

  const auto fail = [](AddResult a) {
    return a == AddResult::kInfeasible ? QpStatus::kInfeasible : QpStatus::kMaxIterations;
  };

  // Phase 1: equalities are always active (sign chosen so that the slack is <= 0).
  for (int id = 0; id < nv + nc; ++id) {
    if (!IsEquality(id)) continue;
    if (!q_ready) InitQ();
    const int sign = Slack(id, 1) > 0.0 ? -1 : 1;
    const AddResult a = Add(id, sign, /*equality=*/true, /*warm_only=*/false);
    if (a == AddResult::kInfeasible || a == AddResult::kMaxIterations) return fail(a);
  }

  // Phase 2: warm start from the previous active inequalities (a dual feasible start:
  // x minimises the QP on the working set and u >= 0), see QpSettings::warm_start_batch.
  bool refined = false;  // (x, u) freshly recomputed from the factorisation
  if (settings.warm_start && prev_count > 0) {
    const AddResult a = settings.warm_start_batch ? WarmStartBatch() : WarmStartSequential();
    if (a == AddResult::kInfeasible || a == AddResult::kMaxIterations) return fail(a);
    refined = settings.warm_start_batch && a == AddResult::kAdded;
  }

  // Phase 3: GI major iterations on the most violated constraint.
  // When no violated constraint is left, (x, u) is recomputed once from the factorisation
  // (removes the drift of the incremental steps) and checked again.
  int refinements = 0;
  const int max_scans = 2 * settings.max_iterations + 2 * (nv + nc) + 10;
  for (int scan = 0; scan < max_scans; ++scan) {
    int id = -1;
    int sign = 0;
    if (!NextCandidate(&id, &sign) && !MostViolated(&id, &sign)) {
      bool done = q == 0 || refined || refinements >= kMaxRefinements;
      if (!done) {
        ++refinements;
        refined = true;
        z = x;
        Refine(/*clamp=*/true);
        // A refinement that moved x by less than the tolerance needs no new scan.
        done = (x - z).lpNorm<Eigen::Infinity>() <= settings.tolerance;
      }
      if (done) {
        if (!x.allFinite() || !u.head(q).allFinite()) return QpStatus::kNumericalError;
        WriteSolution(sol);
        return QpStatus::kOptimal;
      }
      continue;
    }
    refined = false;
    if (!q_ready) InitQ();
    const AddResult a = Add(id, sign, /*equality=*/false, /*warm_only=*/false);
    if (a == AddResult::kInfeasible || a == AddResult::kMaxIterations) return fail(a);
  }
  return QpStatus::kMaxIterations;
}

DenseQpSolver::DenseQpSolver(const DenseQpDims& dims, const QpSettings& settings)
    : dims_(dims), settings_(settings) {
  if (dims.nv <= 0) {
    throw std::invalid_argument("[DenseQpSolver] nv must be > 0, got " + std::to_string(dims.nv));
  }
  if (dims.nc < 0) {
    throw std::invalid_argument("[DenseQpSolver] nc must be >= 0, got " + std::to_string(dims.nc));
  }
  if (settings.max_iterations <= 0) {
    throw std::invalid_argument("[DenseQpSolver] max_iterations must be > 0, got " +
                                std::to_string(settings.max_iterations));
  }
  if (!(settings.tolerance > 0.0) || !std::isfinite(settings.tolerance)) {
    throw std::invalid_argument("[DenseQpSolver] tolerance must be finite and > 0, got " +
                                std::to_string(settings.tolerance));
  }
  ws_ = std::make_unique<Workspace>(dims, settings);
}

DenseQpSolver::~DenseQpSolver() = default;
DenseQpSolver::DenseQpSolver(DenseQpSolver&&) noexcept = default;
DenseQpSolver& DenseQpSolver::operator=(DenseQpSolver&&) noexcept = default;

void DenseQpSolver::ResetWarmStart() {
  if (ws_) ws_->prev_count = 0;
}

QpStatus DenseQpSolver::Solve(const DenseQp& qp, QpSolution* solution) {
  if (solution == nullptr || !ws_) return QpStatus::kInvalidInput;
  Workspace& ws = *ws_;
  // Size the output once if the caller did not (the only allocation path of Solve()).
  if (solution->x.size() != dims_.nv) solution->x.setZero(dims_.nv);
  if (solution->y_bounds.size() != dims_.nv) solution->y_bounds.setZero(dims_.nv);
  if (solution->y_constraints.size() != dims_.nc) solution->y_constraints.setZero(dims_.nc);

  QpStatus status = QpStatus::kNumericalError;
  status = ws.Run(qp, solution);
  solution->iterations = ws.iterations;
  solution->num_drops = ws.drops;
  solution->num_warm_start_adds = ws.warm_adds;
  solution->status = status;
  if (status == QpStatus::kOptimal) {
    // Remember the active inequalities, in order, for the next warm start.
    ws.prev_count = 0;
    for (int k = 0; k < ws.q; ++k) {
      if (ws.active_eq[k]) continue;
      ws.prev_id[ws.prev_count] = ws.active_id[k];
      ws.prev_sign[ws.prev_count] = ws.active_sign[k];
      ++ws.prev_count;
    }
  } else {
    // The previous warm-start set is kept: one failed QP does not cost the next one.
    // Last iterate if it is finite (useful for kMaxIterations), zeros otherwise.
    const bool usable =
        (status == QpStatus::kMaxIterations || status == QpStatus::kInfeasible) && ws.x.allFinite();
    if (usable) {
      solution->x = ws.x;
    } else {
      solution->x.setZero();
    }
    solution->y_bounds.setZero();
    solution->y_constraints.setZero();
    solution->objective = 0.0;
    solution->num_active = 0;
  }
  return status;
}

KktResiduals ComputeKktResiduals(const DenseQp& qp, const QpSolution& sol) {
  KktResiduals res;
  const Eigen::Index nv = qp.g.size();
  const Eigen::Index nc = qp.A.rows();
  if (sol.x.size() != nv || sol.y_bounds.size() != nv || sol.y_constraints.size() != nc) {
    res.stationarity = res.primal = res.dual = res.complementarity = kInfinity;
    return res;
  }
  Eigen::VectorXd grad = qp.g + sol.y_bounds;
  if (qp.h_factor_given) {
    const Eigen::VectorXd ltx = qp.L.transpose().triangularView<Eigen::Upper>() * sol.x;
    grad.noalias() += qp.L.triangularView<Eigen::Lower>() * ltx;
  } else {
    grad.noalias() += qp.H * sol.x;
  }
  if (nc > 0) grad.noalias() += qp.A.transpose() * sol.y_constraints;
  res.stationarity = grad.lpNorm<Eigen::Infinity>();
  const auto side = [&res](double value, double lo, double hi, double y) {
    res.primal = std::max({res.primal, lo - value, value - hi});
    if (lo == hi) return;  // equality: free multiplier, no complementarity
    if (y > 0.0) {
      if (hi == kInfinity) {
        res.dual = std::max(res.dual, y);
      } else {
        res.complementarity = std::max(res.complementarity, y * std::abs(hi - value));
      }
    } else if (y < 0.0) {
      if (lo == -kInfinity) {
        res.dual = std::max(res.dual, -y);
      } else {
        res.complementarity = std::max(res.complementarity, -y * std::abs(value - lo));
      }
    }
  };
  for (Eigen::Index j = 0; j < nv; ++j) side(sol.x[j], qp.lb[j], qp.ub[j], sol.y_bounds[j]);
  if (nc > 0) {
    const Eigen::VectorXd ax = qp.A * sol.x;
    for (Eigen::Index i = 0; i < nc; ++i) side(ax[i], qp.lbA[i], qp.ubA[i], sol.y_constraints[i]);
  }
  return res;
}

}  // namespace fnmpc::qp
