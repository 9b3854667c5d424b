// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"

namespace fnmpc::sim {

/// Generalised force on the six dofs of a MuJoCo free joint from a world-frame force and torque
/// acting at the body's centre of mass: what MuJoCo does with the body's row of `xfrc_applied`,
/// to be added to `qfrc_applied` at the joint's first dof instead.
///
/// Why: MuJoCo 2.2 maps every non-zero `xfrc_applied` row through `mj_applyFT`, which builds
/// dense 3 x nv translational and rotational Jacobians and multiplies them out: O(nv) per body,
/// O(N^2) per physics step for N free bodies (nv = 6 N). For a free joint the Jacobian is known
/// in closed form, so the same generalised force costs a handful of flops.
///
/// Convention (MuJoCo's free joint, checked against `mj_applyFT` in tests/sim/free_joint_force_
/// test.cpp): dofs 0-2 translate the body frame's origin along the world axes; dofs 3-5 rotate
/// about the body frame's own axes (qvel[3:6] is the body-frame angular velocity). A world force
/// f at the centre of mass c (body-frame offset `com_b` from the body origin, MuJoCo's
/// body_ipos) and a world torque tau therefore give
///   qfrc[0:3] = f,   qfrc[3:6] = R^T (tau + (R com_b) x f) = R^T tau + com_b x (R^T f),
/// with R the body's orientation (body to world).
[[nodiscard]] inline Vec<6> FreeJointForce(const Mat3& body_rotation, const Vec3& com_b,
                                           const Vec3& force_w, const Vec3& torque_w) {
  Vec<6> q;
  q.head<3>() = force_w;
  q.tail<3>() =
      body_rotation.transpose() * torque_w + com_b.cross(body_rotation.transpose() * force_w);
  return q;
}

}  // namespace fnmpc::sim
