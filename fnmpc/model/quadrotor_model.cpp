// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/model/quadrotor_model.hpp"

#include <cmath>

namespace fnmpc::model {

OwnDynamicsJacobian OwnDynamicsJacobian::At(double phi, double theta, double psi, const Vec3& u,
                                            double psi_ref, const AttitudeModelParams& m) {
  OwnDynamicsJacobian j;
  const double t_over_m = u[0] / m.mass;
  Vec3 z;
  BodyZAndJacobian(phi, theta, psi, &z, &j.dv_dangles);
  j.vdot = z * t_over_m - Vec3(0, 0, kGravity);
  j.dv_dangles *= t_over_m;
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

OwnInterval OwnInterval::Integrate(const Vec3& v0, const Vec3& angles0, const Vec3& u,
                                   double psi_ref, const AttitudeModelParams& m, double dt,
                                   int steps) {
  const double h = dt / steps;
  const double t_over_m = u[0] / m.mass;
  const Vec3 inv_tau = m.time_constant.cwiseInverse();
  const Vec3 target = m.gain.cwiseProduct(Vec3(u[1], u[2], psi_ref));
  const Eigen::Vector2d gain_over_tau = m.gain.head<2>().cwiseProduct(inv_tau.head<2>());
  // Derivative of the state and of its sensitivity at one RK4 stage.
  struct Stage {
    Vec3 v, kv, ka, dka0;
    Eigen::Vector2d dkref;
    Mat<3, kCols> dv, dkv;
  };
  const auto eval = [&](const Vec3& a, const Vec3& al, const Eigen::Vector2d& be, Stage* s) {
    // z = R e3 and its derivatives by (phi, theta, psi).
    Vec3 z;
    Mat3 dz;
    BodyZAndJacobian(a[0], a[1], a[2], &z, &dz);
    const auto zphi = dz.col(0);
    const auto zth = dz.col(1);
    const auto zpsi = dz.col(2);
    s->kv = z * t_over_m;
    s->kv[2] -= kGravity;
    s->ka = (target - a).cwiseProduct(inv_tau);
    // v' depends on the angles, whose sensitivities are diagonal: column-wise products.
    s->dkv.col(0) = zphi * (t_over_m * al[0]);
    s->dkv.col(1) = zth * (t_over_m * al[1]);
    s->dkv.col(2) = zpsi * (t_over_m * al[2]);
    s->dkv.col(3) = z / m.mass;
    s->dkv.col(4) = zphi * (t_over_m * be[0]);
    s->dkv.col(5) = zth * (t_over_m * be[1]);
    s->dka0 = -al.cwiseProduct(inv_tau);
    s->dkref = gain_over_tau - be.cwiseProduct(inv_tau.head<2>());
  };
  OwnInterval r;
  r.displacement.setZero();
  r.velocity = v0;
  r.angles = angles0;
  r.dp.setZero();
  r.dv.setZero();
  r.dangle_dangle0.setOnes();
  r.dangle_dref.setZero();
  Stage s1, s2, s3, s4;
  for (int step = 0; step < steps; ++step) {
    // Stage states x + c h k_prev and their sensitivities S + c h dk_prev.
    s1.v = r.velocity;
    s1.dv = r.dv;
    eval(r.angles, r.dangle_dangle0, r.dangle_dref, &s1);
    s2.v = r.velocity + (0.5 * h) * s1.kv;
    s2.dv = r.dv + (0.5 * h) * s1.dkv;
    eval(r.angles + (0.5 * h) * s1.ka, r.dangle_dangle0 + (0.5 * h) * s1.dka0,
         r.dangle_dref + (0.5 * h) * s1.dkref, &s2);
    s3.v = r.velocity + (0.5 * h) * s2.kv;
    s3.dv = r.dv + (0.5 * h) * s2.dkv;
    eval(r.angles + (0.5 * h) * s2.ka, r.dangle_dangle0 + (0.5 * h) * s2.dka0,
         r.dangle_dref + (0.5 * h) * s2.dkref, &s3);
    s4.v = r.velocity + h * s3.kv;
    s4.dv = r.dv + h * s3.dkv;
    eval(r.angles + h * s3.ka, r.dangle_dangle0 + h * s3.dka0, r.dangle_dref + h * s3.dkref, &s4);
    const double w = h / 6.0;
    // p' = v: the displacement and its sensitivity integrate the stage velocities.
    r.displacement += w * (s1.v + 2.0 * s2.v + 2.0 * s3.v + s4.v);
    r.dp += w * (s1.dv + 2.0 * s2.dv + 2.0 * s3.dv + s4.dv);
    r.velocity += w * (s1.kv + 2.0 * s2.kv + 2.0 * s3.kv + s4.kv);
    r.dv += w * (s1.dkv + 2.0 * s2.dkv + 2.0 * s3.dkv + s4.dkv);
    r.angles += w * (s1.ka + 2.0 * s2.ka + 2.0 * s3.ka + s4.ka);
    r.dangle_dangle0 += w * (s1.dka0 + 2.0 * s2.dka0 + 2.0 * s3.dka0 + s4.dka0);
    r.dangle_dref += w * (s1.dkref + 2.0 * s2.dkref + 2.0 * s3.dkref + s4.dkref);
  }
  return r;
}

Vec<QuadrotorModel::kNx> QuadrotorModel::Discretise(const Vec<kNx>& x, const Vec<kNu>& u,
                                                    double psi_ref, const AttitudeModelParams& m,
                                                    double dt, int steps, Mat<kNx, kNx>* A,
                                                    Mat<kNx, kNu>* B) {
  const OwnInterval r =
      OwnInterval::Integrate(x.segment<3>(kVel), x.segment<3>(kPhi), u, psi_ref, m, dt, steps);
  Vec<kNx> next;
  next.segment<3>(kPos) = x.segment<3>(kPos) + r.displacement;
  next.segment<3>(kVel) = r.velocity;
  next.segment<3>(kPhi) = r.angles;
  if (A != nullptr && B != nullptr) {
    for (int i = 0; i < 3; ++i) {
      (*A)(kPos + i, kPos + i) = 1.0;
      (*A)(kPos + i, kVel + i) = dt;
      (*A)(kVel + i, kVel + i) = 1.0;
      (*A)(kPhi + i, kPhi + i) = r.dangle_dangle0[i];
    }
    A->block<3, 3>(kPos, kPhi) = r.dp.leftCols<3>();
    A->block<3, 3>(kVel, kPhi) = r.dv.leftCols<3>();
    B->block<3, 3>(kPos, 0) = r.dp.rightCols<3>();
    B->block<3, 3>(kVel, 0) = r.dv.rightCols<3>();
    (*B)(kPhi, kPhiRef) = r.dangle_dref[0];
    (*B)(kTheta, kThetaRef) = r.dangle_dref[1];
  }
  return next;
}

}  // namespace fnmpc::model
