// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/eigen_abi.hpp"  // before any Eigen header

#include <array>

#include <Eigen/Geometry>

#include "fnmpc/core/types.hpp"

/// Conversions between MAVLink's frames and the project's (README, "Frames and units").
///
/// MAVLink (PX4, ArduPilot): world NED (x north, y east, z down; yaw 0 = north, clockwise
/// positive), body FRD (x forward, y right, z down); attitudes rotate body vectors into the
/// world (R_NED_FRD), quaternions ordered (w, x, y, z), Euler angles ZYX.
/// fnmpc: world ENU (x east, y north, z up; yaw 0 = east, counter-clockwise positive), body
/// FLU (x forward, y left, z up); R = Rz(psi) Ry(theta) Rx(phi) = R_ENU_FLU.
///
/// With the constant rotations R_ENU_NED (x and y swapped, z negated) and R_FRD_FLU
/// (y and z negated):  R_ENU_FLU = R_ENU_NED R_NED_FRD R_FRD_FLU, which for ZYX angles is
/// roll -> roll, pitch -> -pitch, yaw -> pi/2 - yaw. Each conversion is its own kind's
/// inverse pair (tested both ways and round trip in tests/mavlink/frame_conversions_test.cpp).
namespace fnmpc::mavlink {

/// World-frame vector (position [m], velocity [m/s], acceleration) from NED to ENU.
inline Vec3 NedToEnu(const Vec3& v_ned) { return {v_ned.y(), v_ned.x(), -v_ned.z()}; }
/// World-frame vector from ENU to NED.
inline Vec3 EnuToNed(const Vec3& v_enu) { return {v_enu.y(), v_enu.x(), -v_enu.z()}; }

/// Body-frame vector (body rates [rad/s], specific force [m/s^2], body velocity) from FRD to
/// FLU. A resting accelerometer reads (0, 0, -g) in FRD and (0, 0, +g) in FLU.
inline Vec3 FrdToFlu(const Vec3& v_frd) { return {v_frd.x(), -v_frd.y(), -v_frd.z()}; }
/// Body-frame vector from FLU to FRD.
inline Vec3 FluToFrd(const Vec3& v_flu) { return {v_flu.x(), -v_flu.y(), -v_flu.z()}; }

/// Attitude quaternion: R_NED_FRD -> R_ENU_FLU (unit quaternions in, unit out; the sign of
/// the result is not normalised: q and -q are the same attitude).
Eigen::Quaterniond NedFrdToEnuFlu(const Eigen::Quaterniond& q_ned_frd);
/// Attitude quaternion: R_ENU_FLU -> R_NED_FRD.
Eigen::Quaterniond EnuFluToNedFrd(const Eigen::Quaterniond& q_enu_flu);

/// ZYX Euler angles (roll, pitch, yaw) [rad] of R_NED_FRD -> those of R_ENU_FLU:
/// (roll, -pitch, wrap(pi/2 - yaw)), yaw wrapped to (-pi, pi].
Vec3 EulerNedFrdToEnuFlu(const Vec3& rpy_ned_frd);
/// ZYX Euler angles of R_ENU_FLU -> those of R_NED_FRD: (roll, -pitch, wrap(pi/2 - yaw)).
Vec3 EulerEnuFluToNedFrd(const Vec3& rpy_enu_flu);

/// A MAVLink quaternion array (w, x, y, z) as an Eigen quaternion (not normalised).
inline Eigen::Quaterniond QuaternionFromWxyz(const std::array<float, 4>& q) {
  return {double{q[0]}, double{q[1]}, double{q[2]}, double{q[3]}};
}
/// An Eigen quaternion as a MAVLink quaternion array (w, x, y, z).
inline std::array<float, 4> QuaternionToWxyz(const Eigen::Quaterniond& q) {
  return {static_cast<float>(q.w()), static_cast<float>(q.x()), static_cast<float>(q.y()),
          static_cast<float>(q.z())};
}

}  // namespace fnmpc::mavlink
