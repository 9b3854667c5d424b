// SPDX-License-Identifier: BSD-3-Clause
// The RTI solver: Algorithm 1 of the reference work over the pieces of docs/rti.md's
// "Structure of the solver" (problem contract, dimensions, stage data, structure,
// workspace, condensing strategies, QP interface).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "fnmpc/core/assert.hpp"
#include "fnmpc/core/eigen_abi.hpp"
#include "fnmpc/core/stopwatch.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/qp/dense_qp.hpp"
#include "fnmpc/rti/condensed_qp.hpp"
#include "fnmpc/rti/condensing.hpp"
#include "fnmpc/rti/dimensions.hpp"
#include "fnmpc/rti/iterate.hpp"
#include "fnmpc/rti/kkt.hpp"
#include "fnmpc/rti/problem_contract.hpp"
#include "fnmpc/rti/riccati.hpp"
#include "fnmpc/rti/rti_settings.hpp"
#include "fnmpc/rti/stage_data.hpp"
#include "fnmpc/rti/stage_products.hpp"
#include "fnmpc/rti/stage_qp.hpp"
#include "fnmpc/rti/structure.hpp"
#include "fnmpc/rti/workspace.hpp"

namespace fnmpc::rti {

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

  /// Validates the settings and the layout (std::invalid_argument), finds the problem's
  /// structure and allocates everything the control step uses.
  RtiSolver(const Problem& problem, const RtiSettings& settings, const StateBoundLayout& layout)
      : problem_(problem),
        settings_(Validated(settings)),
        layout_(layout),
        dims_(settings_.horizon, kNx, kNu, layout_),
        data_(dims_.n),
        it_(dims_.n),
        sq_(dims_.n),
        ws_(dims_.n),
        qp_(dims_, settings_) {
    structure_.Detect(problem_, settings_);
    structure_.BuildCostPatterns(data_.w, data_.w_n);
    OnCostPatternsChanged();
  }

  // ---- Stage data (call before Prepare(); no allocation) ----
  // Setters check their arguments: a stage index out of range throws std::out_of_range, a
  // negative or NaN weight std::invalid_argument (programming errors, found at setup).

  /// Diagonal weights of the stage (kNy) and terminal (kNyN) residuals, each >= 0.
  void SetWeights(const Y& w, const YN& w_terminal) {
    CheckWeights("SetWeights", w, w_terminal);
    data_.w = w;
    data_.w_n = w_terminal;
    structure_.BuildCostPatterns(data_.w, data_.w_n);
    OnCostPatternsChanged();
  }
  /// New weight values within the cost sparsity found by the last SetWeights: a weighted
  /// row may get weight zero (it then contributes nothing) but a row unweighted there may
  /// not become weighted. Keeps the patterns, so no allocation (SetWeights rebuilds them).
  /// Throws std::invalid_argument for a row outside the pattern.
  void SetWeightValues(const Y& w, const YN& w_terminal) {
    CheckWeights("SetWeightValues", w, w_terminal);
    structure_.CheckWithinCostPattern("SetWeightValues", w, w_terminal);
    data_.w = w;
    data_.w_n = w_terminal;
  }
  /// Reference of stage k = 0..N-1.
  void SetReference(int k, const Y& yref) {
    CheckStage("SetReference", k, 0, dims_.n - 1, dims_.n);
    data_.yref[k] = yref;
  }
  void SetTerminalReference(const YN& yref) { data_.yref_n = yref; }
  /// Parameters (online data) of node k = 0..N, passed to the problem's functions.
  void SetParameters(int k, const P& p) {
    CheckStage("SetParameters", k, 0, dims_.n, dims_.n);
    data_.params[k] = p;
  }
  /// Bounds on the layout's state components at node k = 1..N (other entries ignored).
  void SetStateBounds(int k, const X& lb, const X& ub) {
    CheckStage("SetStateBounds", k, 1, dims_.n, dims_.n);
    data_.lbx[k] = lb;
    data_.ubx[k] = ub;
  }
  /// Input bounds of stage k = 0..N-1.
  void SetInputBounds(int k, const U& lb, const U& ub) {
    CheckStage("SetInputBounds", k, 0, dims_.n - 1, dims_.n);
    data_.lbu[k] = lb;
    data_.ubu[k] = ub;
  }

  /// Initial guess: every node at x0, every control at u (spec: (m g, 0, 0)).
  void InitializeGuess(const X& x0, const U& u) {
    std::fill(it_.x.begin(), it_.x.end(), x0);
    std::fill(it_.u.begin(), it_.u.end(), u);
    first_call_ = true;
    prepared_ = false;
  }

  /// Warm start for the next sampling time: drop the first node, duplicate the last.
  void Shift() {
    const int n = dims_.n;
    for (int k = 0; k < n; ++k) it_.x[k] = it_.x[k + 1];
    for (int k = 0; k + 1 < n; ++k) it_.u[k] = it_.u[k + 1];
    prepared_ = false;
  }

  /// Adds `delta` to every node of the state guess. Used by the reduced follower, whose
  /// displacement state restarts at zero every sampling time (a translation of the guess
  /// leaves the linearisation of a translation-invariant problem unchanged).
  void OffsetGuess(const X& delta) {
    for (X& x : it_.x) x += delta;
    prepared_ = false;
  }

  /// Linearise and condense around the current guess (the preparation phase).
  /// Returns false when the linearisation produced NaN/Inf.
  bool Prepare() {
    Stopwatch sw;
    const int n = dims_.n;
    const ProblemStructure<Problem>& s = structure_;
    bool finite = true;
    Y y;
    // The problem writes only the Jacobians' structural nonzeros; the rest stays zero.
    Mat<kNy, kNx>& yx = *ws_.yx;
    Mat<kNy, kNu>& yu = *ws_.yu;
    for (int k = 0; k < n; ++k) {
      const X next = problem_.Discretise(it_.x[k], it_.u[k], data_.params[k], settings_.sample_time,
                                         settings_.integrator_steps, &sq_.a[k], &sq_.b[k]);
      sq_.d[k] = next - it_.x[k + 1];
      problem_.StageResidual(it_.x[k], it_.u[k], data_.params[k], &y, &yx, &yu);
      const Y wr = data_.w.cwiseProduct(y - data_.yref[k]);
      sq_.GaussNewtonBlocks(yx, &yu, data_.w, wr, s.weighted_rows, s.yx_cols, s.yu_cols,
                            s.q_pattern, s.s_pattern, k);
      finite = finite && StageFinite(k);
    }
    {
      YN yn;
      Mat<kNyN, kNx>& ynx = *ws_.ynx;
      problem_.TerminalResidual(it_.x[n], data_.params[n], &yn, &ynx);
      const YN wr = data_.w_n.cwiseProduct(yn - data_.yref_n);
      sq_.template GaussNewtonBlocks<Mat<kNyN, kNx>, Mat<kNyN, kNu>>(
          ynx, nullptr, data_.w_n, wr, s.weighted_rows_n, s.ynx_cols, {}, s.qn_pattern, s.s_pattern,
          n);
      finite = finite && sq_.q_vec[n].allFinite();
    }
    if (s.riccati) {
      if (s.compact) {
        riccati::CompactRecursion(dims_, s, sq_, &ws_);
      } else {
        riccati::Recursion(dims_, sq_, StageProducts<Problem>(s, sq_, n), &ws_);
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
      const StageProducts<Problem> ops(structure_, sq_, dims_.n);
      condensing::GradientAndBounds(dims_, sq_, ops, data_, it_, x0, &ws_, &qp_.hard());
      const qp::QpStatus qs = qp_.Solve(dims_, settings_);
      const qp::QpSolution& sol = qp_.solution();
      stats_.qp_status = qs;
      stats_.qp_iterations += sol.iterations;
      last_qp_active_ = sol.y_bounds.head(dims_.nv).any() || sol.y_constraints.any() ||
                        qs != qp::QpStatus::kOptimal;
      if (qs != qp::QpStatus::kOptimal) {
        status = RtiStatus::kQpFailure;
      } else if (!condensing::Expand(dims_, sq_, ops, ws_, sol.x, &it_)) {
        status = RtiStatus::kNanDetected;
      } else {
        ApplyStep(x0);
      }
    }
    prepared_ = false;
    *u0 = it_.u[0];
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
    // (max_iterations = 1) never reads the thread CPU clock, a system call of about 1 us.
    // It stays CPU time, not wall time: Algorithm 1 of the reference work budgets CPU time,
    // and a wall budget would let preemption (other processes, the simulator's other
    // vehicles) change the number of SQP iterations, and with it the trajectory, from one
    // run of the same seed to the next. The wall time of the step is stats().time_total;
    // one CPU-clock reading per extra iteration is small next to its Prepare() + Feedback().
    const bool budgeted = !first && cap > 1;
    const double cpu0 = budgeted ? ThreadCpuSeconds() : 0.0;
    RtiStatus status = RtiStatus::kSuccess;
    const U fallback_u = it_.u[0];
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

  /// KKT value of the current iterate with the last QP's multipliers (benchmark spec,
  /// kkt.hpp). Linearises at the current iterate, so call it outside timed sections. Uses
  /// the data of the last Prepare()/Feedback(); infinity before the first step.
  double ComputeKkt(const X& x0) {
    if (!has_multipliers_) return kInf;
    return KktValue(problem_, settings_, dims_, data_, sq_, qp_.solution(), x0, &it_, &ws_);
  }

  // ---- Accessors ----
  [[nodiscard]] const std::vector<X>& states() const { return it_.x; }
  [[nodiscard]] const std::vector<U>& inputs() const { return it_.u; }
  [[nodiscard]] const RtiStats& stats() const { return stats_; }
  [[nodiscard]] const RtiSettings& settings() const { return settings_; }
  [[nodiscard]] const Problem& problem() const { return problem_; }
  [[nodiscard]] int horizon() const { return dims_.n; }
  [[nodiscard]] const RtiDimensions& dimensions() const { return dims_; }
  [[nodiscard]] const ProblemStructure<Problem>& structure() const { return structure_; }
  [[nodiscard]] const qp::QpSolution& qp_solution() const { return qp_.solution(); }
  /// Slack of stage k = 1..N of the soft bounds in the last QP (0 without soft bounds).
  [[nodiscard]] double slack(int k) const {
    return dims_.nsl > 0 ? qp_.solution().x[dims_.nv + k - 1] : 0.0;
  }
  [[nodiscard]] const X& lower_state_bound(int k) const { return data_.lbx[k]; }
  [[nodiscard]] const X& upper_state_bound(int k) const { return data_.ubx[k]; }
  [[nodiscard]] const U& lower_input_bound(int k) const { return data_.lbu[k]; }
  [[nodiscard]] const U& upper_input_bound(int k) const { return data_.ubu[k]; }
  [[nodiscard]] const StateBoundLayout& layout() const { return layout_; }

 private:
  static RtiSettings Validated(RtiSettings settings) {
    settings.Validate();
    return settings;
  }

  // After new cost patterns (construction, SetWeights): the condensing they select, and
  // entries outside them reading as zero in the dense Q_k and S_k.
  void OnCostPatternsChanged() {
    sq_.ClearCost();
    if (structure_.compact) ws_.AllocateCompact(structure_.nr);
    qp_.SetFactorGiven(structure_.riccati);
    condensed_ = false;
    last_qp_active_ = true;
  }

  // Whether A_k, B_k, d_k, q_k and r_k of the linearisation are finite (NaN in a weighted
  // residual reaches q_k or r_k; zero-weight rows do not matter). One sum per block: it is
  // finite when every entry is and NaN or infinite when one is not (or when finite entries
  // overflow, as wrong as NaN), instead of a test per entry. Small nx: A_k and B_k densely
  // (their entries off the pattern are zero), else over their structural nonzeros.
  [[nodiscard]] bool StageFinite(int k) const {
    double sum = sq_.d[k].sum() + sq_.q_vec[k].sum() + sq_.r_vec[k].sum();
    if constexpr (ProblemStructure<Problem>::kDenseStageProducts) {
      sum += sq_.a[k].sum() + sq_.b[k].sum();
    } else if (!structure_.a_pattern.AllFinite(sq_.a[k]) ||
               !structure_.b_pattern.AllFinite(sq_.b[k])) {
      return false;
    }
    return std::isfinite(sum);
  }

  // Dense condensing of the Hessian (or its factor) and the constraint rows.
  void Condense() {
    condensed_ = true;
    condensing::Condense(dims_, structure_, sq_, &ws_, &qp_.hard());
  }

  // The unconstrained Riccati step when the Riccati data is valid; when it satisfies every
  // bound it is recorded as the QP's solution and true returned.
  bool TryUnconstrainedStep(const X& x0) {
    if (!structure_.riccati || !ws_.riccati_ok) return false;
    const StageProducts<Problem> ops(structure_, sq_, dims_.n);
    if (!riccati::UnconstrainedStep(dims_, structure_, sq_, ops, data_, x0, &it_, &ws_)) {
      return false;
    }
    qp_.SetUnconstrainedSolution(dims_, it_.du);
    return true;
  }

  // Iterate update by the step (dx, du) of the last QP, with the measured x0 embedded.
  void ApplyStep(const X& x0) {
    for (int k = 0; k <= dims_.n; ++k) it_.x[k] += it_.dx[k];
    for (int k = 0; k < dims_.n; ++k) it_.u[k] += it_.du[k];
    it_.x[0] = x0;
    has_multipliers_ = true;
  }

  Problem problem_;
  RtiSettings settings_;
  StateBoundLayout layout_;
  RtiDimensions dims_;
  StageData<Problem> data_;
  Iterate<Problem> it_;
  StageQp<Problem> sq_;
  ProblemStructure<Problem> structure_;
  RtiWorkspace<Problem> ws_;
  CondensedQp qp_;
  RtiStats stats_;
  bool prepared_ = false;
  bool first_call_ = true;
  bool has_multipliers_ = false;
  bool condensed_ = false;      // the QP data (G, factor or Hessian, rows) is built
  bool last_qp_active_ = true;  // the last QP had an active constraint (or failed)
};

}  // namespace fnmpc::rti
