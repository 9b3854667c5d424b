// SPDX-License-Identifier: BSD-3-Clause
// Structure of a problem, found once: the structural nonzeros of its stage matrices, the
// input-reachable and cost-relevant states, and the condensing strategy they select.
#pragma once

#include <algorithm>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/rti/problem_contract.hpp"
#include "fnmpc/rti/rti_settings.hpp"
#include "fnmpc/rti/sparsity.hpp"

namespace fnmpc::rti {

/// The sparsity patterns of A_k, B_k, Q_k, Q_N, S_k and of the residual Jacobians: the
/// entries that the problem's Discretise and residual functions write (both write the
/// same entries on every call; NaN marks the others), and for Q and S only residual rows
/// with a nonzero weight. Detect() runs once at construction; BuildCostPatterns() again
/// whenever the weights' zero pattern changes (SetWeights).
template <class Problem>
struct ProblemStructure {
  static constexpr int kNx = Problem::kNx, kNu = Problem::kNu, kNy = Problem::kNy,
                       kNyN = Problem::kNyN;
  using X = Vec<kNx>;
  using U = Vec<kNu>;
  using Y = Vec<kNy>;
  using YN = Vec<kNyN>;
  using P = typename Problem::Params;
  using MX = Mat<kNx, kNx>;
  using MU = Mat<kNx, kNu>;
  using Model = typename detail::ModelOf<Problem>::type;

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
  // Products with A_k by the model's own block structure when it offers them.
  static constexpr bool kStructuredA = detail::HasStructuredTransition<Model>::value;
  // Small nx: B_k, Q_k and S_k as dense fixed-size products (their entries off the pattern
  // are zero). A loop over a handful of structural nonzeros is slower there: consecutive
  // entries update the same output entry, a chain of dependent loads and stores.
  static constexpr bool kDenseStageProducts = kNx <= 16;

  /// Finds the patterns of the problem's functions (evaluated at zero with zero parameters).
  void Detect(const Problem& problem, const RtiSettings& settings) {
    MX a = MX::Constant(kNaN);
    MU b = MU::Constant(kNaN);
    const P p0 = detail::ZeroParams<P>();
    problem.Discretise(X::Zero(), U::Zero(), p0, settings.sample_time, settings.integrator_steps,
                       &a, &b);
    a_pattern.SetFromWritten(a);
    b_pattern.SetFromWritten(b);
    FindReachableStates();
    Y y;
    YN yn;
    // On the heap: kNy x kNx is large for F6.
    auto yx = std::make_unique<Mat<kNy, kNx>>(Mat<kNy, kNx>::Constant(kNaN));
    auto yu = std::make_unique<Mat<kNy, kNu>>(Mat<kNy, kNu>::Constant(kNaN));
    auto ynx = std::make_unique<Mat<kNyN, kNx>>(Mat<kNyN, kNx>::Constant(kNaN));
    problem.StageResidual(X::Zero(), U::Zero(), p0, &y, yx.get(), yu.get());
    problem.TerminalResidual(X::Zero(), p0, &yn, ynx.get());
    // (x == x is false exactly for NaN: the entries written)
    const Eigen::Array<bool, kNy, kNx> yx_mask = yx->array() == yx->array();
    const Eigen::Array<bool, kNy, kNu> yu_mask = yu->array() == yu->array();
    const Eigen::Array<bool, kNyN, kNx> ynx_mask = ynx->array() == ynx->array();
    const auto columns = [](const auto& mask, std::vector<std::vector<int>>* cols) {
      cols->assign(mask.rows(), {});
      for (int r = 0; r < mask.rows(); ++r) {
        for (int c = 0; c < mask.cols(); ++c) {
          if (mask(r, c)) (*cols)[r].push_back(c);
        }
      }
    };
    columns(yx_mask, &yx_cols);
    columns(yu_mask, &yu_cols);
    columns(ynx_mask, &ynx_cols);
    q_pattern.Reserve(kNx, kNx);
    qn_pattern.Reserve(kNx, kNx);
    weighted_rows.reserve(kNy);
    weighted_rows_n.reserve(kNyN);
    s_pattern.Reserve(kNu, kNx);
  }

  /// Nonzeros of Q_k, Q_N and S_k for the weights (rows with zero weight drop out), the
  /// cost-relevant states and the condensing they select (riccati, compact).
  void BuildCostPatterns(const Y& w, const YN& w_n) {
    Eigen::Array<bool, kNx, kNx> q = Eigen::Array<bool, kNx, kNx>::Constant(false);
    Eigen::Array<bool, kNx, kNx> qn = Eigen::Array<bool, kNx, kNx>::Constant(false);
    Eigen::Array<bool, kNu, kNx> sm = Eigen::Array<bool, kNu, kNx>::Constant(false);
    weighted_rows.clear();
    weighted_rows_n.clear();
    for (int r = 0; r < kNy; ++r) {
      if (w[r] != 0.0) weighted_rows.push_back(r);
    }
    for (int r = 0; r < kNyN; ++r) {
      if (w_n[r] != 0.0) weighted_rows_n.push_back(r);
    }
    for (int r : weighted_rows) {
      for (int a : yx_cols[r]) {
        for (int b : yx_cols[r]) q(a, b) = true;
        for (int i : yu_cols[r]) sm(i, a) = true;
      }
    }
    for (int r : weighted_rows_n) {
      for (int a : ynx_cols[r]) {
        for (int b : ynx_cols[r]) qn(a, b) = true;
      }
    }
    q_pattern.SetFromMask(q);
    qn_pattern.SetFromMask(qn);
    s_pattern.SetFromMask(sm);
    FindCostRelevantStates(q, qn, sm);
  }

  /// Throws std::invalid_argument (naming the setter) when a nonzero weight falls on a row
  /// outside the weighted rows of the last BuildCostPatterns.
  void CheckWithinCostPattern(const char* setter, const Y& w, const YN& w_n) const {
    auto in = [](const std::vector<int>& rows, int r) {
      return std::find(rows.begin(), rows.end(), r) != rows.end();
    };
    for (int r = 0; r < kNy; ++r) {
      if (w[r] != 0.0 && !in(weighted_rows, r))
        throw std::invalid_argument(std::string("[RtiSolver] ") + setter + ": stage row " +
                                    std::to_string(r) + " is outside the cost pattern");
    }
    for (int r = 0; r < kNyN; ++r) {
      if (w_n[r] != 0.0 && !in(weighted_rows_n, r))
        throw std::invalid_argument(std::string("[RtiSolver] ") + setter + ": terminal row " +
                                    std::to_string(r) + " is outside the cost pattern");
    }
  }

  SparsityPattern a_pattern, b_pattern, q_pattern, qn_pattern, s_pattern;
  // Input-reachable states, A_k on them, and those among them that the gains Kt_k use.
  std::vector<int> reach, gain_reach;
  SparsityPattern a_reach_pattern;
  // Nonzero columns of each row of the residual Jacobians (stage x, stage u, terminal x).
  std::vector<std::vector<int>> yx_cols, yu_cols, ynx_cols;
  // Residual rows with a nonzero weight (stage, terminal): the only ones in Q, S, R, q, r.
  std::vector<int> weighted_rows, weighted_rows_n;
  bool riccati = kRiccatiCondensing;  // Riccati condensing (factor) instead of the Hessian
  bool compact = false;               // Riccati on the cost-relevant states rel only
  std::vector<int> rel;               // the cost-relevant states
  int nr = kNx;                       // their number
  SparsityPattern ac_pattern;         // A_k on rel x rel (compact indices)
  std::vector<SparsityPattern::Entry> ac_full;  // the same entries, full indices

 private:
  // Closes the state set *in under the couplings of A_k: downstream adds every state whose
  // dynamics involve a member, upstream every state that enters a member's dynamics.
  void CloseUnderDynamics(bool downstream, std::vector<char>* in) const {
    std::vector<char>& set = *in;
    for (bool changed = true; changed;) {
      changed = false;
      for (const auto& e : a_pattern.entries()) {
        const int from = downstream ? e.col : e.row;
        const int to = downstream ? e.row : e.col;
        if (set[from] && !set[to]) {
          set[to] = 1;
          changed = true;
        }
      }
    }
  }

  // reach: the states the inputs can move (rows of B_k, closed under A_k: a state whose
  // dynamics involve a reachable one is reachable); the other rows of G are zero.
  void FindReachableStates() {
    std::vector<char> in(kNx, 0);
    for (const auto& e : b_pattern.entries()) in[e.row] = 1;
    CloseUnderDynamics(/*downstream=*/true, &in);
    reach.clear();
    for (int i = 0; i < kNx; ++i) {
      if (in[i]) reach.push_back(i);
    }
    Eigen::Array<bool, kNx, kNx> mask = Eigen::Array<bool, kNx, kNx>::Constant(false);
    for (const auto& e : a_pattern.entries()) mask(e.row, e.col) = in[e.row] && in[e.col];
    a_reach_pattern.Reserve(kNx, kNx);
    a_reach_pattern.SetFromMask(mask);
  }

  // rel: the states that can influence the cost (rows of Q_k, Q_N and columns of S_k,
  // closed under A_k: a state entering the dynamics of a relevant one is relevant); the
  // rest never reaches the Riccati matrices. Chooses the condensing (riccati, compact).
  template <class QMask, class SMask>
  void FindCostRelevantStates(const QMask& q, const QMask& qn, const SMask& sm) {
    std::vector<char> in(kNx, 0);
    for (int i = 0; i < kNx; ++i) {
      in[i] = static_cast<char>(q.row(i).any() || qn.row(i).any() || sm.col(i).any());
    }
    CloseUnderDynamics(/*downstream=*/false, &in);
    rel.clear();
    std::vector<int> pos(kNx, -1);
    for (int i = 0; i < kNx; ++i) {
      if (in[i]) {
        pos[i] = static_cast<int>(rel.size());
        rel.push_back(i);
      }
    }
    nr = static_cast<int>(rel.size());
    riccati = kRiccatiCondensing || nr <= kMaxCompact;
    compact = !kRiccatiCondensing && riccati;
    // Columns of Kt_k that can be nonzero (all, or rel when compact) and rows of G likewise.
    gain_reach.clear();
    for (int i : reach) {
      if (!compact || in[i]) gain_reach.push_back(i);
    }
    if (compact) {
      Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> mask =
          Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>::Constant(nr, nr, false);
      for (const auto& e : a_pattern.entries()) {
        if (in[e.row]) mask(pos[e.row], pos[e.col]) = true;
      }
      ac_pattern.Reserve(nr, nr);
      ac_pattern.SetFromMask(mask);
      ac_full.clear();
      for (const auto& e : ac_pattern.entries()) ac_full.push_back({rel[e.row], rel[e.col]});
    }
  }
};

}  // namespace fnmpc::rti
