// SPDX-License-Identifier: BSD-3-Clause
// Products with the stage matrices A_k, B_k, Q_k and S_k over their structural nonzeros
// (the neighbour blocks of the full follower models are mostly zero; for L, A_k has 30 of
// 81 entries), or by the model's own block structure, or densely for small nx.
#pragma once

#include "fnmpc/rti/stage_qp.hpp"
#include "fnmpc/rti/structure.hpp"

namespace fnmpc::rti {

/// A view of a StageQp with its ProblemStructure; built on the fly where needed.
template <class Problem>
class StageProducts {
 public:
  using S = ProblemStructure<Problem>;
  using Model = typename S::Model;

  StageProducts(const S& structure, const StageQp<Problem>& stage_qp, int horizon)
      : s_(structure), q_(stage_qp), n_(horizon) {}

  // out = A_k in.
  template <class In, class Out>
  void MultiplyA(int k, const In& in, Out* out) const {
    if constexpr (S::kStructuredA) {
      Model::MultiplyTransition(q_.a[k], in, out);
    } else {
      s_.a_pattern.Multiply(q_.a[k], in, out);
    }
  }
  // out = A_k' in.
  template <class In, class Out>
  void MultiplyATransposed(int k, const In& in, Out* out) const {
    if constexpr (S::kStructuredA) {
      Model::MultiplyTransitionTransposed(q_.a[k], in, out);
    } else {
      out->setZero();
      s_.a_pattern.AddTransposedProduct(q_.a[k], in, out);
    }
  }
  // out = in A_k.
  template <class In, class Out>
  void MultiplyARight(int k, const In& in, Out* out) const {
    if constexpr (S::kStructuredA) {
      Model::MultiplyTransitionRight(in, q_.a[k], out);
    } else {
      s_.a_pattern.MultiplyRight(in, q_.a[k], out);
    }
  }
  // out += A_k' in.
  template <class In, class Out>
  void AddATransposed(int k, const In& in, Out* out) const {
    if constexpr (S::kStructuredA) {
      typename Out::PlainObject t;
      Model::MultiplyTransitionTransposed(q_.a[k], in, &t);
      *out += t;
    } else {
      s_.a_pattern.AddTransposedProduct(q_.a[k], in, out);
    }
  }
  // out += B_k in.
  template <class In, class Out>
  void AddB(int k, const In& in, Out* out) const {
    if constexpr (S::kDenseStageProducts) {
      out->noalias() += q_.b[k] * in;
    } else {
      s_.b_pattern.AddProduct(q_.b[k], in, out);
    }
  }
  // out += B_k' in.
  template <class In, class Out>
  void AddBTransposed(int k, const In& in, Out* out) const {
    if constexpr (S::kDenseStageProducts) {
      out->noalias() += q_.b[k].transpose() * in;
    } else {
      s_.b_pattern.AddTransposedProduct(q_.b[k], in, out);
    }
  }
  // out += Q_k in; k = N is the terminal cost.
  template <class In, class Out>
  void AddQ(int k, const In& in, Out* out) const {
    if constexpr (S::kDenseStageProducts) {
      out->noalias() += q_.q_mat[k] * in;
    } else {
      (k == n_ ? s_.qn_pattern : s_.q_pattern).AddProduct(q_.q_mat[k], in, out);
    }
  }
  // out += S_k in.
  template <class In, class Out>
  void AddS(int k, const In& in, Out* out) const {
    if constexpr (S::kDenseStageProducts) {
      out->noalias() += q_.s_mat[k] * in;
    } else {
      s_.s_pattern.AddProduct(q_.s_mat[k], in, out);
    }
  }

 private:
  const S& s_;
  const StageQp<Problem>& q_;
  int n_;
};

}  // namespace fnmpc::rti
