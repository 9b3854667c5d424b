// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/eigen_abi.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/model/vehicle_params.hpp"

namespace fnmpc::model {

/// The constants of the NMPC prediction model: mass and the identified first-order
/// closed-loop attitude dynamics (roll, pitch, yaw) of the reference work, Eqs. (2)-(4).
struct AttitudeModelParams {
  double mass = 1.37;                                     ///< [kg]
  Eigen::Vector3d time_constant{0.1203, 0.1303, 0.0651};  ///< tau_i [s]
  Eigen::Vector3d gain{1.01, 1.02, 0.99};                 ///< k_i [-]

  static AttitudeModelParams From(const VehicleParams& v) {
    return {v.mass, v.attitude_time_constant, v.attitude_gain};
  }
};

/// Jacobian blocks shared by every model with the quadrotor's own velocity/attitude:
/// rows of v' and angle' with respect to (angles, inputs).
struct OwnDynamicsJacobian {
  Mat3 dv_dangles;     ///< d v' / d(phi, theta, psi)
  Vec3 dv_dthrust;     ///< d v' / d T
  Vec3 dangle_dangle;  ///< diagonal: -1/tau_i
  Vec3 dangle_dref;    ///< diagonal: k_i/tau_i (phi_ref, theta_ref; yaw's is online data)
  Vec3 vdot;           ///< v'
  Vec3 angle_dot;      ///< angle'
  static OwnDynamicsJacobian At(double phi, double theta, double psi, const Vec3& u, double psi_ref,
                                const AttitudeModelParams& m);
};

/// One RK4 shooting interval of the quadrotor's own dynamics (displacement, velocity,
/// attitude) with the exact sensitivities of the discrete map, kept in the structured form
/// the dynamics imply: v' does not depend on p or v and the three angles are decoupled
/// and linear, so d p/d p0 = I, d p/d v0 = dt I, d v/d v0 = I, the angle rows are
/// diagonal, and only d(p, v)/d(angles0, u) (3 x 6 each) and two scalars per angle are
/// propagated through the RK4 stages. This is the same discrete map and derivative as
/// the generic Rk4 (tests compare them to 1e-12) for a fraction of its arithmetic.
struct OwnInterval {
  /// Columns of dp and dv: (phi0, theta0, psi0, T, phi_ref, theta_ref).
  static constexpr int kCols = 6;
  Vec3 displacement;            ///< p(dt) - p(0) [m]
  Vec3 velocity;                ///< v(dt) [m/s]
  Vec3 angles;                  ///< (phi, theta, psi)(dt) [rad]
  Mat<3, kCols> dp;             ///< d displacement / d(angles0, u)
  Mat<3, kCols> dv;             ///< d v(dt) / d(angles0, u)
  Vec3 dangle_dangle0;          ///< d angle_i(dt) / d angle_i(0)
  Eigen::Vector2d dangle_dref;  ///< d (phi, theta)(dt) / d (phi_ref, theta_ref)

  /// Integrates from (v0, angles0) under input u over dt in `steps` RK4 steps.
  static OwnInterval Integrate(const Vec3& v0, const Vec3& angles0, const Vec3& u, double psi_ref,
                               const AttitudeModelParams& m, double dt, int steps);
};

/// Quadrotor with first-order closed-loop attitude (problem L of the benchmark spec).
///
/// State x (kNx = 9): [p (3) position, v (3) velocity, phi, theta, psi] in the inertial
/// frame (ENU, z up). Input u (kNu = 3): [T collective thrust [N], phi_ref, theta_ref].
/// Online data: psi_ref [rad].
///   p' = v,  v' = R(phi,theta,psi) e3 T/m - g e3,  angle_i' = (k_i ref_i - angle_i)/tau_i.
struct QuadrotorModel {
  static constexpr int kNx = 9;
  static constexpr int kNu = 3;
  enum Index : int { kPos = 0, kVel = 3, kPhi = 6, kTheta = 7, kPsi = 8 };
  enum InputIndex : int { kThrust = 0, kPhiRef = 1, kThetaRef = 2 };

  /// Time derivative, templated on the scalar for automatic differentiation in tests.
  template <class S>
  static Eigen::Matrix<S, kNx, 1> Flow(const Eigen::Matrix<S, kNx, 1>& x,
                                       const Eigen::Matrix<S, kNu, 1>& u, double psi_ref,
                                       const AttitudeModelParams& m) {
    Eigen::Matrix<S, kNx, 1> f;
    f.template segment<3>(kPos) = x.template segment<3>(kVel);
    f.template segment<3>(kVel) = BodyZ<S>(x[kPhi], x[kTheta], x[kPsi]) * (u[kThrust] / m.mass);
    f[kVel + 2] -= S(kGravity);
    f[kPhi] = (m.gain[0] * u[kPhiRef] - x[kPhi]) / m.time_constant[0];
    f[kTheta] = (m.gain[1] * u[kThetaRef] - x[kTheta]) / m.time_constant[1];
    f[kPsi] = (m.gain[2] * psi_ref - x[kPsi]) / m.time_constant[2];
    return f;
  }

  /// Flow and its Jacobians f_x (kNx x kNx) and f_u (kNx x kNu), derived by hand.
  static void FlowJacobian(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                           const AttitudeModelParams& m, Vec<kNx>* f, Mat<kNx, kNx>* fx,
                           Mat<kNx, kNu>* fu);

  /// Structured Jacobian: only its nonzero blocks (see OwnDynamicsJacobian).
  using Jacobian = OwnDynamicsJacobian;
  /// Flow and structured Jacobian at (x, u): what RK4's sensitivity propagation needs.
  static void FlowAndJacobian(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                              const AttitudeModelParams& m, Vec<kNx>* f, Jacobian* jac);
  /// out = f_x * S for any S with kNx rows, exploiting the sparsity of f_x
  /// (O(kNx * cols) instead of O(kNx^2 * cols)).
  template <class In, class Out>
  static void MultiplyFx(const Jacobian& jac, const In& s, Out* out);
  /// out += f_u, with out a kNx x kNu block.
  template <class Out>
  static void AddFu(const Jacobian& jac, Out* out);

  /// RK4 over one interval (as Rk4 in rk4.hpp) with the sensitivities A = dx(dt)/dx(0),
  /// B = dx(dt)/du from OwnInterval. Writes only the structural nonzeros of A and B: the
  /// other entries must be zero on entry (they are the same for every call).
  static Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                             const AttitudeModelParams& m, double dt, int steps, Mat<kNx, kNx>* A,
                             Mat<kNx, kNu>* B);

  /// Products with a transition matrix A of Discretise by its block structure
  ///   [[I, dt I, Ap], [0, I, Av], [0, 0, diag(a)]]   (blocks p, v, angles; dt = A(0, 3)),
  /// which condensing does O(N^2) times: 90 multiply-adds for a 9 x 3 operand where the
  /// dense product takes 243. out = A in (out must not alias in).
  /// (a: the 9 x 9 transition matrix or a block expression of one.)
  template <class MA, class In, class Out>
  static void MultiplyTransition(const MA& a, const In& in, Out* out);
  /// out = in A (out must not alias in).
  template <class In, class MA, class Out>
  static void MultiplyTransitionRight(const In& in, const MA& a, Out* out);
  /// out = A' in (out must not alias in).
  template <class MA, class In, class Out>
  static void MultiplyTransitionTransposed(const MA& a, const In& in, Out* out);
};

template <class MA, class In, class Out>
void QuadrotorModel::MultiplyTransitionTransposed(const MA& a, const In& in, Out* out) {
  const double dt = a(kPos, kVel);
  const auto pos = in.template middleRows<3>(kPos);
  const auto vel = in.template middleRows<3>(kVel);
  out->template middleRows<3>(kPhi) =
      a.diagonal().template tail<3>().asDiagonal() * in.template middleRows<3>(kPhi);
  out->template middleRows<3>(kPhi).noalias() +=
      a.template block<3, 3>(kPos, kPhi).transpose() * pos;
  out->template middleRows<3>(kPhi).noalias() +=
      a.template block<3, 3>(kVel, kPhi).transpose() * vel;
  out->template middleRows<3>(kVel) = vel + dt * pos;
  out->template middleRows<3>(kPos) = pos;
}

template <class MA, class In, class Out>
void QuadrotorModel::MultiplyTransition(const MA& a, const In& in, Out* out) {
  const double dt = a(kPos, kVel);
  const auto ang = in.template middleRows<3>(kPhi);
  out->template middleRows<3>(kPos) =
      in.template middleRows<3>(kPos) + dt * in.template middleRows<3>(kVel);
  out->template middleRows<3>(kPos).noalias() += a.template block<3, 3>(kPos, kPhi) * ang;
  out->template middleRows<3>(kVel) = in.template middleRows<3>(kVel);
  out->template middleRows<3>(kVel).noalias() += a.template block<3, 3>(kVel, kPhi) * ang;
  out->template middleRows<3>(kPhi) = a.diagonal().template tail<3>().asDiagonal() * ang;
}

template <class In, class MA, class Out>
void QuadrotorModel::MultiplyTransitionRight(const In& in, const MA& a, Out* out) {
  const double dt = a(kPos, kVel);
  const auto pos = in.template middleCols<3>(kPos);
  const auto vel = in.template middleCols<3>(kVel);
  out->template middleCols<3>(kPhi) =
      in.template middleCols<3>(kPhi) * a.diagonal().template tail<3>().asDiagonal();
  out->template middleCols<3>(kPhi).noalias() += pos * a.template block<3, 3>(kPos, kPhi);
  out->template middleCols<3>(kPhi).noalias() += vel * a.template block<3, 3>(kVel, kPhi);
  out->template middleCols<3>(kVel) = vel + dt * pos;
  out->template middleCols<3>(kPos) = pos;
}

template <class In, class Out>
void QuadrotorModel::MultiplyFx(const Jacobian& jac, const In& s, Out* out) {
  out->template middleRows<3>(kPos) = s.template middleRows<3>(kVel);
  out->template middleRows<3>(kVel).noalias() = jac.dv_dangles * s.template middleRows<3>(kPhi);
  out->template middleRows<3>(kPhi) =
      jac.dangle_dangle.asDiagonal() * s.template middleRows<3>(kPhi);
}

template <class Out>
void QuadrotorModel::AddFu(const Jacobian& jac, Out* out) {
  out->template block<3, 1>(kVel, kThrust) += jac.dv_dthrust;
  (*out)(kPhi, kPhiRef) += jac.dangle_dref[0];
  (*out)(kTheta, kThetaRef) += jac.dangle_dref[1];
}

}  // namespace fnmpc::model
