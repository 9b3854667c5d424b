// SPDX-License-Identifier: BSD-3-Clause
// Condensing of the stage QP into the dense QP in the input increments: the sensitivities
// G(k, j), the Hessian (riccati.hpp's factor or column_sweep.hpp's Hessian), the
// constraint rows, and the x0-dependent gradient and bounds; expansion of the QP's
// solution back into the stage step.
#pragma once

#include "fnmpc/qp/dense_qp.hpp"
#include "fnmpc/rti/column_sweep.hpp"
#include "fnmpc/rti/dimensions.hpp"
#include "fnmpc/rti/iterate.hpp"
#include "fnmpc/rti/riccati.hpp"
#include "fnmpc/rti/stage_data.hpp"
#include "fnmpc/rti/stage_products.hpp"
#include "fnmpc/rti/workspace.hpp"

namespace fnmpc::rti::condensing {

// G(k, j) = d x_{k+1} / d u_j for j <= k. Without a structured product: only the rows
// of the input-reachable states (the others are zero in every G).
template <class Problem>
void Sensitivities(const RtiDimensions& dims, const ProblemStructure<Problem>& s,
                   const StageQp<Problem>& sq, const StageProducts<Problem>& ops,
                   RtiWorkspace<Problem>* ws) {
  using MU = Mat<Problem::kNx, Problem::kNu>;
  const int n = dims.n;
  for (int j = 0; j < n; ++j) {
    ws->G(j, j) = sq.b[j];
    for (int k = j + 1; k < n; ++k) {
      if constexpr (ProblemStructure<Problem>::kStructuredA) {
        ops.MultiplyA(k, ws->G(k - 1, j), &ws->G(k, j));
      } else {
        MU& out = ws->G(k, j);
        for (int i : s.reach) out.row(i).setZero();
        s.a_reach_pattern.AddProduct(sq.a[k], ws->G(k - 1, j), &out);
      }
    }
  }
}

// Dense condensing of the Hessian (or its factor) and the constraint rows into *qp (the
// QP without slacks); independent of x0.
template <class Problem>
void Condense(const RtiDimensions& dims, const ProblemStructure<Problem>& s,
              const StageQp<Problem>& sq, RtiWorkspace<Problem>* ws, qp::DenseQp* qp) {
  constexpr int kNu = Problem::kNu;
  const StageProducts<Problem> ops(s, sq, dims.n);
  Sensitivities(dims, s, sq, ops, ws);
  if (s.riccati) {
    riccati::FactorBlocks(dims, s, *ws, qp);
  } else {
    column_sweep::Hessian(dims, sq, ops, *ws, qp);
  }
  for (int h = 0; h < dims.nch; ++h) {
    const BoundRow& row = dims.hard_rows[h];
    for (int j = 0; j < row.stage; ++j) {
      qp->A.template block<1, kNu>(h, dims.UPos(j)) = ws->G(row.stage - 1, j).row(row.index);
    }
  }
}

// The x0-dependent part of the QP: the free response e_k of the linearised dynamics (no
// input change, x0 embedded), the condensed gradient by a backward sweep, the input bounds
// and the state-bound rows' bounds.
template <class Problem>
void GradientAndBounds(const RtiDimensions& dims, const StageQp<Problem>& sq,
                       const StageProducts<Problem>& ops, const StageData<Problem>& data,
                       const Iterate<Problem>& it, const Vec<Problem::kNx>& x0,
                       RtiWorkspace<Problem>* ws, qp::DenseQp* qp) {
  constexpr int kNu = Problem::kNu;
  using X = Vec<Problem::kNx>;
  using U = Vec<kNu>;
  const int n = dims.n;
  std::vector<X>& e = ws->e;
  e[0] = x0 - it.x[0];
  for (int k = 0; k < n; ++k) {
    ops.MultiplyA(k, e[k], &e[k + 1]);
    e[k + 1] += sq.d[k];
  }
  X p = sq.q_vec[n];
  ops.AddQ(n, e[n], &p);
  for (int k = n - 1; k >= 0; --k) {
    U gk = sq.r_vec[k];
    ops.AddS(k, e[k], &gk);
    ops.AddBTransposed(k, p, &gk);
    qp->g.template segment<kNu>(dims.UPos(k)) = gk;
    X pk = sq.q_vec[k];
    ops.AddQ(k, e[k], &pk);
    ops.AddATransposed(k, p, &pk);
    p = pk;
  }
  for (int k = 0; k < n; ++k) {
    qp->lb.template segment<kNu>(dims.UPos(k)) = data.lbu[k] - it.u[k];
    qp->ub.template segment<kNu>(dims.UPos(k)) = data.ubu[k] - it.u[k];
  }
  for (int h = 0; h < dims.nch; ++h) {
    const BoundRow& row = dims.hard_rows[h];
    const double base = it.x[row.stage][row.index] + e[row.stage][row.index];
    qp->lbA[h] = data.lbx[row.stage][row.index] - base;
    qp->ubA[h] = data.ubx[row.stage][row.index] - base;
  }
}

// Expansion of the QP's input increments z: dx_0 = e_0, du_k from z,
// dx_{k+1} = A dx_k + B du_k + d_k. Returns whether every dx_k is finite.
template <class Problem>
bool Expand(const RtiDimensions& dims, const StageQp<Problem>& sq,
            const StageProducts<Problem>& ops, const RtiWorkspace<Problem>& ws,
            const Eigen::VectorXd& z, Iterate<Problem>* it) {
  constexpr int kNu = Problem::kNu;
  const int n = dims.n;
  it->dx[0] = ws.e[0];
  for (int k = 0; k < n; ++k) {
    it->du[k] = z.template segment<kNu>(dims.UPos(k));
    ops.MultiplyA(k, it->dx[k], &it->dx[k + 1]);
    ops.AddB(k, it->du[k], &it->dx[k + 1]);
    it->dx[k + 1] += sq.d[k];
  }
  bool finite = true;
  for (int k = 0; k <= n; ++k) finite = finite && it->dx[k].allFinite();
  return finite;
}

}  // namespace fnmpc::rti::condensing
