// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"
#include "fnmpc/model/wake_force.hpp"
#include "fnmpc/ocp/problem_extensions.hpp"

/// The neighbours' predicted wakes in a follower's prediction (compensation level `wake`): an
/// extension of a least-squares problem (fnmpc/ocp/problems.hpp contract), like those of
/// fnmpc/ocp/problem_extensions.hpp.
namespace fnmpc::ocp {

/// A model whose transition matrix is the wrapped model's plus the wake's couplings of the
/// position to the vertical position and velocity: A = A_M + E with E nonzero only in rows
/// Pos + 2 and Vel + 2, columns Pos..Pos + 2 (E(Pos + 2, Pos + 2) = A(Pos + 2, Pos + 2) - 1:
/// the wrapped model's displacement block is the identity). Keeps the wrapped model's
/// structured products (rti::detail::HasStructuredTransition) and adds E's few terms, so the
/// solver neither misses the coupling nor falls back to the generic products.
template <class M, int Pos, int Vel>
struct WakeCoupledModel : M {
  static constexpr int kNx = M::kNx;
  template <class MA>
  static double E(const MA& a, int row, int c) {
    return row == Pos + 2 && c == 2 ? a(row, Pos + c) - 1.0 : a(row, Pos + c);
  }
  /// out = A in.
  template <class MA, class In, class Out>
  static void MultiplyTransition(const MA& a, const In& in, Out* out) {
    M::MultiplyTransition(a, in, out);
    for (const int row : {Pos + 2, Vel + 2}) {
      for (int c = 0; c < 3; ++c) out->row(row) += E(a, row, c) * in.row(Pos + c);
    }
  }
  /// out = in A.
  template <class In, class MA, class Out>
  static void MultiplyTransitionRight(const In& in, const MA& a, Out* out) {
    M::MultiplyTransitionRight(in, a, out);
    for (const int row : {Pos + 2, Vel + 2}) {
      for (int c = 0; c < 3; ++c) out->col(Pos + c) += E(a, row, c) * in.col(row);
    }
  }
  /// out = A' in.
  template <class MA, class In, class Out>
  static void MultiplyTransitionTransposed(const MA& a, const In& in, Out* out) {
    M::MultiplyTransitionTransposed(a, in, out);
    for (const int row : {Pos + 2, Vel + 2}) {
      for (int c = 0; c < 3; ++c) out->row(Pos + c) += E(a, row, c) * in.row(row);
    }
  }
};

/// The wakes of up to `Slots` neighbours as an acceleration of the follower, a function of its
/// predicted position: with the follower's position block x_p (Pos; in the reduced follower the
/// displacement since the start of the horizon, {m}) and per slot o the neighbour's predicted
/// position c_o relative to the follower's position at the start (stage parameter, its
/// constant-velocity prediction at this stage) and its thrust T_o [N] (stage parameter; 0 =
/// unused slot), the follower feels
///   a_w(x_p) = e_z sum_o WakeForceModel::Acceleration(x_p - c_o, T_o)
/// (model::WakeForceModel: the neighbour's smooth round-jet wake, thrust loss and drag). It is
/// held over each interval at its value at the interval's start, as the observer's estimate in
/// WithAcceleration: the interval map is the wrapped one plus a_w dt^2 / 2 on the position and
/// a_w dt on the velocity, and A gains the rows (dt^2 / 2, dt) d a_w / d x_p. Residuals are the
/// wrapped problem's. With every thrust zero the map and A are the wrapped problem's, to the
/// bit. Parameters appended after the wrapped problem's: [c_o (3), T_o] per slot
/// (DynamicsExtension).
template <class P, int Slots, int Pos = 0, int Vel = 3>
struct WithWake : DynamicsExtension<P, 4 * Slots> {
  using Model = WakeCoupledModel<typename P::Model, Pos, Vel>;
  using Ext = DynamicsExtension<P, 4 * Slots>;
  using Ext::kNp;
  using Ext::kNu;
  using Ext::kNx;
  using typename Ext::Params;
  static constexpr int kSlots = Slots;
  static_assert(Pos + 3 <= kNx && Vel + 3 <= kNx, "position and velocity blocks in the state");
  model::WakeForceModel wake;

  explicit WithWake(const P& p = P{}, const model::WakeForceModel& w = model::WakeForceModel{})
      : Ext(p), wake(w) {}

  /// Offsets of slot o's neighbour position c_o [m] and thrust T_o [N] in the parameters.
  static constexpr int ParamSource(int o) { return P::kNp + 4 * o; }
  static constexpr int ParamThrust(int o) { return P::kNp + 4 * o + 3; }
  /// Writes an unused slot into p (no thrust: no wake).
  template <class Pv>
  static void SetUnused(int o, Pv* p) {
    p->template segment<3>(ParamSource(o)).setZero();
    (*p)[ParamThrust(o)] = 0.0;
  }

  /// Vertical wake acceleration [m/s^2] at the state x for the parameters p, and its gradient
  /// in the position block.
  double Acceleration(const Vec<kNx>& x, const Vec<kNp>& p, Vec3* grad) const {
    double a = 0.0;
    grad->setZero();
    const Vec3 pos = x.template segment<3>(Pos);
    for (int o = 0; o < Slots; ++o) {
      const double thrust = p[ParamThrust(o)];
      if (!(thrust > 0.0)) continue;
      Vec3 g;
      a += wake.Acceleration(pos - p.template segment<3>(ParamSource(o)), thrust, &g);
      *grad += g;
    }
    return a;
  }

  Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, const Params& p, double dt, int steps,
                      Mat<kNx, kNx>* A, Mat<kNx, kNu>* B) const {
    const typename P::Params pb = p.template head<P::kNp>();
    Vec<kNx> next = this->base.Discretise(x, u, pb, dt, steps, A, B);
    Vec3 grad;
    const double a = Acceleration(x, p, &grad);
    next[Pos + 2] += 0.5 * dt * dt * a;
    next[Vel + 2] += dt * a;
    if (A != nullptr && B != nullptr) {
      // The same entries on every call (the solver's sparsity detection; see the class).
      for (int c = 0; c < 3; ++c) {
        (*A)(Pos + 2, Pos + c) = (c == 2 ? 1.0 : 0.0) + 0.5 * dt * dt * grad[c];
        (*A)(Vel + 2, Pos + c) = dt * grad[c];
      }
    }
    return next;
  }
};

}  // namespace fnmpc::ocp
