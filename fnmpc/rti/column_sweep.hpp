// SPDX-License-Identifier: BSD-3-Clause
// Column-sweep condensing (more than 32 cost-relevant states): the condensed Hessian column
// by column, each by a backward sweep over the structural nonzeros of A_k, B_k, Q_k, S_k.
#pragma once

#include "fnmpc/qp/dense_qp.hpp"
#include "fnmpc/rti/dimensions.hpp"
#include "fnmpc/rti/stage_products.hpp"
#include "fnmpc/rti/workspace.hpp"

namespace fnmpc::rti::column_sweep {

// Hessian columns by backward sweeps, O(N^2 nnz nu). Needs the sensitivities G
// (condensing.hpp).
template <class Problem>
void Hessian(const RtiDimensions& dims, const StageQp<Problem>& sq,
             const StageProducts<Problem>& ops, const RtiWorkspace<Problem>& ws, qp::DenseQp* qp) {
  constexpr int kNx = Problem::kNx, kNu = Problem::kNu;
  using MU = Mat<kNx, kNu>;
  const int n = dims.n;
  MU p, pk;
  for (int j = 0; j < n; ++j) {
    p.setZero();
    ops.AddQ(n, ws.G(n - 1, j), &p);
    for (int k = n - 1; k > j; --k) {
      const MU& gkj = ws.G(k - 1, j);
      Mat<kNu, kNu> hkj = Mat<kNu, kNu>::Zero();
      ops.AddS(k, gkj, &hkj);
      ops.AddBTransposed(k, p, &hkj);
      qp->H.template block<kNu, kNu>(dims.UPos(k), dims.UPos(j)) = hkj;
      qp->H.template block<kNu, kNu>(dims.UPos(j), dims.UPos(k)) = hkj.transpose();
      pk.setZero();
      ops.AddQ(k, gkj, &pk);
      ops.AddATransposed(k, p, &pk);
      p = pk;
    }
    Mat<kNu, kNu> hjj = sq.r_mat[j];
    ops.AddBTransposed(j, p, &hjj);
    qp->H.template block<kNu, kNu>(dims.UPos(j), dims.UPos(j)) = 0.5 * (hjj + hjj.transpose());
  }
}

}  // namespace fnmpc::rti::column_sweep
