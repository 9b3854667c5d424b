// SPDX-License-Identifier: BSD-3-Clause
#include "conversions.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <string_view>

#include "dds_node.hpp"
#include "fnmpc/core/rotation.hpp"

namespace fnmpc::ros2 {
namespace {

std_msgs_msg_dds__Header_ MakeHeader(double stamp, const char* frame) {
  std_msgs_msg_dds__Header_ h{};
  h.stamp = ToRosTime(stamp);
  h.frame_id = const_cast<char*>(frame);  // written, never freed: the caller owns it
  return h;
}
geometry_msgs_msg_dds__Vector3_ ToVector3(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3 FromVector3(const geometry_msgs_msg_dds__Vector3_& m) { return Vec3(m.x, m.y, m.z); }
geometry_msgs_msg_dds__Point_ ToPoint(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
Measurement Base(SensorKind kind, const std_msgs_msg_dds__Header_& h, int vehicle) {
  Measurement m;
  m.kind = kind;
  m.vehicle = vehicle;
  m.stamp = FromRosTime(h.stamp);
  m.arrival = m.stamp;  // set by the receiver when it knows the delivery time
  return m;
}
// formation::ToString's views are of string literals (null-terminated).
char* Literal(std::string_view s) { return const_cast<char*>(s.data()); }

}  // namespace

geometry_msgs_msg_dds__Quaternion_ EulerToQuaternion(const Vec3& e) {
  const Eigen::Quaterniond q(RotationZyx(e.x(), e.y(), e.z()));
  return {q.x(), q.y(), q.z(), q.w()};
}

Vec3 QuaternionToEuler(const geometry_msgs_msg_dds__Quaternion_& m) {
  return EulerZyx(Eigen::Quaterniond(m.w, m.x, m.y, m.z).normalized().toRotationMatrix());
}

geometry_msgs_msg_dds__PoseStamped_ ToPose(const Measurement& m) {
  geometry_msgs_msg_dds__PoseStamped_ p{};
  p.header = MakeHeader(m.stamp, kWorldFrame);
  p.pose.position = ToPoint(m.position);
  p.pose.orientation = EulerToQuaternion(m.euler);
  return p;
}

sensor_msgs_msg_dds__Imu_ ToImu(const Measurement& m, const char* body_frame) {
  sensor_msgs_msg_dds__Imu_ i{};
  i.header = MakeHeader(m.stamp, body_frame);
  i.orientation.w = 1.0;
  i.orientation_covariance[0] = -1.0;  // REP 145: no orientation estimate
  i.angular_velocity = ToVector3(m.gyro);
  i.linear_acceleration = ToVector3(m.accel);
  return i;
}

fnmpc_msgs_msg_dds__OpticalFlow_ ToOpticalFlow(const Measurement& m) {
  fnmpc_msgs_msg_dds__OpticalFlow_ f{};
  f.header = MakeHeader(m.stamp, kWorldFrame);
  f.velocity = ToVector3(m.velocity);
  return f;
}

fnmpc_msgs_msg_dds__Heading_ ToHeading(const Measurement& m) {
  fnmpc_msgs_msg_dds__Heading_ h{};
  h.header = MakeHeader(m.stamp, kWorldFrame);
  h.yaw = m.yaw;
  return h;
}

sensor_msgs_msg_dds__BatteryState_ ToBattery(const Measurement& m) {
  sensor_msgs_msg_dds__BatteryState_ b{};
  b.header = MakeHeader(m.stamp, "");
  b.voltage = static_cast<float>(m.voltage);
  b.temperature = b.current = b.charge = b.capacity = b.design_capacity = b.percentage =
      std::numeric_limits<float>::quiet_NaN();
  b.present = true;
  b.location = const_cast<char*>("");
  b.serial_number = const_cast<char*>("");
  return b;
}

fnmpc_msgs_msg_dds__RelativeObservation_ ToRelative(const Measurement& m, const char* body_frame) {
  fnmpc_msgs_msg_dds__RelativeObservation_ r{};
  r.header = MakeHeader(m.stamp, body_frame);
  r.neighbour_id = m.relative.target;
  r.range = m.relative.range;
  r.bearing = m.relative.bearing;
  r.elevation = m.relative.elevation;
  r.relative_yaw = m.relative.relative_yaw;
  return r;
}

Measurement FromPose(const geometry_msgs_msg_dds__PoseStamped_& msg, int vehicle) {
  Measurement m = Base(SensorKind::kMocapPose, msg.header, vehicle);
  m.position = Vec3(msg.pose.position.x, msg.pose.position.y, msg.pose.position.z);
  m.euler = QuaternionToEuler(msg.pose.orientation);
  return m;
}

Measurement FromImu(const sensor_msgs_msg_dds__Imu_& msg, int vehicle) {
  Measurement m = Base(SensorKind::kImu, msg.header, vehicle);
  m.accel = FromVector3(msg.linear_acceleration);
  m.gyro = FromVector3(msg.angular_velocity);
  return m;
}

Measurement FromOpticalFlow(const fnmpc_msgs_msg_dds__OpticalFlow_& msg, int vehicle) {
  Measurement m = Base(SensorKind::kOpticalFlow, msg.header, vehicle);
  m.velocity = FromVector3(msg.velocity);
  return m;
}

Measurement FromHeading(const fnmpc_msgs_msg_dds__Heading_& msg, int vehicle) {
  Measurement m = Base(SensorKind::kCompass, msg.header, vehicle);
  m.yaw = msg.yaw;
  return m;
}

Measurement FromBattery(const sensor_msgs_msg_dds__BatteryState_& msg, int vehicle) {
  Measurement m = Base(SensorKind::kBattery, msg.header, vehicle);
  m.voltage = msg.voltage;
  return m;
}

Measurement FromRelative(const fnmpc_msgs_msg_dds__RelativeObservation_& msg, int vehicle) {
  Measurement m = Base(SensorKind::kRelative, msg.header, vehicle);
  m.relative.target = msg.neighbour_id;
  m.relative.range = msg.range;
  m.relative.bearing = msg.bearing;
  m.relative.elevation = msg.elevation;
  m.relative.relative_yaw = msg.relative_yaw;
  return m;
}

fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_ ToSetpoint(const formation::ControlOutput& out) {
  fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_ s{};
  s.header = MakeHeader(out.time, "");
  s.thrust = out.thrust;
  s.throttle = out.throttle;
  s.roll = out.roll;
  s.pitch = out.pitch;
  s.yaw = out.yaw;
  s.phase = Literal(formation::ToString(out.phase));
  return s;
}

nav_msgs_msg_dds__Odometry_ ToOdometry(double t, const char* frame, const char* body_frame,
                                       const Vec3& position, const Vec3& velocity_world,
                                       const Vec3& euler, const Vec3& body_rates) {
  nav_msgs_msg_dds__Odometry_ o{};
  o.header = MakeHeader(t, frame);
  o.child_frame_id = const_cast<char*>(body_frame);
  o.pose.pose.position = ToPoint(position);
  o.pose.pose.orientation = EulerToQuaternion(euler);
  const Mat3 r = RotationZyx(euler.x(), euler.y(), euler.z());
  o.twist.twist.linear = ToVector3(r.transpose() * velocity_world);
  o.twist.twist.angular = ToVector3(body_rates);
  return o;
}

void FromOdometry(const nav_msgs_msg_dds__Odometry_& msg, Vec3* position, Vec3* velocity_world,
                  Vec3* euler) {
  const auto& p = msg.pose.pose.position;
  *position = Vec3(p.x, p.y, p.z);
  *euler = QuaternionToEuler(msg.pose.pose.orientation);
  *velocity_world =
      RotationZyx(euler->x(), euler->y(), euler->z()) * FromVector3(msg.twist.twist.linear);
}

}  // namespace fnmpc::ros2
