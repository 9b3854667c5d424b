// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"
#include "fnmpc/model/rk4.hpp"

namespace fnmpc::model {

/// Any discretisable model extended by its previous input: x = [base state, u_prev] with
/// u_prev_{k+1} = u_k, an exact discrete memory over one interval. Costs on the change of the
/// input between stages (and from the command last applied, which x_0 carries) then become
/// stage-wise least-squares residuals u_k - u_prev_k. A = diag(A_base, 0), B = [B_base; I].
template <class Base>
struct InputMemoryModel {
  static constexpr int kNxBase = Base::kNx, kNu = Base::kNu, kNx = kNxBase + kNu;
  static constexpr int kPrevInput = kNxBase;  ///< offset of u_prev in the state

  /// The base model's interval map (structured when it has one) and the memory. Writes the
  /// entries the base model writes, plus the identity of B's memory rows; the others stay as
  /// the caller left them (zero), so the solver's sparsity detection sees the true pattern.
  static Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                             const AttitudeModelParams& m, double dt, int steps, Mat<kNx, kNx>* A,
                             Mat<kNx, kNu>* B) {
    Vec<kNx> next;
    if (A == nullptr || B == nullptr) {
      next.template head<kNxBase>() = model::Discretise<Base>(
          x.template head<kNxBase>(), u, psi_ref, m, dt, steps, nullptr, nullptr);
    } else {
      Mat<kNxBase, kNxBase> a = A->template topLeftCorner<kNxBase, kNxBase>();
      Mat<kNxBase, kNu> b = B->template topRows<kNxBase>();
      next.template head<kNxBase>() =
          model::Discretise<Base>(x.template head<kNxBase>(), u, psi_ref, m, dt, steps, &a, &b);
      A->template topLeftCorner<kNxBase, kNxBase>() = a;
      B->template topRows<kNxBase>() = b;
      B->template bottomRows<kNu>().diagonal().setOnes();
    }
    next.template tail<kNu>() = u;
    return next;
  }

  // Products with A = diag(A_base, 0) by the base model's structured products (Base must
  // have them: QuadrotorModel; see rti::detail::HasStructuredTransition).
  template <class MA, class In, class Out>
  static void MultiplyTransition(const MA& a, const In& in, Out* out) {
    auto top = out->template topRows<kNxBase>();
    Base::MultiplyTransition(a.template topLeftCorner<kNxBase, kNxBase>(),
                             in.template topRows<kNxBase>(), &top);
    out->template bottomRows<kNu>().setZero();
  }
  template <class In, class MA, class Out>
  static void MultiplyTransitionRight(const In& in, const MA& a, Out* out) {
    auto left = out->template leftCols<kNxBase>();
    Base::MultiplyTransitionRight(in.template leftCols<kNxBase>(),
                                  a.template topLeftCorner<kNxBase, kNxBase>(), &left);
    out->template rightCols<kNu>().setZero();
  }
  template <class MA, class In, class Out>
  static void MultiplyTransitionTransposed(const MA& a, const In& in, Out* out) {
    auto top = out->template topRows<kNxBase>();
    Base::MultiplyTransitionTransposed(a.template topLeftCorner<kNxBase, kNxBase>(),
                                       in.template topRows<kNxBase>(), &top);
    out->template bottomRows<kNu>().setZero();
  }
};

}  // namespace fnmpc::model
