// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/frame_conversions.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "fnmpc/core/rotation.hpp"

namespace fnmpc::mavlink {
namespace {

constexpr double kTol = 1e-12;

// R_ENU_NED and R_FRD_FLU as matrices (README "Frames and units").
Mat3 EnuNed() {
  Mat3 r;
  r << 0, 1, 0, 1, 0, 0, 0, 0, -1;
  return r;
}
Mat3 FrdFlu() { return Vec3(1, -1, -1).asDiagonal(); }

Vec3 RandomEuler(std::mt19937* rng) {
  std::uniform_real_distribution<double> angle(-M_PI, M_PI);
  std::uniform_real_distribution<double> pitch(-1.5, 1.5);  // away from gimbal lock
  return {angle(*rng), pitch(*rng), angle(*rng)};
}

TEST(FrameConversionsTest, WorldVectorsNorthEastDownToEastNorthUp) {
  // Flying north at 1 m/s, 2 m east of the origin, 3 m up (z down = -3)
  EXPECT_TRUE(NedToEnu(Vec3(1, 0, 0)).isApprox(Vec3(0, 1, 0)));   // north is ENU y
  EXPECT_TRUE(NedToEnu(Vec3(0, 2, 0)).isApprox(Vec3(2, 0, 0)));   // east is ENU x
  EXPECT_TRUE(NedToEnu(Vec3(0, 0, -3)).isApprox(Vec3(0, 0, 3)));  // up
  EXPECT_TRUE(EnuToNed(Vec3(2, 1, 3)).isApprox(Vec3(1, 2, -3)));
  std::mt19937 rng(1);
  std::normal_distribution<double> n;
  for (int i = 0; i < 100; ++i) {
    const Vec3 v(n(rng), n(rng), n(rng));
    EXPECT_TRUE(NedToEnu(v).isApprox(EnuNed() * v, kTol));
    EXPECT_TRUE(EnuToNed(NedToEnu(v)).isApprox(v, kTol));
    EXPECT_TRUE(NedToEnu(EnuToNed(v)).isApprox(v, kTol));
  }
}

TEST(FrameConversionsTest, BodyVectorsForwardRightDownToForwardLeftUp) {
  // A resting accelerometer: -g along FRD z (up), +g along FLU z
  EXPECT_TRUE(FrdToFlu(Vec3(0, 0, -9.81)).isApprox(Vec3(0, 0, 9.81)));
  // Turning right (clockwise seen from above): positive FRD yaw rate, negative FLU yaw rate
  EXPECT_TRUE(FrdToFlu(Vec3(0, 0, 0.5)).isApprox(Vec3(0, 0, -0.5)));
  // Rolling right (right wing down) is positive about x in both
  EXPECT_TRUE(FrdToFlu(Vec3(0.3, 0, 0)).isApprox(Vec3(0.3, 0, 0)));
  // Nose up: positive FRD pitch rate (about y right), negative FLU pitch rate (about y left)
  EXPECT_TRUE(FrdToFlu(Vec3(0, 0.2, 0)).isApprox(Vec3(0, -0.2, 0)));
  std::mt19937 rng(2);
  std::normal_distribution<double> n;
  for (int i = 0; i < 100; ++i) {
    const Vec3 v(n(rng), n(rng), n(rng));
    EXPECT_TRUE(FrdToFlu(v).isApprox(FrdFlu() * v, kTol));
    EXPECT_TRUE(FluToFrd(FrdToFlu(v)).isApprox(v, kTol));
  }
}

TEST(FrameConversionsTest, QuaternionIsTheSameAttitudeInTheOtherFrames) {
  std::mt19937 rng(3);
  for (int i = 0; i < 200; ++i) {
    // Given an attitude R_NED_FRD from ZYX angles
    const Vec3 e = RandomEuler(&rng);
    const Mat3 r_ned_frd = RotationZyx(e.x(), e.y(), e.z());
    const Eigen::Quaterniond q_ned_frd(r_ned_frd);
    // When it is converted
    const Eigen::Quaterniond q_enu_flu = NedFrdToEnuFlu(q_ned_frd);
    // Then it is R_ENU_NED R_NED_FRD R_FRD_FLU, a unit quaternion, and converts back
    EXPECT_NEAR(q_enu_flu.norm(), 1.0, kTol);
    EXPECT_TRUE(q_enu_flu.toRotationMatrix().isApprox(EnuNed() * r_ned_frd * FrdFlu(), kTol));
    const Eigen::Quaterniond back = EnuFluToNedFrd(q_enu_flu);
    EXPECT_TRUE(back.toRotationMatrix().isApprox(r_ned_frd, kTol));
    // And it maps body vectors consistently with the vector conversions
    const Vec3 v_frd(0.3, -1.2, 2.0);
    EXPECT_TRUE((q_enu_flu * FrdToFlu(v_frd)).isApprox(NedToEnu(q_ned_frd * v_frd), kTol));
    // The other direction, from a random ENU/FLU attitude
    const Eigen::Quaterniond q2(RotationZyx(e.z(), e.y(), e.x()));
    EXPECT_TRUE(EnuFluToNedFrd(q2).toRotationMatrix().isApprox(
        EnuNed() * q2.toRotationMatrix() * FrdFlu(), kTol));
    EXPECT_TRUE(NedFrdToEnuFlu(EnuFluToNedFrd(q2))
                    .toRotationMatrix()
                    .isApprox(q2.toRotationMatrix(), kTol));
  }
}

TEST(FrameConversionsTest, EulerAnglesMatchTheQuaternionConversion) {
  // Heading north in NED (yaw 0) is yaw pi/2 in ENU; east (pi/2) is 0; a nose-up pitch in
  // FRD is a negative pitch in FLU; roll keeps its sign.
  EXPECT_TRUE(EulerNedFrdToEnuFlu(Vec3(0, 0, 0)).isApprox(Vec3(0, 0, M_PI_2)));
  EXPECT_TRUE(EulerNedFrdToEnuFlu(Vec3(0.1, 0.2, M_PI_2)).isApprox(Vec3(0.1, -0.2, 0)));
  EXPECT_NEAR(EulerNedFrdToEnuFlu(Vec3(0, 0, -M_PI_2)).z(), M_PI, kTol);  // west
  std::mt19937 rng(4);
  for (int i = 0; i < 200; ++i) {
    const Vec3 e_ned = RandomEuler(&rng);
    const Vec3 e_enu = EulerNedFrdToEnuFlu(e_ned);
    // The converted angles give R_ENU_FLU = R_ENU_NED R_NED_FRD R_FRD_FLU
    const Mat3 r_enu_flu = EnuNed() * RotationZyx(e_ned.x(), e_ned.y(), e_ned.z()) * FrdFlu();
    EXPECT_TRUE(RotationZyx(e_enu.x(), e_enu.y(), e_enu.z()).isApprox(r_enu_flu, kTol));
    EXPECT_GT(e_enu.z(), -M_PI);
    EXPECT_LE(e_enu.z(), M_PI);
    // Round trip (yaw wrapped)
    const Vec3 back = EulerEnuFluToNedFrd(e_enu);
    EXPECT_NEAR(back.x(), e_ned.x(), kTol);
    EXPECT_NEAR(back.y(), e_ned.y(), kTol);
    EXPECT_NEAR(WrapAngle(back.z() - e_ned.z()), 0.0, kTol);
    // The other direction
    const Vec3 e_ned2 = EulerEnuFluToNedFrd(e_ned);
    const Mat3 r_ned_frd = EnuNed() * RotationZyx(e_ned.x(), e_ned.y(), e_ned.z()) * FrdFlu();
    EXPECT_TRUE(RotationZyx(e_ned2.x(), e_ned2.y(), e_ned2.z()).isApprox(r_ned_frd, kTol));
  }
}

TEST(FrameConversionsTest, MavlinkQuaternionArraysAreWxyz) {
  const std::array<float, 4> q{0.5F, -0.5F, 0.5F, -0.5F};
  const Eigen::Quaterniond e = QuaternionFromWxyz(q);
  EXPECT_EQ(e.w(), 0.5);
  EXPECT_EQ(e.x(), -0.5);
  EXPECT_EQ(e.y(), 0.5);
  EXPECT_EQ(e.z(), -0.5);
  EXPECT_EQ(QuaternionToWxyz(e), q);
}

}  // namespace
}  // namespace fnmpc::mavlink
