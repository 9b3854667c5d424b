// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/model/quadrotor_model.hpp"

namespace fnmpc::model {

/// Per-neighbour block of the follower state (shared with NeighbourEkf), 8 entries:
/// [dx (3) = p_j - p_self in {m} axes, v_j (3) neighbour velocity in {m}, psi_j, wz_j].
struct NeighbourIndex {
  static constexpr int kSize = 8;
  static constexpr int kRelPos = 0, kVel = 3, kYaw = 6, kYawRate = 7;
};

/// Follower of the reference work, Eqs. (6)-(11), with `Neighbours` neighbours under a
/// constant-velocity assumption (problems F2, F6 of the benchmark spec). No absolute
/// position: the follower senses only relative positions.
///
/// State (kNx = 6 + 8 * Neighbours): [v (3), phi, theta, psi, then per neighbour j the
/// NeighbourIndex block]. Input as QuadrotorModel; online data psi_ref.
///   v', angles' as QuadrotorModel;  dx_j' = v_j - v;  v_j' = 0;  psi_j' = wz_j;  wz_j' = 0.
template <int Neighbours>
struct FollowerModel {
  static_assert(Neighbours >= 1, "a follower needs at least one neighbour");
  static constexpr int kNeighbours = Neighbours;
  static constexpr int kNx = 6 + NeighbourIndex::kSize * Neighbours;
  static constexpr int kNu = 3;
  static constexpr int kVel = 0, kPhi = 3, kTheta = 4, kPsi = 5;
  /// Offset of neighbour j's block in the state.
  static constexpr int Neighbour(int j) { return 6 + NeighbourIndex::kSize * j; }

  template <class S>
  static Eigen::Matrix<S, kNx, 1> Flow(const Eigen::Matrix<S, kNx, 1>& x,
                                       const Eigen::Matrix<S, kNu, 1>& u, double psi_ref,
                                       const AttitudeModelParams& m) {
    Eigen::Matrix<S, kNx, 1> f = Eigen::Matrix<S, kNx, 1>::Zero();
    f.template segment<3>(kVel) = BodyZ<S>(x[kPhi], x[kTheta], x[kPsi]) * (u[0] / m.mass);
    f[kVel + 2] -= S(kGravity);
    f[kPhi] = (m.gain[0] * u[1] - x[kPhi]) / m.time_constant[0];
    f[kTheta] = (m.gain[1] * u[2] - x[kTheta]) / m.time_constant[1];
    f[kPsi] = (m.gain[2] * psi_ref - x[kPsi]) / m.time_constant[2];
    for (int j = 0; j < Neighbours; ++j) {
      const int o = Neighbour(j);
      f.template segment<3>(o + NeighbourIndex::kRelPos) =
          x.template segment<3>(o + NeighbourIndex::kVel) - x.template segment<3>(kVel);
      f[o + NeighbourIndex::kYaw] = x[o + NeighbourIndex::kYawRate];
    }
    return f;
  }

  using Jacobian = OwnDynamicsJacobian;
  /// Flow and structured Jacobian (the neighbour blocks of f_x are constant).
  static void FlowAndJacobian(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                              const AttitudeModelParams& m, Vec<kNx>* f, Jacobian* jac) {
    *jac = OwnDynamicsJacobian::At(x[kPhi], x[kTheta], x[kPsi], u, psi_ref, m);
    f->template segment<3>(kVel) = jac->vdot;
    f->template segment<3>(kPhi) = jac->angle_dot;
    for (int j = 0; j < Neighbours; ++j) {
      const int o = Neighbour(j);
      f->template segment<3>(o) =
          x.template segment<3>(o + NeighbourIndex::kVel) - x.template segment<3>(kVel);
      f->template segment<3>(o + NeighbourIndex::kVel).setZero();
      (*f)[o + NeighbourIndex::kYaw] = x[o + NeighbourIndex::kYawRate];
      (*f)[o + NeighbourIndex::kYawRate] = 0.0;
    }
  }
  /// out = f_x * S exploiting the sparsity of f_x.
  template <class In, class Out>
  static void MultiplyFx(const Jacobian& jac, const In& s, Out* out) {
    out->template middleRows<3>(kVel).noalias() = jac.dv_dangles * s.template middleRows<3>(kPhi);
    out->template middleRows<3>(kPhi) =
        jac.dangle_dangle.asDiagonal() * s.template middleRows<3>(kPhi);
    for (int j = 0; j < Neighbours; ++j) {
      const int o = Neighbour(j);
      out->template middleRows<3>(o) =
          s.template middleRows<3>(o + NeighbourIndex::kVel) - s.template middleRows<3>(kVel);
      out->template middleRows<3>(o + NeighbourIndex::kVel).setZero();
      out->row(o + NeighbourIndex::kYaw) = s.row(o + NeighbourIndex::kYawRate);
      out->row(o + NeighbourIndex::kYawRate).setZero();
    }
  }
  /// out += f_u.
  template <class Out>
  static void AddFu(const Jacobian& jac, Out* out) {
    out->template block<3, 1>(kVel, 0) += jac.dv_dthrust;
    (*out)(kPhi, 1) += jac.dangle_dref[0];
    (*out)(kTheta, 2) += jac.dangle_dref[1];
  }

  /// RK4 over one interval (as Rk4 in rk4.hpp) with A = dx(dt)/dx(0), B = dx(dt)/du. The
  /// own rows come from OwnInterval; a neighbour block is linear: dx_j(dt) = dx_j + dt v_j
  /// minus the own displacement, so its rows are constant up to minus the displacement's
  /// sensitivity. Writes only the structural nonzeros of A and B: the other entries must
  /// be zero on entry (they are the same for every call).
  static Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                             const AttitudeModelParams& m, double dt, int steps, Mat<kNx, kNx>* A,
                             Mat<kNx, kNu>* B) {
    using N = NeighbourIndex;
    const OwnInterval r = OwnInterval::Integrate(
        x.template segment<3>(kVel), x.template segment<3>(kPhi), u, psi_ref, m, dt, steps);
    Vec<kNx> next;
    next.template segment<3>(kVel) = r.velocity;
    next.template segment<3>(kPhi) = r.angles;
    for (int j = 0; j < Neighbours; ++j) {
      const int o = Neighbour(j);
      next.template segment<3>(o + N::kRelPos) = x.template segment<3>(o + N::kRelPos) +
                                                 dt * x.template segment<3>(o + N::kVel) -
                                                 r.displacement;
      next.template segment<3>(o + N::kVel) = x.template segment<3>(o + N::kVel);
      next[o + N::kYaw] = x[o + N::kYaw] + dt * x[o + N::kYawRate];
      next[o + N::kYawRate] = x[o + N::kYawRate];
    }
    if (A == nullptr || B == nullptr) return next;
    for (int i = 0; i < 3; ++i) {
      (*A)(kVel + i, kVel + i) = 1.0;
      (*A)(kPhi + i, kPhi + i) = r.dangle_dangle0[i];
    }
    A->template block<3, 3>(kVel, kPhi) = r.dv.template leftCols<3>();
    B->template block<3, 3>(kVel, 0) = r.dv.template rightCols<3>();
    (*B)(kPhi, 1) = r.dangle_dref[0];
    (*B)(kTheta, 2) = r.dangle_dref[1];
    for (int j = 0; j < Neighbours; ++j) {
      const int o = Neighbour(j);
      for (int i = 0; i < 3; ++i) {
        (*A)(o + i, o + i) = 1.0;
        (*A)(o + i, o + N::kVel + i) = dt;
        (*A)(o + i, kVel + i) = -dt;
        (*A)(o + N::kVel + i, o + N::kVel + i) = 1.0;
      }
      A->template block<3, 3>(o, kPhi) = -r.dp.template leftCols<3>();
      B->template block<3, 3>(o, 0) = -r.dp.template rightCols<3>();
      (*A)(o + N::kYaw, o + N::kYaw) = 1.0;
      (*A)(o + N::kYaw, o + N::kYawRate) = dt;
      (*A)(o + N::kYawRate, o + N::kYawRate) = 1.0;
    }
    return next;
  }

  static void FlowJacobian(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                           const AttitudeModelParams& m, Vec<kNx>* f, Mat<kNx, kNx>* fx,
                           Mat<kNx, kNu>* fu) {
    const auto jac = OwnDynamicsJacobian::At(x[kPhi], x[kTheta], x[kPsi], u, psi_ref, m);
    f->setZero();
    fx->setZero();
    fu->setZero();
    f->template segment<3>(kVel) = jac.vdot;
    f->template segment<3>(kPhi) = jac.angle_dot;
    fx->template block<3, 3>(kVel, kPhi) = jac.dv_dangles;
    fx->template block<3, 3>(kPhi, kPhi).diagonal() = jac.dangle_dangle;
    fu->template block<3, 1>(kVel, 0) = jac.dv_dthrust;
    (*fu)(kPhi, 1) = jac.dangle_dref[0];
    (*fu)(kTheta, 2) = jac.dangle_dref[1];
    for (int j = 0; j < Neighbours; ++j) {
      const int o = Neighbour(j);
      f->template segment<3>(o) =
          x.template segment<3>(o + NeighbourIndex::kVel) - x.template segment<3>(kVel);
      (*f)[o + NeighbourIndex::kYaw] = x[o + NeighbourIndex::kYawRate];
      fx->template block<3, 3>(o, o + NeighbourIndex::kVel).setIdentity();
      fx->template block<3, 3>(o, kVel) = -Mat3::Identity();
      (*fx)(o + NeighbourIndex::kYaw, o + NeighbourIndex::kYawRate) = 1.0;
    }
  }
};

}  // namespace fnmpc::model
