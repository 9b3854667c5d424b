// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/model/quadrotor_model.hpp"

namespace fnmpc::model {

OwnDynamicsJacobian OwnDynamicsJacobian::At(double phi, double theta, double psi, const Vec3& u,
                                            double psi_ref, const AttitudeModelParams& m) {
  OwnDynamicsJacobian j;
  const double t_over_m = u[0] / m.mass;
  const Vec3 z = BodyZ(phi, theta, psi);
  j.vdot = z * t_over_m - Vec3(0, 0, kGravity);
  j.dv_dangles = BodyZJacobian(phi, theta, psi) * t_over_m;
  j.dv_dthrust = z / m.mass;
  j.dangle_dangle = -m.time_constant.cwiseInverse();
  j.dangle_dref = m.gain.cwiseQuotient(m.time_constant);
  const Vec3 angles(phi, theta, psi);
  const Vec3 refs(u[1], u[2], psi_ref);
  j.angle_dot = (m.gain.cwiseProduct(refs) - angles).cwiseQuotient(m.time_constant);
  return j;
}

void QuadrotorModel::FlowJacobian(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                                  const AttitudeModelParams& m, Vec<kNx>* f, Mat<kNx, kNx>* fx,
                                  Mat<kNx, kNu>* fu) {
  const auto j = OwnDynamicsJacobian::At(x[kPhi], x[kTheta], x[kPsi], u, psi_ref, m);
  f->segment<3>(kPos) = x.segment<3>(kVel);
  f->segment<3>(kVel) = j.vdot;
  f->segment<3>(kPhi) = j.angle_dot;
  fx->setZero();
  fu->setZero();
  fx->block<3, 3>(kPos, kVel).setIdentity();
  fx->block<3, 3>(kVel, kPhi) = j.dv_dangles;
  fx->block<3, 3>(kPhi, kPhi).diagonal() = j.dangle_dangle;
  fu->block<3, 1>(kVel, kThrust) = j.dv_dthrust;
  (*fu)(kPhi, kPhiRef) = j.dangle_dref[0];
  (*fu)(kTheta, kThetaRef) = j.dangle_dref[1];
}

void QuadrotorModel::FlowAndJacobian(const Vec<kNx>& x, const Vec<kNu>& u, double psi_ref,
                                     const AttitudeModelParams& m, Vec<kNx>* f, Jacobian* jac) {
  *jac = OwnDynamicsJacobian::At(x[kPhi], x[kTheta], x[kPsi], u, psi_ref, m);
  f->segment<3>(kPos) = x.segment<3>(kVel);
  f->segment<3>(kVel) = jac->vdot;
  f->segment<3>(kPhi) = jac->angle_dot;
}

}  // namespace fnmpc::model
