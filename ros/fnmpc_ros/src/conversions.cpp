// SPDX-License-Identifier: BSD-3-Clause
#include "conversions.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>

#include "fnmpc/core/rotation.hpp"

namespace fnmpc::ros_bridge {

std::string BodyFrame(const std::string& vehicle) { return vehicle + "/base_link"; }
std::string MpcFrame(const std::string& vehicle) { return vehicle + "/mpc"; }

double ToSec(const ros::Time& t) { return t.toSec(); }

ros::Time ToRosTime(double t) {
  const auto ns = static_cast<std::int64_t>(std::llround(std::max(0.0, t) * 1e9));
  ros::Time r;
  r.fromNSec(static_cast<std::uint64_t>(ns));
  return r;
}

geometry_msgs::Quaternion EulerToQuaternion(const Vec3& e) {
  const Eigen::Quaterniond q(RotationZyx(e.x(), e.y(), e.z()));
  geometry_msgs::Quaternion m;
  m.w = q.w();
  m.x = q.x();
  m.y = q.y();
  m.z = q.z();
  return m;
}

Vec3 QuaternionToEuler(const geometry_msgs::Quaternion& m) {
  const Mat3 r = Eigen::Quaterniond(m.w, m.x, m.y, m.z).normalized().toRotationMatrix();
  return EulerZyx(r);
}

namespace {
std_msgs::Header MakeHeader(double stamp, const std::string& frame, std::uint32_t seq) {
  std_msgs::Header h;
  h.stamp = ToRosTime(stamp);
  h.frame_id = frame;
  h.seq = seq;
  return h;
}
geometry_msgs::Vector3 ToVector3(const Vec3& v) {
  geometry_msgs::Vector3 m;
  m.x = v.x();
  m.y = v.y();
  m.z = v.z();
  return m;
}
Vec3 FromVector3(const geometry_msgs::Vector3& m) { return Vec3(m.x, m.y, m.z); }
geometry_msgs::Point ToPoint(const Vec3& v) {
  geometry_msgs::Point m;
  m.x = v.x();
  m.y = v.y();
  m.z = v.z();
  return m;
}
Measurement Base(SensorKind kind, const std_msgs::Header& h, int vehicle) {
  Measurement m;
  m.kind = kind;
  m.vehicle = vehicle;
  m.stamp = ToSec(h.stamp);
  m.arrival = m.stamp;  // set by the receiver when it knows the delivery time
  return m;
}
}  // namespace

geometry_msgs::PoseStamped ToPose(const Measurement& m, std::uint32_t seq) {
  geometry_msgs::PoseStamped p;
  p.header = MakeHeader(m.stamp, kWorldFrame, seq);
  p.pose.position = ToPoint(m.position);
  p.pose.orientation = EulerToQuaternion(m.euler);
  return p;
}

sensor_msgs::Imu ToImu(const Measurement& m, const std::string& vehicle, std::uint32_t seq) {
  sensor_msgs::Imu i;
  i.header = MakeHeader(m.stamp, BodyFrame(vehicle), seq);
  i.orientation_covariance[0] = -1.0;  // REP 145: no orientation estimate
  i.angular_velocity = ToVector3(m.gyro);
  i.linear_acceleration = ToVector3(m.accel);
  return i;
}

fnmpc_ros::OpticalFlow ToOpticalFlow(const Measurement& m, std::uint32_t seq) {
  fnmpc_ros::OpticalFlow f;
  f.header = MakeHeader(m.stamp, kWorldFrame, seq);
  f.velocity = ToVector3(m.velocity);
  return f;
}

fnmpc_ros::Heading ToHeading(const Measurement& m, std::uint32_t seq) {
  fnmpc_ros::Heading h;
  h.header = MakeHeader(m.stamp, kWorldFrame, seq);
  h.yaw = m.yaw;
  return h;
}

sensor_msgs::BatteryState ToBattery(const Measurement& m, std::uint32_t seq) {
  sensor_msgs::BatteryState b;
  b.header = MakeHeader(m.stamp, "", seq);
  b.voltage = static_cast<float>(m.voltage);
  b.current = b.charge = b.capacity = b.design_capacity = b.percentage =
      std::numeric_limits<float>::quiet_NaN();
  b.present = true;
  return b;
}

fnmpc_ros::RelativeMeasurement ToRelative(const Measurement& m, const std::string& vehicle,
                                          std::uint32_t seq) {
  fnmpc_ros::RelativeMeasurement r;
  r.header = MakeHeader(m.stamp, BodyFrame(vehicle), seq);
  r.neighbour_id = m.relative.target;
  r.range = m.relative.range;
  r.bearing = m.relative.bearing;
  r.elevation = m.relative.elevation;
  r.relative_yaw = m.relative.relative_yaw;
  return r;
}

Measurement FromPose(const geometry_msgs::PoseStamped& msg, int vehicle) {
  Measurement m = Base(SensorKind::kMocapPose, msg.header, vehicle);
  m.position = Vec3(msg.pose.position.x, msg.pose.position.y, msg.pose.position.z);
  m.euler = QuaternionToEuler(msg.pose.orientation);
  return m;
}

Measurement FromImu(const sensor_msgs::Imu& msg, int vehicle) {
  Measurement m = Base(SensorKind::kImu, msg.header, vehicle);
  m.accel = FromVector3(msg.linear_acceleration);
  m.gyro = FromVector3(msg.angular_velocity);
  return m;
}

Measurement FromOpticalFlow(const fnmpc_ros::OpticalFlow& msg, int vehicle) {
  Measurement m = Base(SensorKind::kOpticalFlow, msg.header, vehicle);
  m.velocity = FromVector3(msg.velocity);
  return m;
}

Measurement FromHeading(const fnmpc_ros::Heading& msg, int vehicle) {
  Measurement m = Base(SensorKind::kCompass, msg.header, vehicle);
  m.yaw = msg.yaw;
  return m;
}

Measurement FromBattery(const sensor_msgs::BatteryState& msg, int vehicle) {
  Measurement m = Base(SensorKind::kBattery, msg.header, vehicle);
  m.voltage = msg.voltage;
  return m;
}

Measurement FromRelative(const fnmpc_ros::RelativeMeasurement& msg, int vehicle) {
  Measurement m = Base(SensorKind::kRelative, msg.header, vehicle);
  m.relative.target = msg.neighbour_id;
  m.relative.range = msg.range;
  m.relative.bearing = msg.bearing;
  m.relative.elevation = msg.elevation;
  m.relative.relative_yaw = msg.relative_yaw;
  return m;
}

fnmpc_ros::AttitudeThrustSetpoint ToSetpoint(const formation::ControlOutput& out) {
  fnmpc_ros::AttitudeThrustSetpoint s;
  s.header = MakeHeader(out.time, "", 0);
  s.thrust = out.thrust;
  s.throttle = out.throttle;
  s.roll = out.roll;
  s.pitch = out.pitch;
  s.yaw = out.yaw;
  s.phase = std::string(formation::ToString(out.phase));
  return s;
}

fnmpc_ros::SolverDiagnostics ToDiagnostics(const formation::ControlOutput& out,
                                           const formation::VehicleController& c) {
  fnmpc_ros::SolverDiagnostics d;
  d.header = MakeHeader(out.time, "", 0);
  d.phase = std::string(formation::ToString(out.phase));
  d.nmpc = out.nmpc;
  d.status = std::string(rti::ToString(out.status));
  d.cost = out.cost;
  d.kkt = out.kkt;
  d.solver_time = out.solver_time;
  d.sqp_iterations = out.sqp_iterations;
  d.qp_iterations = out.qp_iterations;
  d.fallback = out.fallback;
  d.fallback_count = c.fallbacks();
  d.guarded = out.guarded;
  d.estimator_rejections = c.estimator_rejections();
  d.nmpc_thrust = out.nmpc_thrust;
  d.nmpc_roll = out.nmpc_roll;
  d.nmpc_pitch = out.nmpc_pitch;
  d.reference = ToPoint(out.reference);
  d.voltage = out.voltage;
  d.recovery = std::string(formation::ToString(out.recovery));
  d.recovery_reason = std::string(formation::ToString(out.recovery_reason));
  d.active_neighbours = out.active_neighbours;
  const auto& nbs = c.config().neighbours;
  for (std::size_t j = 0; j < nbs.size(); ++j) {
    d.neighbour_ids.push_back(nbs[j].vehicle);
    const Vec3 r = j < c.estimates().neighbours.size() ? Vec3(c.estimates().neighbours[j].head<3>())
                                                       : Vec3::Constant(kNaN);
    d.neighbour_relative.push_back(ToPoint(r));
  }
  return d;
}

nav_msgs::Odometry ToOdometry(double t, const std::string& frame, const std::string& vehicle,
                              const Vec3& position, const Vec3& velocity_world, const Vec3& euler,
                              const Vec3& body_rates) {
  nav_msgs::Odometry o;
  o.header = MakeHeader(t, frame, 0);
  o.child_frame_id = BodyFrame(vehicle);
  o.pose.pose.position = ToPoint(position);
  o.pose.pose.orientation = EulerToQuaternion(euler);
  const Mat3 r = RotationZyx(euler.x(), euler.y(), euler.z());
  o.twist.twist.linear = ToVector3(r.transpose() * velocity_world);
  o.twist.twist.angular = ToVector3(body_rates);
  return o;
}

void FromOdometry(const nav_msgs::Odometry& msg, Vec3* position, Vec3* velocity_world,
                  Vec3* euler) {
  const auto& p = msg.pose.pose.position;
  *position = Vec3(p.x, p.y, p.z);
  *euler = QuaternionToEuler(msg.pose.pose.orientation);
  *velocity_world =
      RotationZyx(euler->x(), euler->y(), euler->z()) * FromVector3(msg.twist.twist.linear);
}

std::string RequiredParam(const ros::NodeHandle& nh, const std::string& name) {
  std::string v;
  if (!nh.getParam(name, v) || v.empty()) {
    throw std::runtime_error("missing required parameter " + nh.resolveName(name) +
                             " (a string, see docs/ros.md)");
  }
  return v;
}

fnmpc_ros::Plan ToPlan(const formation::PlanMessage& plan) {
  fnmpc_ros::Plan m;
  m.header = MakeHeader(plan.stamp, kWorldFrame, 0);
  m.vehicle = plan.vehicle;
  m.sample_time = plan.sample_time;
  for (int k = 0; k < plan.points; ++k) {
    const auto i = static_cast<std::size_t>(k);
    m.displacement.push_back(ToVector3(plan.displacement[i]));
    m.velocity.push_back(ToVector3(plan.velocity[i]));
    m.thrust.push_back(plan.thrust[i]);
  }
  m.disturbance = ToVector3(plan.disturbance);
  return m;
}

bool FromPlan(const fnmpc_ros::Plan& msg, formation::PlanMessage* plan) {
  const std::size_t n = msg.displacement.size();
  if (n > static_cast<std::size_t>(formation::kMaxPlanIntervals) + 1 || msg.velocity.size() != n ||
      msg.thrust.size() != n) {
    return false;
  }
  plan->vehicle = msg.vehicle;
  plan->stamp = ToSec(msg.header.stamp);
  plan->sample_time = msg.sample_time;
  plan->points = static_cast<int>(n);
  for (std::size_t i = 0; i < n; ++i) {
    plan->displacement[i] = FromVector3(msg.displacement[i]);
    plan->velocity[i] = FromVector3(msg.velocity[i]);
    plan->thrust[i] = msg.thrust[i];
  }
  plan->disturbance = FromVector3(msg.disturbance);
  return plan->Valid();
}

}  // namespace fnmpc::ros_bridge
