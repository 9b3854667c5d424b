// SPDX-License-Identifier: BSD-3-Clause
// FreeJointForce: the closed-form generalised force of a free joint equals what
// MuJoCo's own xfrc_applied path (mj_applyFT through the body Jacobians) gives, including a
// centre of mass off the body origin, so the simulator may write qfrc_applied directly.
#include "fnmpc/sim/free_joint_force.hpp"

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <string>

#include "fnmpc/core/types.hpp"

namespace fnmpc::sim {
namespace {

// Three free bodies: one with its centre of mass at the body origin (as the simulator's
// vehicles), one with an offset and rotated inertial frame, one with a non-diagonal inertia.
constexpr const char* kModel = R"(
<mujoco>
  <option timestep="0.001" gravity="0 0 -9.81" integrator="Euler"/>
  <worldbody>
    <body name="a" pos="0 0 1">
      <freejoint/>
      <inertial pos="0 0 0" mass="1.2" diaginertia="0.01 0.012 0.02"/>
      <geom type="box" size="0.1 0.1 0.02" contype="0" conaffinity="0"/>
    </body>
    <body name="b" pos="2 0 1" quat="0.9 0.1 -0.3 0.2">
      <freejoint/>
      <inertial pos="0.07 -0.03 0.05" quat="0.8 0.2 0.1 -0.4" mass="0.7"
                diaginertia="0.004 0.006 0.009"/>
      <geom type="sphere" size="0.05" contype="0" conaffinity="0"/>
    </body>
    <body name="c" pos="-1 3 2">
      <freejoint/>
      <inertial pos="-0.02 0.04 0.01" mass="2.0" fullinertia="0.03 0.04 0.05 0.002 -0.001 0.003"/>
      <geom type="sphere" size="0.05" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>)";

struct ModelDeleter {
  void operator()(mjModel* m) const { mj_deleteModel(m); }
};
struct DataDeleter {
  void operator()(mjData* d) const { mj_deleteData(d); }
};

std::unique_ptr<mjModel, ModelDeleter> LoadModel() {
  std::array<char, 1000> error{};
  auto vfs = std::make_unique<mjVFS>();  // ~2 MB: never on the stack
  mj_defaultVFS(vfs.get());
  const std::string xml(kModel);
  EXPECT_EQ(mj_makeEmptyFileVFS(vfs.get(), "model.xml", static_cast<int>(xml.size())), 0);
  const int file = mj_findFileVFS(vfs.get(), "model.xml");
  std::copy(xml.begin(), xml.end(), static_cast<char*>(vfs->filedata[file]));
  mjModel* m = mj_loadXML("model.xml", vfs.get(), error.data(), static_cast<int>(error.size()));
  mj_deleteVFS(vfs.get());
  EXPECT_NE(m, nullptr) << error.data();
  return std::unique_ptr<mjModel, ModelDeleter>(m);
}

/// Body-to-world rotation from a free joint's qpos quaternion (w, x, y, z), normalised as
/// MuJoCo's kinematics does.
Mat3 RotationOf(const mjData* d, int qposadr) {
  const double* q = d->qpos + qposadr + 3;
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
}

TEST(FreeJointForceTest, EqualsMuJoCosXfrcPathIncludingOffsetCentreOfMass) {
  auto model = LoadModel();
  ASSERT_NE(model, nullptr);
  mjModel* m = model.get();
  ASSERT_EQ(m->nv, 18);
  std::unique_ptr<mjData, DataDeleter> data(mj_makeData(m));
  mjData* d = data.get();
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  double max_qfrc_err = 0.0, max_qacc_err = 0.0, max_qacc = 0.0;
  for (int trial = 0; trial < 20; ++trial) {
    // Given random poses (unnormalised quaternions too), velocities and wrenches,
    mj_resetData(m, d);
    for (int j = 0; j < m->njnt; ++j) {
      double* q = d->qpos + m->jnt_qposadr[j];
      for (int k = 0; k < 3; ++k) q[k] = 3.0 * n01(rng);
      for (int k = 3; k < 7; ++k) q[k] = n01(rng) * (trial % 2 == 0 ? 1.0 : 2.5);
      for (int k = 0; k < 6; ++k) d->qvel[m->jnt_dofadr[j] + k] = n01(rng);
    }
    std::array<Vec3, 4> force, torque;
    for (int b = 1; b < m->nbody; ++b) {
      force[b] = 20.0 * Vec3(n01(rng), n01(rng), n01(rng));
      torque[b] = 2.0 * Vec3(n01(rng), n01(rng), n01(rng));
    }
    // When MuJoCo applies them as xfrc_applied (mj_applyFT at xipos, via mj_forward),
    for (int b = 1; b < m->nbody; ++b) {
      Eigen::Map<Vec3>(d->xfrc_applied + 6 * b) = force[b];
      Eigen::Map<Vec3>(d->xfrc_applied + 6 * b + 3) = torque[b];
    }
    mj_forward(m, d);
    VecX qacc_xfrc = Eigen::Map<const VecX>(d->qacc, m->nv);
    VecX qfrc_xfrc = VecX::Zero(m->nv);
    for (int b = 1; b < m->nbody; ++b) {
      mj_applyFT(m, d, force[b].data(), torque[b].data(), d->xipos + 3 * b, b, qfrc_xfrc.data());
    }
    // and FreeJointForce writes them into qfrc_applied (xfrc_applied cleared),
    mju_zero(d->xfrc_applied, 6 * m->nbody);
    VecX qfrc_direct = VecX::Zero(m->nv);
    for (int b = 1; b < m->nbody; ++b) {
      const int j = m->body_jntadr[b];
      ASSERT_EQ(m->jnt_type[j], mjJNT_FREE);
      const Vec3 com_b(m->body_ipos + 3 * b);
      qfrc_direct.segment<6>(m->jnt_dofadr[j]) =
          FreeJointForce(RotationOf(d, m->jnt_qposadr[j]), com_b, force[b], torque[b]);
    }
    Eigen::Map<VecX>(d->qfrc_applied, m->nv) = qfrc_direct;
    mj_forward(m, d);
    const VecX qacc_direct = Eigen::Map<const VecX>(d->qacc, m->nv);
    // then the generalised forces and the accelerations agree to rounding.
    max_qfrc_err = std::max(max_qfrc_err, (qfrc_direct - qfrc_xfrc).cwiseAbs().maxCoeff());
    max_qacc_err = std::max(max_qacc_err, (qacc_direct - qacc_xfrc).cwiseAbs().maxCoeff());
    max_qacc = std::max(max_qacc, qacc_xfrc.cwiseAbs().maxCoeff());
  }
  EXPECT_LT(max_qfrc_err, 1e-12);
  EXPECT_LT(max_qacc_err, 1e-12 * max_qacc);
  // (A torque sign or frame error would show at the size of the torques, about 1.)
  EXPECT_GT(max_qacc, 10.0);
}

TEST(FreeJointForceTest, OffCentreForceMakesTheLeverArmTorque) {
  // Given a body rotated 90 degrees about z with its centre of mass 0.1 m along body x,
  const Mat3 r = Eigen::AngleAxisd(std::acos(-1.0) / 2, Vec3::UnitZ()).toRotationMatrix();
  // when a world force of 1 N along world z acts at the centre of mass (no torque),
  const Vec<6> q = FreeJointForce(r, Vec3(0.1, 0.0, 0.0), Vec3(0, 0, 1), Vec3::Zero());
  // then the translational dofs get the force and the rotational dofs (body frame) the
  // torque about the body origin, (0.1 x_b) x z_w = -0.1 y_b.
  EXPECT_NEAR((q.head<3>() - Vec3(0, 0, 1)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((q.tail<3>() - Vec3(0.0, -0.1, 0.0)).norm(), 0.0, 1e-15);
}

}  // namespace
}  // namespace fnmpc::sim
