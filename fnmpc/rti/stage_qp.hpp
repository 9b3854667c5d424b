// SPDX-License-Identifier: BSD-3-Clause
// The OCP's QP at the current iterate, stage by stage (acados' ocp_qp_in): dynamics
// Jacobians A_k, B_k and defects d_k, Gauss-Newton blocks Q_k, S_k, R_k, q_k, r_k.
#pragma once

#include <array>
#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/rti/sparsity.hpp"

namespace fnmpc::rti {

template <class Problem>
struct StageQp {
  static constexpr int kNx = Problem::kNx, kNu = Problem::kNu;
  using X = Vec<kNx>;
  using U = Vec<kNu>;
  using MX = Mat<kNx, kNx>;
  using MU = Mat<kNx, kNu>;

  explicit StageQp(int horizon)
      : a(horizon, MX::Zero()),
        b(horizon, MU::Zero()),
        d(horizon, X::Zero()),
        q_mat(horizon + 1, MX::Zero()),
        s_mat(horizon, Mat<kNu, kNx>::Zero()),
        r_mat(horizon, Mat<kNu, kNu>::Zero()),
        q_vec(horizon + 1, X::Zero()),
        r_vec(horizon, U::Zero()) {}

  // Gauss-Newton blocks of node k from the residual Jacobians, over the rows with a nonzero
  // weight (rows) and the structural nonzeros of each: Q_k = Jx' W Jx, S_k = Ju' W Jx,
  // R_k = Ju' W Ju, q_k = Jx' W r, r_k = Ju' W r (the entries of q_pattern outside the rows'
  // products are never written and stay zero; R_k and r_k only with ju).
  template <class Jx, class Ju, class Wv, class Rv>
  void GaussNewtonBlocks(const Jx& jx, const Ju* ju, const Wv& w, const Rv& wr,
                         const std::vector<int>& rows, const std::vector<std::vector<int>>& x_cols,
                         const std::vector<std::vector<int>>& u_cols,
                         const SparsityPattern& q_pattern, const SparsityPattern& s_pattern,
                         int k) {
    for (const auto& e : q_pattern.entries()) q_mat[k](e.row, e.col) = 0.0;
    q_vec[k].setZero();
    if (ju != nullptr) {
      for (const auto& e : s_pattern.entries()) s_mat[k](e.row, e.col) = 0.0;
      r_mat[k].setZero();
      r_vec[k].setZero();
    }
    for (int r : rows) {
      // Every structural entry reaches q_k and r_k, so that a NaN residual does; the products
      // run over the entries that are nonzero at this iterate only (a zero entry adds exact
      // zeros: an inactive one-sided penalty row, such as a collision row, adds nothing).
      int nx = 0, nu = 0;
      std::array<int, kNx> xc;
      std::array<double, kNx> xv;
      std::array<int, kNu> uc;
      // Zeroed for GCC 12 on aarch64 (-Wmaybe-uninitialized): entries past nu are never read.
      std::array<double, kNu> uv{};
      for (int a : x_cols[r]) {
        const double ya = jx(r, a);
        q_vec[k][a] += ya * wr[r];
        if (ya != 0.0) {
          xc[nx] = a;
          xv[nx++] = ya;
        }
      }
      if (ju != nullptr) {
        for (int i : u_cols[r]) {
          const double yi = (*ju)(r, i);
          r_vec[k][i] += yi * wr[r];
          if (yi != 0.0) {
            uc[nu] = i;
            uv[nu++] = yi;
          }
        }
      }
      for (int p = 0; p < nx; ++p) {
        const double wya = w[r] * xv[p];
        for (int q = 0; q < nx; ++q) q_mat[k](xc[p], xc[q]) += wya * xv[q];
        for (int i = 0; i < nu; ++i) s_mat[k](uc[i], xc[p]) += uv[i] * wya;
      }
      for (int i = 0; i < nu; ++i) {
        const double wyi = w[r] * uv[i];
        for (int j = 0; j < nu; ++j) r_mat[k](uc[i], uc[j]) += wyi * uv[j];
      }
    }
  }

  /// Entries outside new cost patterns must read as zero in the dense Q_k and S_k.
  void ClearCost() {
    for (auto& m : q_mat) m.setZero();
    for (auto& m : s_mat) m.setZero();
  }

  std::vector<MX> a;      ///< A_k = d x_{k+1} / d x_k, k = 0..N-1
  std::vector<MU> b;      ///< B_k = d x_{k+1} / d u_k
  std::vector<X> d;       ///< defects d_k = F(x_k, u_k) - x_{k+1}
  std::vector<MX> q_mat;  ///< Q_k, k = 0..N (N: terminal)
  std::vector<Mat<kNu, kNx>> s_mat;
  std::vector<Mat<kNu, kNu>> r_mat;
  std::vector<X> q_vec;  ///< q_k, k = 0..N
  std::vector<U> r_vec;
};

}  // namespace fnmpc::rti
