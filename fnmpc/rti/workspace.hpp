// SPDX-License-Identifier: BSD-3-Clause
// Scratch memory of an RtiSolver, allocated once (construction, or SetWeights when the
// compact Riccati path is chosen): nothing in Prepare, Feedback or Step allocates.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "fnmpc/core/assert.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/rti/structure.hpp"

namespace fnmpc::rti {

template <class Problem>
struct RtiWorkspace {
  static constexpr int kNx = Problem::kNx, kNu = Problem::kNu, kNy = Problem::kNy,
                       kNyN = Problem::kNyN;
  static constexpr int kMaxCompact = ProblemStructure<Problem>::kMaxCompact;
  using X = Vec<kNx>;
  using U = Vec<kNu>;
  using MX = Mat<kNx, kNx>;
  using MU = Mat<kNx, kNu>;
  // Matrices of the compact Riccati path, of fixed capacity (no heap).
  using MC = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxCompact, kMaxCompact>;
  using VC = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxCompact, 1>;
  // (a single-input problem's UC is one row: Eigen requires row-major storage for it)
  using UC = Eigen::Matrix<double, kNu, Eigen::Dynamic,
                           kNu == 1 ? Eigen::RowMajor : Eigen::ColMajor, kNu, kMaxCompact>;
  using BC = Eigen::Matrix<double, Eigen::Dynamic, kNu, 0, kMaxCompact, kNu>;

  explicit RtiWorkspace(int horizon)
      : n(horizon),
        e(horizon + 1, X::Zero()),
        g(static_cast<std::size_t>(horizon) * (horizon + 1) / 2, MU::Zero()),
        k_gain(horizon, Mat<kNu, kNx>::Zero()),
        l_diag(horizon, Mat<kNu, kNu>::Identity()),
        kt_vec(horizon, U::Zero()) {
    if constexpr (ProblemStructure<Problem>::kRiccatiCondensing) p_mat.assign(n + 1, MX::Zero());
    yx->setZero();
    yu->setZero();
    ynx->setZero();
  }

  /// The compact Riccati matrices for nr cost-relevant states.
  void AllocateCompact(int nr) {
    ac = MC::Zero(nr, nr);
    pc_mat.assign(n + 1, MC::Zero(nr, nr));
  }

  // Block G(k, j) = d x_{k+1} / d u_j (j <= k) of the condensed sensitivities.
  MU& G(int k, int j) {
    FNMPC_ASSERT(j >= 0 && j <= k && k < n);
    return g[static_cast<std::size_t>(k) * (k + 1) / 2 + j];
  }
  const MU& G(int k, int j) const {
    FNMPC_ASSERT(j >= 0 && j <= k && k < n);
    return g[static_cast<std::size_t>(k) * (k + 1) / 2 + j];
  }

  int n;
  std::vector<X> e;   ///< free response of the linearised dynamics from x0
  std::vector<MU> g;  ///< G(k, j), packed
  // Residual Jacobian buffers (on the heap: kNy x kNx is large for F6). The problem writes
  // only the structural nonzeros; the rest stays zero.
  std::unique_ptr<Mat<kNy, kNx>> yx = std::make_unique<Mat<kNy, kNx>>();
  std::unique_ptr<Mat<kNy, kNu>> yu = std::make_unique<Mat<kNy, kNu>>();
  std::unique_ptr<Mat<kNyN, kNx>> ynx = std::make_unique<Mat<kNyN, kNx>>();
  // Riccati data: gains Kt_k, factors L_k, kt_k of the last unconstrained step, P_k
  // (k = 0..N; small-nx path) or its compact form with A_k on the relevant states; whether
  // every Rbar_k was positive definite.
  std::vector<Mat<kNu, kNx>> k_gain;
  std::vector<Mat<kNu, kNu>> l_diag;
  std::vector<U> kt_vec;
  std::vector<MX> p_mat;
  std::vector<MC> pc_mat;
  MC ac;
  bool riccati_ok = false;
};

}  // namespace fnmpc::rti
