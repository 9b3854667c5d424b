// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "fnmpc/core/assert.hpp"
#include "fnmpc/core/eigen_abi.hpp"
#include "fnmpc/core/stopwatch.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/qp/dense_qp.hpp"
#include "fnmpc/rti/rti_settings.hpp"
#include "fnmpc/rti/sparsity.hpp"

namespace fnmpc::rti {

namespace detail {
/// Models with structured products with their transition matrix (Model::MultiplyTransition,
/// MultiplyTransitionRight and MultiplyTransitionTransposed, see QuadrotorModel). A detection
/// trait: the ROS nodes include this header from C++17 units.
template <class Model, class = void>
struct HasStructuredTransition : std::false_type {};
template <class Model>
struct HasStructuredTransition<
    Model,
    std::void_t<decltype(Model::MultiplyTransition(
                    std::declval<const Mat<Model::kNx, Model::kNx>&>(),
                    std::declval<const Vec<Model::kNx>&>(), std::declval<Vec<Model::kNx>*>())),
                decltype(Model::MultiplyTransitionRight(
                    std::declval<const Mat<1, Model::kNx>&>(),
                    std::declval<const Mat<Model::kNx, Model::kNx>&>(),
                    std::declval<Mat<1, Model::kNx>*>())),
                decltype(Model::MultiplyTransitionTransposed(
                    std::declval<const Mat<Model::kNx, Model::kNx>&>(),
                    std::declval<const Vec<Model::kNx>&>(), std::declval<Vec<Model::kNx>*>()))>>
    : std::true_type {};

// ---- The problem contract (docs/rti.md): detection traits for readable errors. ----
template <class T, class = void>
struct HasDims : std::false_type {};
template <class T>
struct HasDims<T, std::void_t<decltype(int{T::kNx}), decltype(int{T::kNu}), decltype(int{T::kNy}),
                              decltype(int{T::kNyN})>> : std::true_type {};
template <class T, class = void>
struct HasParams : std::false_type {};
template <class T>
struct HasParams<T, std::void_t<typename T::Params>> : std::true_type {};
template <class T, class = void>
struct HasDiscretise : std::false_type {};
template <class T>
struct HasDiscretise<
    T, std::void_t<decltype(Vec<T::kNx>(std::declval<const T&>().Discretise(
           std::declval<const Vec<T::kNx>&>(), std::declval<const Vec<T::kNu>&>(),
           std::declval<const typename T::Params&>(), 0.0, 1, std::declval<Mat<T::kNx, T::kNx>*>(),
           std::declval<Mat<T::kNx, T::kNu>*>())))>> : std::true_type {};
template <class T, class = void>
struct HasStageResidual : std::false_type {};
template <class T>
struct HasStageResidual<
    T, std::void_t<decltype(std::declval<const T&>().StageResidual(
           std::declval<const Vec<T::kNx>&>(), std::declval<const Vec<T::kNu>&>(),
           std::declval<const typename T::Params&>(), std::declval<Vec<T::kNy>*>(),
           std::declval<Mat<T::kNy, T::kNx>*>(), std::declval<Mat<T::kNy, T::kNu>*>()))>>
    : std::true_type {};
template <class T, class = void>
struct HasTerminalResidual : std::false_type {};
template <class T>
struct HasTerminalResidual<
    T, std::void_t<decltype(std::declval<const T&>().TerminalResidual(
           std::declval<const Vec<T::kNx>&>(), std::declval<const typename T::Params&>(),
           std::declval<Vec<T::kNyN>*>(), std::declval<Mat<T::kNyN, T::kNx>*>()))>>
    : std::true_type {};
/// Problem::Model when the problem names one (for its optional structured transition
/// products), else void.
template <class T, class = void>
struct ModelOf {
  using type = void;
};
template <class T>
struct ModelOf<T, std::void_t<typename T::Model>> {
  using type = typename T::Model;
};

/// Checks the problem contract before RtiSolver's body uses it, so that the first error a
/// compiler prints names the missing member. Each check is required by the next ones.
template <class Problem>
struct ProblemContract {
  static constexpr bool kDims = HasDims<Problem>::value;
  static_assert(kDims,
                "RtiSolver<Problem>: Problem must declare static constexpr int kNx, kNu, kNy, "
                "kNyN (state, input, stage residual and terminal residual sizes)");
  static constexpr bool kParams = kDims && HasParams<Problem>::value;
  static_assert(!kDims || kParams,
                "RtiSolver<Problem>: Problem must declare the type Params of its "
                "per-stage parameters (e.g. `struct Params {};` for none)");
  static constexpr bool kSizes =
      kParams && Problem::kNx >= 1 && Problem::kNu >= 1 && Problem::kNy >= 1 && Problem::kNyN >= 1;
  static_assert(!kParams || kSizes, "RtiSolver<Problem>: kNx, kNu, kNy and kNyN must be >= 1");
  static_assert(
      !kSizes || HasDiscretise<Problem>::value,
      "RtiSolver<Problem>: Problem must have `Vec<kNx> Discretise(const Vec<kNx>& x, const "
      "Vec<kNu>& u, const Params& p, double dt, int steps, Mat<kNx, kNx>* A, Mat<kNx, "
      "kNu>* B) const` (the interval map and, when A and B are not null, its Jacobians)");
  static_assert(
      !kSizes || HasStageResidual<Problem>::value,
      "RtiSolver<Problem>: Problem must have `void StageResidual(const Vec<kNx>& x, const "
      "Vec<kNu>& u, const Params& p, Vec<kNy>* y, Mat<kNy, kNx>* yx, Mat<kNy, kNu>* yu) "
      "const`");
  static_assert(!kSizes || HasTerminalResidual<Problem>::value,
                "RtiSolver<Problem>: Problem must have `void TerminalResidual(const Vec<kNx>& x, "
                "const Params& p, Vec<kNyN>* y, Mat<kNyN, kNx>* yx) const`");
};

template <class P>
constexpr int ParamsSize() {
  if constexpr (std::is_base_of_v<Eigen::EigenBase<P>, P>) {
    return static_cast<int>(P::SizeAtCompileTime);
  } else {
    return 0;
  }
}

/// Parameters with every entry zero for Eigen types, value-initialised otherwise.
template <class P>
P ZeroParams() {
  if constexpr (std::is_base_of_v<Eigen::EigenBase<P>, P>) {
    return P::Zero();
  } else {
    return P{};
  }
}
}  // namespace detail

/// Real-time-iteration SQP solver for a nonlinear least-squares OCP `Problem`, any type
/// meeting the contract of docs/rti.md (sizes, Params, Discretise, StageResidual,
/// TerminalResidual; the quadrotor problems of fnmpc/ocp/problems.hpp are examples):
///   min  sum_k 0.5|y(x_k,u_k,p_k) - yref_k|^2_W + 0.5|yN(x_N,p_N) - yrefN|^2_WN
///   s.t. x_0 = x0, x_{k+1} = RK4(x_k, u_k, p_k), lbu_k <= u_k <= ubu_k,
///        lbx_k <= x_k(i) <= ubx_k for the components i of the StateBoundLayout (k = 1..N),
///        soft components relaxed by one slack per stage s_k >= 0 penalised by
///        rho1 s_k + 0.5 rho2 s_k^2 (an exact L-infinity penalty: for rho1 larger than the
///        sum of that stage's bound multipliers the soft problem has the hard optimum).
///
/// Multiple shooting, RK4 with exact forward sensitivities, Gauss-Newton Hessian,
/// condensing into a dense QP solved by our active-set solver (fnmpc/qp). Prepare()
/// linearises and condenses around the current guess before x0 is known; Feedback(x0)
/// embeds x0, solves the QP and updates the iterate (its time is the feedback latency).
/// Step() runs Algorithm 1 of the reference work. No heap allocation after construction.
template <class Problem>
class RtiSolver : private detail::ProblemContract<Problem> {
 public:
  static constexpr int kNx = Problem::kNx, kNu = Problem::kNu, kNy = Problem::kNy,
                       kNyN = Problem::kNyN;
  /// The problem's model when it names one (optional structured transition products).
  using Model = typename detail::ModelOf<Problem>::type;
  using X = Vec<kNx>;
  using U = Vec<kNu>;
  using Y = Vec<kNy>;
  using YN = Vec<kNyN>;
  using P = typename Problem::Params;  ///< per-stage parameters
  /// Entries of P when it is an Eigen vector (the quadrotor problems: Vec<kNp>), else 0.
  static constexpr int kNp = detail::ParamsSize<P>();
  using MX = Mat<kNx, kNx>;
  using MU = Mat<kNx, kNu>;

  RtiSolver(const Problem& problem, const RtiSettings& settings, const StateBoundLayout& layout)
      : problem_(problem), settings_(settings), layout_(layout) {
    settings_.Validate();
    if (layout_.soft.size() != layout_.indices.size()) {
      throw std::invalid_argument("[RtiSolver] StateBoundLayout: soft and indices differ in size");
    }
    for (int i : layout_.indices) {
      if (i < 0 || i >= kNx) {
        throw std::invalid_argument("[RtiSolver] bounded state index out of range: " +
                                    std::to_string(i));
      }
    }
    n_ = settings_.horizon;
    int rows_per_stage = 0;
    bool any_soft = false;
    for (bool s : layout_.soft) {
      rows_per_stage += s ? 2 : 1;
      any_soft = any_soft || s;
    }
    nsl_ = any_soft ? n_ : 0;
    nz_ = n_ * kNu + nsl_;
    nc_ = n_ * rows_per_stage;
    for (int k = 1; k <= n_; ++k) {
      for (std::size_t c = 0; c < layout_.indices.size(); ++c) {
        const int kind = layout_.soft[c] ? 1 : 0;
        soft_to_hard_.push_back(static_cast<int>(hard_rows_.size()));
        rows_.push_back({k, layout_.indices[c], kind});
        if (kind == 1) {
          soft_to_hard_.push_back(static_cast<int>(hard_rows_.size()));
          rows_.push_back({k, layout_.indices[c], 2});
        }
        hard_rows_.push_back({k, layout_.indices[c], 0});
      }
    }
    nch_ = static_cast<int>(hard_rows_.size());
    x_.assign(n_ + 1, X::Zero());
    u_.assign(n_, U::Zero());
    yref_.assign(n_, Y::Zero());
    yref_n_.setZero();
    w_.setOnes();
    w_n_.setOnes();
    params_.assign(n_ + 1, detail::ZeroParams<P>());
    lbx_.assign(n_ + 1, X::Constant(-kInf));
    ubx_.assign(n_ + 1, X::Constant(kInf));
    lbu_.assign(n_, U::Constant(-kInf));
    ubu_.assign(n_, U::Constant(kInf));
    a_.assign(n_, MX::Zero());
    b_.assign(n_, MU::Zero());
    d_.assign(n_, X::Zero());
    q_mat_.assign(n_ + 1, MX::Zero());
    s_mat_.assign(n_, Mat<kNu, kNx>::Zero());
    r_mat_.assign(n_, Mat<kNu, kNu>::Zero());
    q_vec_.assign(n_ + 1, X::Zero());
    r_vec_.assign(n_, U::Zero());
    e_.assign(n_ + 1, X::Zero());
    dx_.assign(n_ + 1, X::Zero());
    du_.assign(n_, U::Zero());
    lambda_.assign(n_ + 1, X::Zero());
    mu_.assign(n_ + 1, X::Zero());
    k_gain_.assign(n_, Mat<kNu, kNx>::Zero());
    if constexpr (kRiccatiCondensing) p_mat_.assign(n_ + 1, MX::Zero());
    l_diag_.assign(n_, Mat<kNu, kNu>::Identity());
    kt_vec_.assign(n_, U::Zero());
    g_.assign(static_cast<std::size_t>(n_) * (n_ + 1) / 2, MU::Zero());
    qp_ = qp::DenseQp({nz_, nc_});
    qp_solution_ = qp::QpSolution({nz_, nc_});
    qp_solver_ = std::make_unique<qp::DenseQpSolver>(qp::DenseQpDims{nz_, nc_}, settings_.qp);
    qp_.A.setZero();
    qp_.H.setZero();
    qp_.L.setZero();
    if (nsl_ > 0) {
      const int nv = n_ * kNu;
      const qp::DenseQpDims hard{nv, nch_};
      qp_no_slack_ = qp::DenseQp(hard);
      qp_no_slack_solution_ = qp::QpSolution(hard);
      qp_no_slack_solver_ = std::make_unique<qp::DenseQpSolver>(hard, settings_.qp);
      qp_no_slack_.A.setZero();
      qp_no_slack_.H.setZero();
      qp_no_slack_.L.setZero();
      // The slack part of the soft QP never changes.
      for (int s = 0; s < nsl_; ++s) {
        qp_.H(nv + s, nv + s) = settings_.soft_quadratic_weight;
        qp_.L(nv + s, nv + s) = std::sqrt(settings_.soft_quadratic_weight);
        qp_.g[nv + s] = settings_.soft_linear_weight;
        qp_.lb[nv + s] = 0.0;
        qp_.ub[nv + s] = kInf;
      }
      for (int r = 0; r < nc_; ++r) {
        if (rows_[r].kind != 0) qp_.A(r, nv + rows_[r].stage - 1) = rows_[r].kind == 1 ? 1.0 : -1.0;
      }
    }
    DetectStructure();
  }

  // ---- Stage data (call before Prepare(); no allocation) ----
  // Setters check their arguments: a stage index out of range throws std::out_of_range, a
  // negative or NaN weight std::invalid_argument (programming errors, found at setup).

  /// Diagonal weights of the stage (kNy) and terminal (kNyN) residuals, each >= 0.
  void SetWeights(const Y& w, const YN& w_terminal) {
    CheckWeights("SetWeights", w, w_terminal);
    w_ = w;
    w_n_ = w_terminal;
    BuildCostPatterns();
  }
  /// New weight values within the cost sparsity found by the last SetWeights: a weighted
  /// row may get weight zero (it then contributes nothing) but a row unweighted there may
  /// not become weighted. Keeps the patterns, so no allocation (SetWeights rebuilds them).
  /// Throws std::invalid_argument for a row outside the pattern.
  void SetWeightValues(const Y& w, const YN& w_terminal) {
    auto in = [](const std::vector<int>& rows, int r) {
      return std::find(rows.begin(), rows.end(), r) != rows.end();
    };
    CheckWeights("SetWeightValues", w, w_terminal);
    for (int r = 0; r < kNy; ++r) {
      if (w[r] != 0.0 && !in(weighted_rows_, r))
        throw std::invalid_argument("[RtiSolver] SetWeightValues: stage row " + std::to_string(r) +
                                    " is outside the cost pattern");
    }
    for (int r = 0; r < kNyN; ++r) {
      if (w_terminal[r] != 0.0 && !in(weighted_rows_n_, r))
        throw std::invalid_argument("[RtiSolver] SetWeightValues: terminal row " +
                                    std::to_string(r) + " is outside the cost pattern");
    }
    w_ = w;
    w_n_ = w_terminal;
  }
  /// Reference of stage k = 0..N-1.
  void SetReference(int k, const Y& yref) {
    CheckStage("SetReference", k, 0, n_ - 1);
    yref_[k] = yref;
  }
  void SetTerminalReference(const YN& yref) { yref_n_ = yref; }
  /// Parameters (online data) of node k = 0..N, passed to the problem's functions.
  void SetParameters(int k, const P& p) {
    CheckStage("SetParameters", k, 0, n_);
    params_[k] = p;
  }
  /// Bounds on the layout's state components at node k = 1..N (other entries ignored).
  void SetStateBounds(int k, const X& lb, const X& ub) {
    CheckStage("SetStateBounds", k, 1, n_);
    lbx_[k] = lb;
    ubx_[k] = ub;
  }
  /// Input bounds of stage k = 0..N-1.
  void SetInputBounds(int k, const U& lb, const U& ub) {
    CheckStage("SetInputBounds", k, 0, n_ - 1);
    lbu_[k] = lb;
    ubu_[k] = ub;
  }

  /// Initial guess: every node at x0, every control at u (spec: (m g, 0, 0)).
  void InitializeGuess(const X& x0, const U& u) {
    std::fill(x_.begin(), x_.end(), x0);
    std::fill(u_.begin(), u_.end(), u);
    first_call_ = true;
    prepared_ = false;
  }

  /// Warm start for the next sampling time: drop the first node, duplicate the last.
  void Shift() {
    for (int k = 0; k < n_; ++k) x_[k] = x_[k + 1];
    for (int k = 0; k + 1 < n_; ++k) u_[k] = u_[k + 1];
    prepared_ = false;
  }

  /// Adds `delta` to every node of the state guess. Used by the reduced follower, whose
  /// displacement state restarts at zero every sampling time (a translation of the guess
  /// leaves the linearisation of a translation-invariant problem unchanged).
  void OffsetGuess(const X& delta) {
    for (X& x : x_) x += delta;
    prepared_ = false;
  }

  /// Linearise and condense around the current guess (the preparation phase).
  /// Returns false when the linearisation produced NaN/Inf.
  bool Prepare() {
    Stopwatch sw;
    bool finite = true;
    Y y;
    // The problem writes only the Jacobians' structural nonzeros; the rest stays zero.
    Mat<kNy, kNx>& yx = *yx_buf_;
    Mat<kNy, kNu>& yu = *yu_buf_;
    for (int k = 0; k < n_; ++k) {
      const X next = problem_.Discretise(x_[k], u_[k], params_[k], settings_.sample_time,
                                         settings_.integrator_steps, &a_[k], &b_[k]);
      d_[k] = next - x_[k + 1];
      problem_.StageResidual(x_[k], u_[k], params_[k], &y, &yx, &yu);
      const Y wr = w_.cwiseProduct(y - yref_[k]);
      GaussNewtonBlocks(yx, &yu, w_, wr, weighted_rows_, yx_cols_, yu_cols_, q_pattern_, k);
      finite = finite && a_pattern_.AllFinite(a_[k]) && b_pattern_.AllFinite(b_[k]);
      // (NaN in a weighted residual reaches q_k or r_k; zero-weight rows do not matter)
      finite = finite && d_[k].allFinite() && q_vec_[k].allFinite() && r_vec_[k].allFinite();
    }
    {
      YN yn;
      Mat<kNyN, kNx>& ynx = *ynx_buf_;
      problem_.TerminalResidual(x_[n_], params_[n_], &yn, &ynx);
      const YN wr = w_n_.cwiseProduct(yn - yref_n_);
      GaussNewtonBlocks<Mat<kNyN, kNx>, Mat<kNyN, kNu>>(ynx, nullptr, w_n_, wr, weighted_rows_n_,
                                                        ynx_cols_, {}, qn_pattern_, n_);
      finite = finite && q_vec_[n_].allFinite();
    }
    if (riccati_) {
      if (compact_) {
        RiccatiCompact();
      } else {
        Riccati();
      }
      // Condensing for the QP is done now (outside the feedback latency) unless the last
      // step took the unconstrained Riccati step: then it is likely to do so again, and
      // Feedback condenses only if the step violates a bound.
      condensed_ = false;
      if (!settings_.unconstrained_shortcut || last_qp_active_) Condense();
    } else {
      Condense();
    }
    prepared_ = finite;
    stats_.time_prepare = sw.Seconds();
    return finite;
  }

  /// Embeds x0, solves the QP and updates the iterate (the feedback phase). On failure
  /// the iterate is left unchanged and *u0 is the current guess's first control (the
  /// time-shifted previous solution): Algorithm 1's fallback.
  RtiStatus Feedback(const X& x0, U* u0) {
    Stopwatch sw;
    RtiStatus status = RtiStatus::kSuccess;
    stats_.unconstrained_step = false;
    if (!x0.allFinite()) {
      status = RtiStatus::kInvalidInput;
    } else if (!prepared_) {
      status = RtiStatus::kNanDetected;
    } else if (!condensed_ && TryUnconstrainedStep(x0)) {
      // The unconstrained minimiser of the QP satisfies every bound: it is the QP's
      // solution, with no active constraint.
      ApplyStep(x0);
      last_qp_active_ = false;
      stats_.qp_status = qp::QpStatus::kOptimal;
      stats_.unconstrained_step = true;
    } else {
      if (!condensed_) Condense();
      qp::DenseQp& qp = HardQp();
      // Free response of the linearised dynamics (no input change), including x0.
      e_[0] = x0 - x_[0];
      for (int k = 0; k < n_; ++k) {
        MultiplyA(k, e_[k], &e_[k + 1]);
        e_[k + 1] += d_[k];
      }
      // Condensed gradient by a backward sweep.
      X p = q_vec_[n_];
      AddQ(n_, e_[n_], &p);
      for (int k = n_ - 1; k >= 0; --k) {
        U gk = r_vec_[k];
        AddS(k, e_[k], &gk);
        AddBTransposed(k, p, &gk);
        qp.g.template segment<kNu>(UPos(k)) = gk;
        X pk = q_vec_[k];
        AddQ(k, e_[k], &pk);
        AddATransposed(k, p, &pk);
        p = pk;
      }
      for (int k = 0; k < n_; ++k) {
        qp.lb.template segment<kNu>(UPos(k)) = lbu_[k] - u_[k];
        qp.ub.template segment<kNu>(UPos(k)) = ubu_[k] - u_[k];
      }
      for (int h = 0; h < nch_; ++h) {
        const Row& row = hard_rows_[h];
        const double base = x_[row.stage][row.index] + e_[row.stage][row.index];
        qp.lbA[h] = lbx_[row.stage][row.index] - base;
        qp.ubA[h] = ubx_[row.stage][row.index] - base;
      }
      qp::QpStatus qs = qp::QpStatus::kOptimal;
      if (nsl_ == 0) {
        qs = qp_solver_->Solve(qp_, &qp_solution_);
      } else if (!SolveWithoutSlacks()) {
        FillSoftQp();
        qs = qp_solver_->Solve(qp_, &qp_solution_);
      }
      stats_.qp_status = qs;
      stats_.qp_iterations += qp_solution_.iterations;
      last_qp_active_ = qp_solution_.y_bounds.head(n_ * kNu).any() ||
                        qp_solution_.y_constraints.any() || qs != qp::QpStatus::kOptimal;
      if (qs != qp::QpStatus::kOptimal) {
        status = RtiStatus::kQpFailure;
      } else {
        // Expand: dx_{k+1} = A dx_k + B du_k + d_k.
        dx_[0] = e_[0];
        for (int k = 0; k < n_; ++k) {
          du_[k] = qp_solution_.x.template segment<kNu>(UPos(k));
          MultiplyA(k, dx_[k], &dx_[k + 1]);
          AddB(k, du_[k], &dx_[k + 1]);
          dx_[k + 1] += d_[k];
        }
        bool finite = true;
        for (int k = 0; k <= n_; ++k) finite = finite && dx_[k].allFinite();
        if (!finite) {
          status = RtiStatus::kNanDetected;
        } else {
          ApplyStep(x0);
        }
      }
    }
    prepared_ = false;
    *u0 = u_[0];
    stats_.status = status;
    stats_.time_feedback = sw.Seconds();
    return status;
  }

  /// Algorithm 1 of the reference work for the state x0 at the current sampling time:
  /// the first call (after InitializeGuess) iterates until KKT < threshold (capped by
  /// max_initial_iterations); later calls iterate while the CPU time is within the
  /// budget, KKT >= threshold and fewer than max_iterations were done. On a solver error
  /// the time-shifted previous solution's first control is returned, the fallback flag
  /// raised and counted. Does not shift: call Shift() before the next sampling time.
  RtiStatus Step(const X& x0, U* u0) {
    Stopwatch sw;
    stats_.qp_iterations = 0;
    stats_.sqp_iterations = 0;
    stats_.kkt = -1.0;
    const bool first = first_call_;
    const int cap = first ? settings_.max_initial_iterations : settings_.max_iterations;
    // The CPU budget is checked only between iterations of a later call; pure RTI
    // (max_iterations = 1) never reads the thread CPU clock, a system call of about 0.5 us.
    const bool budgeted = !first && cap > 1;
    const double cpu0 = budgeted ? ThreadCpuSeconds() : 0.0;
    RtiStatus status = RtiStatus::kSuccess;
    const U fallback_u = u_[0];
    for (int it = 0; it < cap; ++it) {
      if (!prepared_ && !Prepare()) {
        status = RtiStatus::kNanDetected;
        break;
      }
      status = Feedback(x0, u0);
      ++stats_.sqp_iterations;
      if (status != RtiStatus::kSuccess) break;
      if (it + 1 >= cap) break;
      stats_.kkt = ComputeKkt(x0);
      if (stats_.kkt < settings_.kkt_threshold) break;
      if (budgeted && ThreadCpuSeconds() - cpu0 > settings_.cpu_budget) break;
    }
    stats_.fallback = status != RtiStatus::kSuccess;
    if (stats_.fallback) {
      ++stats_.fallback_count;
      *u0 = fallback_u;
    }
    stats_.status = status;
    first_call_ = false;
    stats_.time_total = sw.Seconds();
    return status;
  }

  /// KKT value of the current iterate with the last QP's multipliers (benchmark spec):
  /// the largest of Lagrangian stationarity, dynamics and initial-state defects, bound
  /// violation and complementarity (infinity norms). Linearises at the current iterate,
  /// so call it outside timed sections. Uses the data of the last Prepare()/Feedback().
  double ComputeKkt(const X& x0) {
    if (!has_multipliers_) return kInf;
    // Dynamics multipliers from the QP (at its linearisation point).
    std::fill(mu_.begin(), mu_.end(), X::Zero());
    for (int r = 0; r < nc_; ++r)
      mu_[rows_[r].stage][rows_[r].index] += qp_solution_.y_constraints[r];
    lambda_[n_] = q_mat_[n_] * dx_[n_] + q_vec_[n_] + mu_[n_];
    for (int k = n_ - 1; k >= 1; --k) {
      X l = q_vec_[k] + mu_[k];
      l.noalias() += q_mat_[k] * dx_[k];
      l.noalias() += s_mat_[k].transpose() * du_[k];
      l.noalias() += a_[k].transpose() * lambda_[k + 1];
      lambda_[k] = l;
    }
    double kkt = (x_[0] - x0).template lpNorm<Eigen::Infinity>();
    Y y;
    Mat<kNy, kNx>& yx = *yx_buf_;
    Mat<kNy, kNu>& yu = *yu_buf_;
    MX a = MX::Zero();  // Discretise writes only the structural nonzeros
    MU b = MU::Zero();
    for (int k = 0; k < n_; ++k) {
      const X next = problem_.Discretise(x_[k], u_[k], params_[k], settings_.sample_time,
                                         settings_.integrator_steps, &a, &b);
      kkt = std::max(kkt, (next - x_[k + 1]).template lpNorm<Eigen::Infinity>());
      problem_.StageResidual(x_[k], u_[k], params_[k], &y, &yx, &yu);
      const Y wr = w_.cwiseProduct(y - yref_[k]);
      // lazyProduct: coefficient-based (GCC 12 reports a false -Waggressive-loop-optimizations
      // in Eigen's GEMV kernel for the larger residuals of the extended problems).
      U gu = yu.transpose().lazyProduct(wr) + b.transpose().lazyProduct(lambda_[k + 1]) +
             qp_solution_.y_bounds.template segment<kNu>(UPos(k));
      kkt = std::max(kkt, gu.template lpNorm<Eigen::Infinity>());
      if (k >= 1) {
        X gx = yx.transpose().lazyProduct(wr) - lambda_[k] +
               a.transpose().lazyProduct(lambda_[k + 1]) + mu_[k];
        kkt = std::max(kkt, gx.template lpNorm<Eigen::Infinity>());
      }
      for (int i = 0; i < kNu; ++i) {
        kkt = std::max({kkt, lbu_[k][i] - u_[k][i], u_[k][i] - ubu_[k][i]});
        const double yb = qp_solution_.y_bounds[UPos(k) + i];
        const double gap = yb > 0 ? ubu_[k][i] - u_[k][i] : u_[k][i] - lbu_[k][i];
        if (yb != 0.0 && std::isfinite(gap)) kkt = std::max(kkt, std::abs(yb * gap));
      }
    }
    {
      YN yn;
      Mat<kNyN, kNx>& ynx = *ynx_buf_;
      problem_.TerminalResidual(x_[n_], params_[n_], &yn, &ynx);
      const YN wrn = w_n_.cwiseProduct(yn - yref_n_);
      X gx = ynx.transpose().lazyProduct(wrn) - lambda_[n_] + mu_[n_];
      kkt = std::max(kkt, gx.template lpNorm<Eigen::Infinity>());
    }
    for (int r = 0; r < nc_; ++r) {
      const Row& row = rows_[r];
      const double v = x_[row.stage][row.index];
      const double lb = lbx_[row.stage][row.index], ub = ubx_[row.stage][row.index];
      const double slack = nsl_ > 0 ? qp_solution_.x[n_ * kNu + row.stage - 1] : 0.0;
      if (row.kind == 0) kkt = std::max({kkt, lb - v, v - ub});
      const double yc = qp_solution_.y_constraints[r];
      const double relax = row.kind == 0 ? 0.0 : slack;
      const double gap = yc > 0 ? ub + relax - v : v - (lb - relax);
      if (yc != 0.0 && std::isfinite(gap)) kkt = std::max(kkt, std::abs(yc * gap));
    }
    return kkt;
  }

  // ---- Accessors ----
  [[nodiscard]] const std::vector<X>& states() const { return x_; }
  [[nodiscard]] const std::vector<U>& inputs() const { return u_; }
  [[nodiscard]] const RtiStats& stats() const { return stats_; }
  [[nodiscard]] const RtiSettings& settings() const { return settings_; }
  [[nodiscard]] const Problem& problem() const { return problem_; }
  [[nodiscard]] int horizon() const { return n_; }
  [[nodiscard]] const qp::QpSolution& qp_solution() const { return qp_solution_; }
  /// Slack of stage k = 1..N of the soft bounds in the last QP (0 without soft bounds).
  [[nodiscard]] double slack(int k) const {
    return nsl_ > 0 ? qp_solution_.x[n_ * kNu + k - 1] : 0.0;
  }
  [[nodiscard]] const X& lower_state_bound(int k) const { return lbx_[k]; }
  [[nodiscard]] const X& upper_state_bound(int k) const { return ubx_[k]; }
  [[nodiscard]] const U& lower_input_bound(int k) const { return lbu_[k]; }
  [[nodiscard]] const U& upper_input_bound(int k) const { return ubu_[k]; }
  [[nodiscard]] const StateBoundLayout& layout() const { return layout_; }

 private:
  // Small nx: Riccati condensing straight into the Cholesky factor of the Hessian (the
  // QP then skips its factorisation). Large nx: the Hessian by sparse backward sweeps
  // (the dense nx x nx Riccati matrix costs O(nx^2) per structural nonzero of A_k: F2,
  // nx = 22, is faster with Riccati, F6, nx = 54, slower; docs/benchmarks.md).
  static constexpr bool kRiccatiCondensing = kNx <= 32;
  // Larger nx: when the states that can influence the cost (cost rows, closed under the
  // dynamics' couplings) are at most kMaxCompact, the Riccati recursion runs on them only:
  // the others have zero rows and columns in P_k and zero columns in Kt_k (F6: its four
  // static neighbours have zero weight, which leaves 22 of 54 states).
  static constexpr int kMaxCompact = 32;
  using MC = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxCompact, kMaxCompact>;
  using VC = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxCompact, 1>;
  // (a single-input problem's UC is one row: Eigen requires row-major storage for it)
  using UC = Eigen::Matrix<double, kNu, Eigen::Dynamic,
                           kNu == 1 ? Eigen::RowMajor : Eigen::ColMajor, kNu, kMaxCompact>;
  using BC = Eigen::Matrix<double, Eigen::Dynamic, kNu, 0, kMaxCompact, kNu>;

  // Position of u_k in the QP variables: last stage first, so that the Riccati recursion
  // (which eliminates u_{N-1} first) gives a lower-triangular factor. Slacks come after.
  [[nodiscard]] int UPos(int k) const {
    FNMPC_ASSERT(k >= 0 && k < n_);
    return (n_ - 1 - k) * kNu;
  }
  void CheckStage(const char* setter, int k, int first, int last) const {
    if (k < first || k > last) {
      throw std::out_of_range(std::string("[RtiSolver] ") + setter + ": stage " +
                              std::to_string(k) + " outside " + std::to_string(first) + ".." +
                              std::to_string(last) + " (horizon " + std::to_string(n_) + ")");
    }
  }
  static void CheckWeights(const char* setter, const Y& w, const YN& w_terminal) {
    auto check = [&](const char* which, const auto& v) {
      for (int r = 0; r < v.size(); ++r) {
        if (!(v[r] >= 0.0) || !std::isfinite(v[r])) {
          throw std::invalid_argument(std::string("[RtiSolver] ") + setter + ": " + which +
                                      " weight " + std::to_string(r) +
                                      " must be finite and >= 0, got " + std::to_string(v[r]));
        }
      }
    };
    check("stage", w);
    check("terminal", w_terminal);
  }

  // The QP without slack variables: the one Condense and Feedback write (with soft bounds
  // it is tried first, see SolveWithoutSlacks), else the only QP.
  qp::DenseQp& HardQp() { return nsl_ > 0 ? qp_no_slack_ : qp_; }

  struct Row {
    int stage;  // node k = 1..N
    int index;  // state component
    int kind;   // 0 two-sided (hard, or any row of the hard QP), 1 soft lower, 2 soft upper
  };

  // Soft bounds are rarely violated, and then the QP without slack variables (soft bounds
  // made hard) has the soft QP's solution with zero slacks, provided each stage's bound
  // multipliers sum to at most the linear penalty (the exact-penalty condition). Trying it
  // first saves the N slack variables and the N active-set additions that pin them at zero.
  // Returns false (and the full soft QP is solved) when it is infeasible or the condition
  // fails.
  bool SolveWithoutSlacks() {
    const int nv = n_ * kNu;
    if (qp_no_slack_solver_->Solve(qp_no_slack_, &qp_no_slack_solution_) !=
        qp::QpStatus::kOptimal) {
      return false;
    }
    const qp::QpSolution& hard = qp_no_slack_solution_;
    // Multipliers of the soft QP's rows: a two-sided hard row's goes to the soft row of its
    // active side. Slack bound multiplier of stage k (stationarity in s_k at s_k = 0): the
    // soft rows' multipliers enter with A = +1 (lower, y <= 0) and -1 (upper, y >= 0).
    auto slack_bound = qp_solution_.y_bounds.tail(nsl_);
    slack_bound.setConstant(-settings_.soft_linear_weight);
    for (int r = 0; r < nc_; ++r) {
      const double y = hard.y_constraints[soft_to_hard_[r]];
      const int kind = rows_[r].kind;
      const double yr = kind == 0 || (kind == 1 && y < 0.0) || (kind == 2 && y > 0.0) ? y : 0.0;
      qp_solution_.y_constraints[r] = yr;
      if (kind != 0) slack_bound[rows_[r].stage - 1] += std::abs(yr);
    }
    if (slack_bound.maxCoeff() > 0.0) return false;
    qp_solution_.x.head(nv) = hard.x;
    qp_solution_.x.tail(nsl_).setZero();
    qp_solution_.y_bounds.head(nv) = hard.y_bounds;
    qp_solution_.iterations = hard.iterations;
    qp_solution_.status = hard.status;
    qp_solution_.objective = hard.objective;
    qp_solution_.num_active = hard.num_active + nsl_;
    qp_solution_.num_drops = hard.num_drops;
    qp_solution_.num_warm_start_adds = hard.num_warm_start_adds;
    return true;
  }

  // Iterate update by the step (dx_, du_) of the last QP, with the measured x0 embedded.
  void ApplyStep(const X& x0) {
    for (int k = 0; k <= n_; ++k) x_[k] += dx_[k];
    for (int k = 0; k < n_; ++k) u_[k] += du_[k];
    x_[0] = x0;
    has_multipliers_ = true;
  }

  // The soft QP from the hard one (its slack part is set in the constructor).
  void FillSoftQp() {
    const int nv = n_ * kNu;
    const qp::DenseQp& hard = qp_no_slack_;
    qp_.g.head(nv) = hard.g;
    qp_.lb.head(nv) = hard.lb;
    qp_.ub.head(nv) = hard.ub;
    for (int r = 0; r < nc_; ++r) {
      const int h = soft_to_hard_[r];
      qp_.lbA[r] = rows_[r].kind == 2 ? -kInf : hard.lbA[h];
      qp_.ubA[r] = rows_[r].kind == 1 ? kInf : hard.ubA[h];
      qp_.A.row(r).head(nv) = hard.A.row(h);
    }
    if (riccati_) {
      qp_.L.topLeftCorner(nv, nv) = hard.L;
    } else {
      qp_.H.topLeftCorner(nv, nv) = hard.H;
    }
  }

  // Dense condensing of the Hessian and the constraint rows (independent of x0).
  void Condense() {
    condensed_ = true;
    qp::DenseQp& qp = HardQp();
    // G(k, j) = d x_{k+1} / d u_j for j <= k. Without a structured product: only the rows
    // of the input-reachable states (the others are zero in every G).
    for (int j = 0; j < n_; ++j) {
      G(j, j) = b_[j];
      for (int k = j + 1; k < n_; ++k) {
        if constexpr (kStructuredA) {
          MultiplyA(k, G(k - 1, j), &G(k, j));
        } else {
          MU& out = G(k, j);
          for (int i : reach_) out.row(i).setZero();
          a_reach_pattern_.AddProduct(a_[k], G(k - 1, j), &out);
        }
      }
    }
    if (riccati_) {
      // Cholesky factor of the condensed Hessian from the Riccati recursion (Riccati()):
      // with the inputs ordered last stage first, it has the diagonal blocks L_k and
      // below them (Kt_k G(k-1, j))' for j < k, since eliminating u_N-1 first is one
      // backward Riccati step: O(N^2 nx nu^2), as much as forming the Hessian, and the
      // QP needs no factorisation.
      Eigen::MatrixXd& l = qp.L;
      for (int k = 0; k < n_; ++k) l.template block<kNu, kNu>(UPos(k), UPos(k)) = l_diag_[k];
      for (int k = 1; k < n_; ++k) {
        for (int j = 0; j < k; ++j) {
          if constexpr (kStructuredA) {
            l.template block<kNu, kNu>(UPos(j), UPos(k)).noalias() =
                (k_gain_[k] * G(k - 1, j)).transpose();
          } else {
            // Over the states where both Kt_k and G can be nonzero.
            Mat<kNu, kNu> kg = Mat<kNu, kNu>::Zero();
            for (int i : gain_reach_) kg.noalias() += k_gain_[k].col(i) * G(k - 1, j).row(i);
            l.template block<kNu, kNu>(UPos(j), UPos(k)) = kg.transpose();
          }
        }
      }
    } else {
      // Large nx: Hessian columns by backward sweeps, O(N^2 nnz nu) with the structural
      // nonzeros of A_k, B_k, Q_k and S_k.
      MU p, pk;
      for (int j = 0; j < n_; ++j) {
        p.setZero();
        AddQ(n_, G(n_ - 1, j), &p);
        for (int k = n_ - 1; k > j; --k) {
          const MU& gkj = G(k - 1, j);
          Mat<kNu, kNu> hkj = Mat<kNu, kNu>::Zero();
          AddS(k, gkj, &hkj);
          AddBTransposed(k, p, &hkj);
          qp.H.template block<kNu, kNu>(UPos(k), UPos(j)) = hkj;
          qp.H.template block<kNu, kNu>(UPos(j), UPos(k)) = hkj.transpose();
          pk.setZero();
          AddQ(k, gkj, &pk);
          AddATransposed(k, p, &pk);
          p = pk;
        }
        Mat<kNu, kNu> hjj = r_mat_[j];
        AddBTransposed(j, p, &hjj);
        qp.H.template block<kNu, kNu>(UPos(j), UPos(j)) = 0.5 * (hjj + hjj.transpose());
      }
    }
    for (int h = 0; h < nch_; ++h) {
      const Row& row = hard_rows_[h];
      for (int j = 0; j < row.stage; ++j) {
        qp.A.template block<1, kNu>(h, UPos(j)) = G(row.stage - 1, j).row(row.index);
      }
    }
  }

  // Riccati recursion P_N = Q_N, Rbar_k = R_k + B_k' P_k+1 B_k = L_k L_k',
  // Kt_k = L_k^-1 (S_k + B_k' P_k+1 A_k), P_k = Q_k + A_k' P_k+1 A_k - Kt_k' Kt_k
  // (k >= 1: x_0 is fixed, P_0 is not needed): O(N nx^3); FactorStage handles an Rbar_k
  // that is not positive definite.
  void Riccati() {
    riccati_ok_ = true;
    p_mat_[n_] = q_mat_[n_];
    for (int k = n_ - 1; k >= 0; --k) {
      const MX& p = p_mat_[k + 1];
      const Mat<kNu, kNx> bp = b_[k].transpose() * p;
      Mat<kNu, kNu> rbar = r_mat_[k];
      rbar.noalias() += bp * b_[k];
      Mat<kNu, kNx> bpa;
      MultiplyARight(k, bp, &bpa);
      const Mat<kNu, kNx> sbar = s_mat_[k] + bpa;
      Mat<kNu, kNx>& kt = k_gain_[k];
      FactorStage(k, rbar, sbar, &kt);
      if (k == 0) break;  // P_0 is never used
      MX pa, apa;
      MultiplyARight(k, p, &pa);
      MultiplyATransposed(k, pa, &apa);
      p_mat_[k] = q_mat_[k] + apa;
      p_mat_[k].noalias() -= kt.transpose() * kt;
    }
  }

  // Riccati() on the cost-relevant states rel_ (kMaxCompact at most): the same recursion
  // with A_k, B_k, Q_k, S_k restricted to them; Kt_k is scattered back (zero elsewhere).
  void RiccatiCompact() {
    riccati_ok_ = true;
    const int nr = nr_;
    const auto gather_q = [&](const MX& q, MC* out) {
      for (int i = 0; i < nr; ++i) {
        for (int j = 0; j < nr; ++j) (*out)(i, j) = q(rel_[i], rel_[j]);
      }
    };
    gather_q(q_mat_[n_], &pc_mat_[n_]);
    for (int k = n_ - 1; k >= 0; --k) {
      const MC& p = pc_mat_[k + 1];
      for (std::size_t e = 0; e < ac_full_.size(); ++e) {
        const auto& c = ac_pattern_.entries()[e];
        ac_(c.row, c.col) = a_[k](ac_full_[e].row, ac_full_[e].col);
      }
      BC bc(nr, kNu);
      UC sc(kNu, nr);
      for (int i = 0; i < nr; ++i) {
        bc.row(i) = b_[k].row(rel_[i]);
        sc.col(i) = s_mat_[k].col(rel_[i]);
      }
      const UC bp = bc.transpose().lazyProduct(p);
      Mat<kNu, kNu> rbar = r_mat_[k];
      rbar += bp.lazyProduct(bc);
      UC bpa(kNu, nr);
      ac_pattern_.MultiplyRight(bp, ac_, &bpa);
      const UC sbar = sc + bpa;
      UC kt(kNu, nr);
      FactorStage(k, rbar, sbar, &kt);
      k_gain_[k].setZero();
      for (int i = 0; i < nr; ++i) k_gain_[k].col(rel_[i]) = kt.col(i);
      if (k == 0) break;  // P_0 is never used
      MC pa(nr, nr);
      ac_pattern_.MultiplyRight(p, ac_, &pa);
      MC& pk = pc_mat_[k];
      gather_q(q_mat_[k], &pk);
      ac_pattern_.AddTransposedProduct(ac_, pa, &pk);
      pk -= kt.transpose().lazyProduct(kt);
    }
  }

  // One Riccati stage's factorisation: Rbar_k = L_k L_k' and Kt = L_k^-1 Sbar. A Rbar_k
  // that is not positive definite leaves L_k = 0 and Kt = 0 (the QP then reports
  // kNotConvex) and clears riccati_ok_.
  template <class Sbar, class Kt>
  void FactorStage(int k, const Mat<kNu, kNu>& rbar, const Sbar& sbar, Kt* kt) {
    const Eigen::LLT<Mat<kNu, kNu>> llt(rbar);
    if (llt.info() == Eigen::Success) {
      l_diag_[k] = llt.matrixL();
      ForwardSubstitute(l_diag_[k], sbar, kt);
    } else {
      l_diag_[k].setZero();
      kt->setZero();
      riccati_ok_ = false;
    }
  }

  // out = l^-1 in for a lower-triangular kNu x kNu l (Eigen's triangular solve for a
  // matrix right-hand side goes through its blocked GEMM kernel).
  template <class In, class Out>
  static void ForwardSubstitute(const Mat<kNu, kNu>& l, const In& in, Out* out) {
    for (int i = 0; i < kNu; ++i) {
      out->row(i) = in.row(i);
      for (int c = 0; c < i; ++c) out->row(i) -= l(i, c) * out->row(c);
      out->row(i) /= l(i, i);
    }
  }

  // The unconstrained minimiser of the QP by the Riccati factorisation: backward
  // w = P_k+1 d_k + p_k+1, kt_k = L_k^-1 (r_k + B_k' w), p_k = q_k + A_k' w - Kt_k' kt_k;
  // forward du_k = -L_k^-T (Kt_k dx_k + kt_k), dx_k+1 = A_k dx_k + B_k du_k + d_k.
  // O(N nx^2), no condensing. Writes dx_, du_ and, when it returns true (finite and every
  // input and state bound satisfied, soft ones as hard), qp_solution_ as the QP's.
  bool TryUnconstrainedStep(const X& x0) {
    if (!riccati_ || !riccati_ok_) return false;
    X p = q_vec_[n_];
    for (int k = n_ - 1; k >= 0; --k) {
      X w = p;
      if (compact_) {
        VC dc(nr_);
        for (int i = 0; i < nr_; ++i) dc[i] = d_[k][rel_[i]];
        const VC pd = pc_mat_[k + 1].lazyProduct(dc);
        for (int i = 0; i < nr_; ++i) w[rel_[i]] += pd[i];
      } else if constexpr (kRiccatiCondensing) {
        w.noalias() += p_mat_[k + 1] * d_[k];
      }
      U r = r_vec_[k];
      AddBTransposed(k, w, &r);
      ForwardSubstitute(l_diag_[k], r, &kt_vec_[k]);
      MultiplyATransposed(k, w, &p);
      p += q_vec_[k];
      p.noalias() -= k_gain_[k].transpose() * kt_vec_[k];
    }
    dx_[0] = x0 - x_[0];
    bool feasible = true;
    for (int k = 0; k < n_; ++k) {
      U v = kt_vec_[k];
      v.noalias() += k_gain_[k] * dx_[k];
      l_diag_[k].transpose().template triangularView<Eigen::Upper>().solveInPlace(v);
      du_[k] = -v;
      MultiplyA(k, dx_[k], &dx_[k + 1]);
      AddB(k, du_[k], &dx_[k + 1]);
      dx_[k + 1] += d_[k];
      const U u_new = u_[k] + du_[k];
      feasible = feasible && (u_new.array() >= lbu_[k].array()).all() &&
                 (u_new.array() <= ubu_[k].array()).all();
    }
    for (int h = 0; h < nch_ && feasible; ++h) {
      const Row& row = hard_rows_[h];
      const double v = x_[row.stage][row.index] + dx_[row.stage][row.index];
      feasible = v >= lbx_[row.stage][row.index] && v <= ubx_[row.stage][row.index];
    }
    if (!feasible) return false;  // (also when NaN: comparisons with NaN are false)
    for (int k = 0; k < n_; ++k) qp_solution_.x.template segment<kNu>(UPos(k)) = du_[k];
    qp_solution_.x.tail(nsl_).setZero();
    qp_solution_.y_bounds.setZero();
    qp_solution_.y_constraints.setZero();
    qp_solution_.iterations = 0;
    qp_solution_.status = qp::QpStatus::kOptimal;
    qp_solution_.objective = kNaN;  // not computed on this path
    qp_solution_.num_active = 0;
    qp_solution_.num_drops = 0;
    qp_solution_.num_warm_start_adds = 0;
    // What the active-set solvers would remember: an empty active set.
    qp_solver_->ResetWarmStart();
    if (qp_no_slack_solver_) qp_no_slack_solver_->ResetWarmStart();
    return true;
  }

  // Block G(k, j) = d x_{k+1} / d u_j (j <= k) of the condensed sensitivities.
  MU& G(int k, int j) {
    FNMPC_ASSERT(j >= 0 && j <= k && k < n_);
    return g_[static_cast<std::size_t>(k) * (k + 1) / 2 + j];
  }

  // Products with the stage matrices over their structural nonzeros (the neighbour blocks
  // of the full follower models are mostly zero; for L, A_k has 30 of 81 entries).
  static constexpr bool kStructuredA = detail::HasStructuredTransition<Model>::value;
  template <class In, class Out>
  void MultiplyA(int k, const In& in, Out* out) const {
    if constexpr (kStructuredA) {
      Model::MultiplyTransition(a_[k], in, out);
    } else {
      a_pattern_.Multiply(a_[k], in, out);
    }
  }
  // out = A_k' in.
  template <class In, class Out>
  void MultiplyATransposed(int k, const In& in, Out* out) const {
    if constexpr (kStructuredA) {
      Model::MultiplyTransitionTransposed(a_[k], in, out);
    } else {
      out->setZero();
      a_pattern_.AddTransposedProduct(a_[k], in, out);
    }
  }
  // out = in A_k.
  template <class In, class Out>
  void MultiplyARight(int k, const In& in, Out* out) const {
    if constexpr (kStructuredA) {
      Model::MultiplyTransitionRight(in, a_[k], out);
    } else {
      a_pattern_.MultiplyRight(in, a_[k], out);
    }
  }
  template <class In, class Out>
  void AddATransposed(int k, const In& in, Out* out) const {
    if constexpr (kStructuredA) {
      typename Out::PlainObject t;
      Model::MultiplyTransitionTransposed(a_[k], in, &t);
      *out += t;
    } else {
      a_pattern_.AddTransposedProduct(a_[k], in, out);
    }
  }
  // Small nx: B_k, Q_k and S_k as dense fixed-size products (their entries off the pattern
  // are zero). A loop over a handful of structural nonzeros is slower there: consecutive
  // entries update the same output entry, a chain of dependent loads and stores.
  static constexpr bool kDenseStageProducts = kNx <= 16;
  template <class In, class Out>
  void AddB(int k, const In& in, Out* out) const {
    if constexpr (kDenseStageProducts) {
      out->noalias() += b_[k] * in;
    } else {
      b_pattern_.AddProduct(b_[k], in, out);
    }
  }
  template <class In, class Out>
  void AddBTransposed(int k, const In& in, Out* out) const {
    if constexpr (kDenseStageProducts) {
      out->noalias() += b_[k].transpose() * in;
    } else {
      b_pattern_.AddTransposedProduct(b_[k], in, out);
    }
  }
  // k = N is the terminal cost.
  template <class In, class Out>
  void AddQ(int k, const In& in, Out* out) const {
    if constexpr (kDenseStageProducts) {
      out->noalias() += q_mat_[k] * in;
    } else {
      (k == n_ ? qn_pattern_ : q_pattern_).AddProduct(q_mat_[k], in, out);
    }
  }
  template <class In, class Out>
  void AddS(int k, const In& in, Out* out) const {
    if constexpr (kDenseStageProducts) {
      out->noalias() += s_mat_[k] * in;
    } else {
      s_pattern_.AddProduct(s_mat_[k], in, out);
    }
  }

  // Gauss-Newton blocks of node k from the residual Jacobians, over the rows with a nonzero
  // weight (rows) and the nonzero columns of each: Q_k = Jx' W Jx, S_k = Ju' W Jx, R_k = Ju' W Ju,
  // q_k = Jx' W r, r_k = Ju' W r (the entries of q_pattern outside the rows' products are never
  // written and stay zero; R_k and r_k only with ju).
  template <class Jx, class Ju, class Wv, class Rv>
  void GaussNewtonBlocks(const Jx& jx, const Ju* ju, const Wv& w, const Rv& wr,
                         const std::vector<int>& rows, const std::vector<std::vector<int>>& x_cols,
                         const std::vector<std::vector<int>>& u_cols,
                         const SparsityPattern& q_pattern, int k) {
    for (const auto& e : q_pattern.entries()) q_mat_[k](e.row, e.col) = 0.0;
    q_vec_[k].setZero();
    if (ju != nullptr) {
      for (const auto& e : s_pattern_.entries()) s_mat_[k](e.row, e.col) = 0.0;
      r_mat_[k].setZero();
      r_vec_[k].setZero();
    }
    for (int r : rows) {
      for (int a : x_cols[r]) {
        const double ya = jx(r, a);
        q_vec_[k][a] += ya * wr[r];
        const double wya = w[r] * ya;
        for (int b : x_cols[r]) q_mat_[k](a, b) += wya * jx(r, b);
        if (ju != nullptr) {
          for (int i : u_cols[r]) s_mat_[k](i, a) += (*ju)(r, i) * wya;
        }
      }
      if (ju == nullptr) continue;
      for (int i : u_cols[r]) {
        const double yi = (*ju)(r, i);
        r_vec_[k][i] += yi * wr[r];
        const double wyi = w[r] * yi;
        for (int j : u_cols[r]) r_mat_[k](i, j) += wyi * (*ju)(r, j);
      }
    }
  }

  // Structural nonzeros: the entries that the problem's Discretise and residual
  // functions write (both write the same entries on every call; NaN marks the others).
  void DetectStructure() {
    MX a = MX::Constant(kNaN);
    MU b = MU::Constant(kNaN);
    const P p0 = detail::ZeroParams<P>();
    problem_.Discretise(X::Zero(), U::Zero(), p0, settings_.sample_time, settings_.integrator_steps,
                        &a, &b);
    a_pattern_.SetFromWritten(a);
    b_pattern_.SetFromWritten(b);
    FindReachableStates();
    Y y;
    YN yn;
    yx_buf_->setConstant(kNaN);
    yu_buf_->setConstant(kNaN);
    ynx_buf_->setConstant(kNaN);
    problem_.StageResidual(X::Zero(), U::Zero(), p0, &y, yx_buf_.get(), yu_buf_.get());
    problem_.TerminalResidual(X::Zero(), p0, &yn, ynx_buf_.get());
    // (x == x is false exactly for NaN: the entries written)
    const Eigen::Array<bool, kNy, kNx> yx_mask = yx_buf_->array() == yx_buf_->array();
    const Eigen::Array<bool, kNy, kNu> yu_mask = yu_buf_->array() == yu_buf_->array();
    const Eigen::Array<bool, kNyN, kNx> ynx_mask = ynx_buf_->array() == ynx_buf_->array();
    yx_buf_->setZero();
    yu_buf_->setZero();
    ynx_buf_->setZero();
    const auto columns = [](const auto& mask, std::vector<std::vector<int>>* cols) {
      cols->assign(mask.rows(), {});
      for (int r = 0; r < mask.rows(); ++r) {
        for (int c = 0; c < mask.cols(); ++c) {
          if (mask(r, c)) (*cols)[r].push_back(c);
        }
      }
    };
    columns(yx_mask, &yx_cols_);
    columns(yu_mask, &yu_cols_);
    columns(ynx_mask, &ynx_cols_);
    q_pattern_.Reserve(kNx, kNx);
    qn_pattern_.Reserve(kNx, kNx);
    weighted_rows_.reserve(kNy);
    weighted_rows_n_.reserve(kNyN);
    s_pattern_.Reserve(kNu, kNx);
    BuildCostPatterns();
  }

  // Closes the state set *in under the couplings of A_k: downstream adds every state whose
  // dynamics involve a member, upstream every state that enters a member's dynamics.
  void CloseUnderDynamics(bool downstream, std::vector<char>* in) const {
    std::vector<char>& set = *in;
    for (bool changed = true; changed;) {
      changed = false;
      for (const auto& e : a_pattern_.entries()) {
        const int from = downstream ? e.col : e.row;
        const int to = downstream ? e.row : e.col;
        if (set[from] && !set[to]) {
          set[to] = 1;
          changed = true;
        }
      }
    }
  }

  // reach_: the states the inputs can move (rows of B_k, closed under A_k: a state whose
  // dynamics involve a reachable one is reachable); the other rows of G are zero.
  void FindReachableStates() {
    std::vector<char> in(kNx, 0);
    for (const auto& e : b_pattern_.entries()) in[e.row] = 1;
    CloseUnderDynamics(/*downstream=*/true, &in);
    reach_.clear();
    for (int i = 0; i < kNx; ++i) {
      if (in[i]) reach_.push_back(i);
    }
    Eigen::Array<bool, kNx, kNx> mask = Eigen::Array<bool, kNx, kNx>::Constant(false);
    for (const auto& e : a_pattern_.entries()) mask(e.row, e.col) = in[e.row] && in[e.col];
    a_reach_pattern_.Reserve(kNx, kNx);
    a_reach_pattern_.SetFromMask(mask);
  }

  // Nonzeros of Q_k, Q_N and S_k for the current weights (rows with zero weight drop out).
  void BuildCostPatterns() {
    if (yx_cols_.empty()) return;  // before DetectStructure
    Eigen::Array<bool, kNx, kNx> q = Eigen::Array<bool, kNx, kNx>::Constant(false);
    Eigen::Array<bool, kNx, kNx> qn = Eigen::Array<bool, kNx, kNx>::Constant(false);
    Eigen::Array<bool, kNu, kNx> sm = Eigen::Array<bool, kNu, kNx>::Constant(false);
    weighted_rows_.clear();
    weighted_rows_n_.clear();
    for (int r = 0; r < kNy; ++r) {
      if (w_[r] != 0.0) weighted_rows_.push_back(r);
    }
    for (int r = 0; r < kNyN; ++r) {
      if (w_n_[r] != 0.0) weighted_rows_n_.push_back(r);
    }
    for (int r : weighted_rows_) {
      for (int a : yx_cols_[r]) {
        for (int b : yx_cols_[r]) q(a, b) = true;
        for (int i : yu_cols_[r]) sm(i, a) = true;
      }
    }
    for (int r : weighted_rows_n_) {
      for (int a : ynx_cols_[r]) {
        for (int b : ynx_cols_[r]) qn(a, b) = true;
      }
    }
    q_pattern_.SetFromMask(q);
    qn_pattern_.SetFromMask(qn);
    s_pattern_.SetFromMask(sm);
    FindCostRelevantStates(q, qn, sm);
    // Entries outside the new patterns must read as zero in the dense copies.
    for (auto& m : q_mat_) m.setZero();
    for (auto& m : s_mat_) m.setZero();
  }

  // rel_: the states that can influence the cost (rows of Q_k, Q_N and columns of S_k,
  // closed under A_k: a state entering the dynamics of a relevant one is relevant); the
  // rest never reaches the Riccati matrices. Chooses the condensing (riccati_, compact_).
  template <class QMask, class SMask>
  void FindCostRelevantStates(const QMask& q, const QMask& qn, const SMask& sm) {
    std::vector<char> in(kNx, 0);
    for (int i = 0; i < kNx; ++i) {
      in[i] = static_cast<char>(q.row(i).any() || qn.row(i).any() || sm.col(i).any());
    }
    CloseUnderDynamics(/*downstream=*/false, &in);
    rel_.clear();
    std::vector<int> pos(kNx, -1);
    for (int i = 0; i < kNx; ++i) {
      if (in[i]) {
        pos[i] = static_cast<int>(rel_.size());
        rel_.push_back(i);
      }
    }
    nr_ = static_cast<int>(rel_.size());
    riccati_ = kRiccatiCondensing || nr_ <= kMaxCompact;
    compact_ = !kRiccatiCondensing && riccati_;
    // Columns of Kt_k that can be nonzero (all, or rel_ when compact) and rows of G likewise.
    gain_reach_.clear();
    for (int i : reach_) {
      if (!compact_ || in[i]) gain_reach_.push_back(i);
    }
    if (compact_) {
      Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> mask =
          Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>::Constant(nr_, nr_, false);
      for (const auto& e : a_pattern_.entries()) {
        if (in[e.row]) mask(pos[e.row], pos[e.col]) = true;
      }
      ac_pattern_.Reserve(nr_, nr_);
      ac_pattern_.SetFromMask(mask);
      ac_full_.clear();
      for (const auto& e : ac_pattern_.entries()) ac_full_.push_back({rel_[e.row], rel_[e.col]});
      ac_ = MC::Zero(nr_, nr_);
      pc_mat_.assign(n_ + 1, MC::Zero(nr_, nr_));
    }
    qp_.h_factor_given = riccati_;
    if (nsl_ > 0) qp_no_slack_.h_factor_given = riccati_;
    condensed_ = false;
    last_qp_active_ = true;
  }

  Problem problem_;
  RtiSettings settings_;
  StateBoundLayout layout_;
  int n_ = 0, nsl_ = 0, nz_ = 0, nc_ = 0, nch_ = 0;
  // Rows of the (soft) QP: a soft component has a lower and an upper row, each with the
  // stage's slack. Rows of the hard QP (HardQp): one two-sided row per component and
  // stage; soft_to_hard_ maps the first onto the second.
  std::vector<Row> rows_, hard_rows_;
  std::vector<int> soft_to_hard_;
  std::vector<X> x_;
  std::vector<U> u_;
  std::vector<Y> yref_;
  YN yref_n_;
  Y w_;
  YN w_n_;
  std::vector<P> params_;
  std::vector<X> lbx_, ubx_;
  std::vector<U> lbu_, ubu_;
  std::vector<MX> a_;
  std::vector<MU> b_;
  std::vector<X> d_;
  std::vector<MX> q_mat_;
  std::vector<Mat<kNu, kNx>> s_mat_;
  std::vector<Mat<kNu, kNu>> r_mat_;
  std::vector<X> q_vec_;
  std::vector<U> r_vec_;
  std::vector<X> e_, dx_, lambda_, mu_;
  std::vector<U> du_;
  std::vector<Mat<kNu, kNx>> k_gain_;
  std::vector<MU> g_;
  SparsityPattern a_pattern_, b_pattern_, q_pattern_, qn_pattern_, s_pattern_;
  // Input-reachable states, A_k on them, and those among them that the gains Kt_k use.
  std::vector<int> reach_, gain_reach_;
  SparsityPattern a_reach_pattern_;
  std::vector<std::vector<int>> yx_cols_, yu_cols_, ynx_cols_;
  // Residual rows with a nonzero weight (stage, terminal): the only ones in Q, S, R, q, r.
  std::vector<int> weighted_rows_, weighted_rows_n_;
  // Residual Jacobian buffers (on the heap: kNy x kNx is large for F6), zero off-pattern.
  std::unique_ptr<Mat<kNy, kNx>> yx_buf_ = std::make_unique<Mat<kNy, kNx>>();
  std::unique_ptr<Mat<kNy, kNu>> yu_buf_ = std::make_unique<Mat<kNy, kNu>>();
  std::unique_ptr<Mat<kNyN, kNx>> ynx_buf_ = std::make_unique<Mat<kNyN, kNx>>();
  qp::DenseQp qp_;
  qp::QpSolution qp_solution_;
  std::unique_ptr<qp::DenseQpSolver> qp_solver_;
  // The QP without slack variables, tried first (SolveWithoutSlacks); only with soft bounds.
  qp::DenseQp qp_no_slack_;
  qp::QpSolution qp_no_slack_solution_;
  std::unique_ptr<qp::DenseQpSolver> qp_no_slack_solver_;
  RtiStats stats_;
  bool prepared_ = false;
  bool first_call_ = true;
  bool has_multipliers_ = false;
  // Riccati data of the small-nx path: P_k (k = 0..N), L_k, and kt_k of the last
  // unconstrained step; whether every Rbar_k was positive definite; whether the QP data
  // (G, factor blocks, constraint rows) is built; whether the last QP had an active
  // constraint (or failed).
  std::vector<MX> p_mat_;
  std::vector<Mat<kNu, kNu>> l_diag_;
  std::vector<U> kt_vec_;
  bool riccati_ok_ = false;
  bool riccati_ = kRiccatiCondensing;  // Riccati condensing (factor) instead of the Hessian
  bool compact_ = false;               // Riccati on the cost-relevant states rel_ only
  std::vector<int> rel_;
  int nr_ = kNx;
  SparsityPattern ac_pattern_;                   // A_k on rel_ x rel_ (compact indices)
  std::vector<SparsityPattern::Entry> ac_full_;  // the same entries, full indices
  MC ac_;
  std::vector<MC> pc_mat_;  // compact P_k
  bool condensed_ = false;
  bool last_qp_active_ = true;
};

}  // namespace fnmpc::rti
