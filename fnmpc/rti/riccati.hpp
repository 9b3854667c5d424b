// SPDX-License-Identifier: BSD-3-Clause
// Riccati condensing (nx <= 32, or at most 32 cost-relevant states): the backward Riccati
// recursion, the Cholesky factor of the condensed Hessian assembled from it, and the
// unconstrained minimiser of the QP by the same factorisation (docs/rti.md).
#pragma once

#include <Eigen/Cholesky>

#include "fnmpc/qp/dense_qp.hpp"
#include "fnmpc/rti/dimensions.hpp"
#include "fnmpc/rti/iterate.hpp"
#include "fnmpc/rti/stage_data.hpp"
#include "fnmpc/rti/stage_products.hpp"
#include "fnmpc/rti/workspace.hpp"

namespace fnmpc::rti::riccati {

// out = l^-1 in for a lower-triangular kNu x kNu l (Eigen's triangular solve for a
// matrix right-hand side goes through its blocked GEMM kernel).
template <int kNu, class In, class Out>
void ForwardSubstitute(const Mat<kNu, kNu>& l, const In& in, Out* out) {
  for (int i = 0; i < kNu; ++i) {
    out->row(i) = in.row(i);
    for (int c = 0; c < i; ++c) out->row(i) -= l(i, c) * out->row(c);
    out->row(i) /= l(i, i);
  }
}

// One Riccati stage's factorisation: Rbar_k = L_k L_k' and Kt = L_k^-1 Sbar. A Rbar_k
// that is not positive definite leaves L_k = 0 and Kt = 0 (the QP then reports
// kNotConvex) and clears riccati_ok.
template <class Problem, class Sbar, class Kt>
void FactorStage(int k, const Mat<Problem::kNu, Problem::kNu>& rbar, const Sbar& sbar, Kt* kt,
                 RtiWorkspace<Problem>* ws) {
  constexpr int kNu = Problem::kNu;
  const Eigen::LLT<Mat<kNu, kNu>> llt(rbar);
  if (llt.info() == Eigen::Success) {
    ws->l_diag[k] = llt.matrixL();
    ForwardSubstitute<kNu>(ws->l_diag[k], sbar, kt);
  } else {
    ws->l_diag[k].setZero();
    kt->setZero();
    ws->riccati_ok = false;
  }
}

// Riccati recursion P_N = Q_N, Rbar_k = R_k + B_k' P_k+1 B_k = L_k L_k',
// Kt_k = L_k^-1 (S_k + B_k' P_k+1 A_k), P_k = Q_k + A_k' P_k+1 A_k - Kt_k' Kt_k
// (k >= 1: x_0 is fixed, P_0 is not needed): O(N nx^3); FactorStage handles an Rbar_k
// that is not positive definite.
template <class Problem>
void Recursion(const RtiDimensions& dims, const StageQp<Problem>& sq,
               const StageProducts<Problem>& ops, RtiWorkspace<Problem>* ws) {
  constexpr int kNx = Problem::kNx, kNu = Problem::kNu;
  using MX = Mat<kNx, kNx>;
  const int n = dims.n;
  ws->riccati_ok = true;
  ws->p_mat[n] = sq.q_mat[n];
  for (int k = n - 1; k >= 0; --k) {
    const MX& p = ws->p_mat[k + 1];
    const Mat<kNu, kNx> bp = sq.b[k].transpose() * p;
    Mat<kNu, kNu> rbar = sq.r_mat[k];
    rbar.noalias() += bp * sq.b[k];
    Mat<kNu, kNx> bpa;
    ops.MultiplyARight(k, bp, &bpa);
    const Mat<kNu, kNx> sbar = sq.s_mat[k] + bpa;
    Mat<kNu, kNx>& kt = ws->k_gain[k];
    FactorStage<Problem>(k, rbar, sbar, &kt, ws);
    if (k == 0) break;  // P_0 is never used
    MX pa, apa;
    ops.MultiplyARight(k, p, &pa);
    ops.MultiplyATransposed(k, pa, &apa);
    ws->p_mat[k] = sq.q_mat[k] + apa;
    // Kt_k' as a column-major copy: the product then runs on whole columns (vectorised);
    // with the transposed view of Kt_k its entries would be read one by one.
    const Mat<kNx, kNu> ktt = kt.transpose();
    ws->p_mat[k].noalias() -= ktt * kt;
  }
}

// Recursion() on the cost-relevant states s.rel (kMaxCompact at most): the same recursion
// with A_k, B_k, Q_k, S_k restricted to them; Kt_k is scattered back (zero elsewhere).
template <class Problem>
void CompactRecursion(const RtiDimensions& dims, const ProblemStructure<Problem>& s,
                      const StageQp<Problem>& sq, RtiWorkspace<Problem>* ws) {
  constexpr int kNx = Problem::kNx, kNu = Problem::kNu;
  using MX = Mat<kNx, kNx>;
  using W = RtiWorkspace<Problem>;
  using MC = typename W::MC;
  using UC = typename W::UC;
  using BC = typename W::BC;
  const int n = dims.n;
  ws->riccati_ok = true;
  const int nr = s.nr;
  const auto gather_q = [&](const MX& q, MC* out) {
    for (int i = 0; i < nr; ++i) {
      for (int j = 0; j < nr; ++j) (*out)(i, j) = q(s.rel[i], s.rel[j]);
    }
  };
  gather_q(sq.q_mat[n], &ws->pc_mat[n]);
  for (int k = n - 1; k >= 0; --k) {
    const MC& p = ws->pc_mat[k + 1];
    for (std::size_t e = 0; e < s.ac_full.size(); ++e) {
      const auto& c = s.ac_pattern.entries()[e];
      ws->ac(c.row, c.col) = sq.a[k](s.ac_full[e].row, s.ac_full[e].col);
    }
    BC bc(nr, kNu);
    UC sc(kNu, nr);
    for (int i = 0; i < nr; ++i) {
      bc.row(i) = sq.b[k].row(s.rel[i]);
      sc.col(i) = sq.s_mat[k].col(s.rel[i]);
    }
    const UC bp = bc.transpose().lazyProduct(p);
    Mat<kNu, kNu> rbar = sq.r_mat[k];
    rbar += bp.lazyProduct(bc);
    UC bpa(kNu, nr);
    s.ac_pattern.MultiplyRight(bp, ws->ac, &bpa);
    const UC sbar = sc + bpa;
    UC kt(kNu, nr);
    FactorStage<Problem>(k, rbar, sbar, &kt, ws);
    ws->k_gain[k].setZero();
    for (int i = 0; i < nr; ++i) ws->k_gain[k].col(s.rel[i]) = kt.col(i);
    if (k == 0) break;  // P_0 is never used
    MC pa(nr, nr);
    s.ac_pattern.MultiplyRight(p, ws->ac, &pa);
    MC& pk = ws->pc_mat[k];
    gather_q(sq.q_mat[k], &pk);
    s.ac_pattern.AddTransposedProduct(ws->ac, pa, &pk);
    pk -= kt.transpose().lazyProduct(kt);
  }
}

// Cholesky factor of the condensed Hessian from the Riccati recursion: with the inputs
// ordered last stage first, it has the diagonal blocks L_k and below them
// (Kt_k G(k-1, j))' for j < k, since eliminating u_N-1 first is one backward Riccati
// step: O(N^2 nx nu^2), as much as forming the Hessian, and the QP needs no
// factorisation. Needs the sensitivities G (condensing.hpp).
template <class Problem>
void FactorBlocks(const RtiDimensions& dims, const ProblemStructure<Problem>& s,
                  const RtiWorkspace<Problem>& ws, qp::DenseQp* qp) {
  constexpr int kNu = Problem::kNu;
  const int n = dims.n;
  Eigen::MatrixXd& l = qp->L;
  for (int k = 0; k < n; ++k) l.template block<kNu, kNu>(dims.UPos(k), dims.UPos(k)) = ws.l_diag[k];
  for (int k = 1; k < n; ++k) {
    for (int j = 0; j < k; ++j) {
      if constexpr (ProblemStructure<Problem>::kStructuredA) {
        l.template block<kNu, kNu>(dims.UPos(j), dims.UPos(k)).noalias() =
            (ws.k_gain[k] * ws.G(k - 1, j)).transpose();
      } else {
        // Over the states where both Kt_k and G can be nonzero.
        Mat<kNu, kNu> kg = Mat<kNu, kNu>::Zero();
        for (int i : s.gain_reach) kg.noalias() += ws.k_gain[k].col(i) * ws.G(k - 1, j).row(i);
        l.template block<kNu, kNu>(dims.UPos(j), dims.UPos(k)) = kg.transpose();
      }
    }
  }
}

// The unconstrained minimiser of the QP by the Riccati factorisation: backward
// w = P_k+1 d_k + p_k+1, kt_k = L_k^-1 (r_k + B_k' w), p_k = q_k + A_k' w - Kt_k' kt_k;
// forward du_k = -L_k^-T (Kt_k dx_k + kt_k), dx_k+1 = A_k dx_k + B_k du_k + d_k.
// O(N nx^2), no condensing. Writes the step (dx, du) of *it and returns whether it is
// finite and satisfies every input and state bound (soft ones as hard).
template <class Problem>
bool UnconstrainedStep(const RtiDimensions& dims, const ProblemStructure<Problem>& s,
                       const StageQp<Problem>& sq, const StageProducts<Problem>& ops,
                       const StageData<Problem>& data, const Vec<Problem::kNx>& x0,
                       Iterate<Problem>* it, RtiWorkspace<Problem>* ws) {
  constexpr int kNu = Problem::kNu;
  using X = Vec<Problem::kNx>;
  using U = Vec<kNu>;
  using VC = typename RtiWorkspace<Problem>::VC;
  const int n = dims.n;
  X p = sq.q_vec[n];
  for (int k = n - 1; k >= 0; --k) {
    X w = p;
    if (s.compact) {
      VC dc(s.nr);
      for (int i = 0; i < s.nr; ++i) dc[i] = sq.d[k][s.rel[i]];
      const VC pd = ws->pc_mat[k + 1].lazyProduct(dc);
      for (int i = 0; i < s.nr; ++i) w[s.rel[i]] += pd[i];
    } else if constexpr (ProblemStructure<Problem>::kRiccatiCondensing) {
      w.noalias() += ws->p_mat[k + 1] * sq.d[k];
    }
    U r = sq.r_vec[k];
    ops.AddBTransposed(k, w, &r);
    ForwardSubstitute<kNu>(ws->l_diag[k], r, &ws->kt_vec[k]);
    ops.MultiplyATransposed(k, w, &p);
    p += sq.q_vec[k];
    p.noalias() -= ws->k_gain[k].transpose() * ws->kt_vec[k];
  }
  it->dx[0] = x0 - it->x[0];
  bool feasible = true;
  for (int k = 0; k < n; ++k) {
    U v = ws->kt_vec[k];
    v.noalias() += ws->k_gain[k] * it->dx[k];
    ws->l_diag[k].transpose().template triangularView<Eigen::Upper>().solveInPlace(v);
    it->du[k] = -v;
    ops.MultiplyA(k, it->dx[k], &it->dx[k + 1]);
    ops.AddB(k, it->du[k], &it->dx[k + 1]);
    it->dx[k + 1] += sq.d[k];
    const U u_new = it->u[k] + it->du[k];
    feasible = feasible && (u_new.array() >= data.lbu[k].array()).all() &&
               (u_new.array() <= data.ubu[k].array()).all();
  }
  for (int h = 0; h < dims.nch && feasible; ++h) {
    const BoundRow& row = dims.hard_rows[h];
    const double v = it->x[row.stage][row.index] + it->dx[row.stage][row.index];
    feasible = v >= data.lbx[row.stage][row.index] && v <= data.ubx[row.stage][row.index];
  }
  return feasible;  // (false also when NaN: comparisons with NaN are false)
}

}  // namespace fnmpc::rti::riccati
