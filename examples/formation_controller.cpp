// SPDX-License-Identifier: BSD-3-Clause
// The product's controller embedded as an onboard program would embed it: a
// formation::VehicleController for a leader, fed time-stamped measurements (motion-capture
// pose at 60 Hz, IMU at 250 Hz, battery at 10 Hz) with Process() and asked for a command every
// 50 ms with Control(); it takes off by PID, switches to the NMPC and flies a 1 m square leg by
// leg. The vehicle here is the NMPC's own model (fnmpc/model/quadrotor_model.hpp) on a flat
// ground, integrated at 1 ms, and the measurements are exact samples of it; on a vehicle they
// come from its sensors and the commands go to its autopilot (docs/autopilot.md).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/model/quadrotor_model.hpp"
#include "fnmpc/model/rk4.hpp"

using namespace fnmpc;

namespace {

constexpr double kGround = 0.1;  // centre-of-mass height resting on the ground [m]

// The NMPC model as the vehicle: state [p, v, roll, pitch, yaw], command [T, roll, pitch].
struct Vehicle {
  Vec<9> x = Vec<9>::Zero();
  model::AttitudeModelParams params;
  Vec3 command = Vec3::Zero();  // [T, roll_ref, pitch_ref]
  double yaw_ref = 0.0;

  Vehicle() { x[2] = kGround; }
  [[nodiscard]] Vec<9> Rate() const {
    return model::QuadrotorModel::Flow<double>(x, command, yaw_ref, params);
  }
  void Step(double dt) {
    x = model::Rk4<model::QuadrotorModel>(x, command, yaw_ref, params, dt, 1);
    if (x[2] < kGround) {  // the ground holds it
      x[2] = kGround;
      x.segment<3>(3).setZero();
    }
  }
  // What an IMU measures: specific force and angular rate in the body frame.
  [[nodiscard]] Measurement Imu(double t) const {
    const Vec<9> rate = Rate();
    const double roll = x[6], pitch = x[7], yaw = x[8];
    const Mat3 r = RotationZyx(roll, pitch, yaw);
    Vec3 accel = rate.segment<3>(3);
    if (x[2] <= kGround && accel.z() < 0) accel.setZero();  // resting: the ground's reaction
    Measurement m;
    m.kind = SensorKind::kImu;
    m.stamp = m.arrival = t;
    m.accel = r.transpose() * (accel + Vec3(0, 0, kGravity));
    // Body rates from the Euler rates (ZYX).
    const Vec3 e = rate.tail<3>();
    const double sr = std::sin(roll), cr = std::cos(roll);
    const double sp = std::sin(pitch), cp = std::cos(pitch);
    m.gyro = Vec3(e.x() - sp * e.z(), cr * e.y() + sr * cp * e.z(), -sr * e.y() + cr * cp * e.z());
    return m;
  }
  [[nodiscard]] Measurement Mocap(double t) const {
    Measurement m;
    m.kind = SensorKind::kMocapPose;
    m.stamp = m.arrival = t;
    m.position = x.head<3>();
    m.euler = x.tail<3>();
    return m;
  }
};

}  // namespace

int main() {
  formation::ControllerConfig config;  // the defaults of the scenario files' controller block
  config.vehicle = 0;
  config.leader = true;
  config.ground_height = kGround;
  config.takeoff_time = 0.5;    // motors start [s]
  config.trajectory_start = 6;  // the square starts [s]
  // A 1 m square at the take-off height, relative to the hover point: 3 s per leg, 1 s hold.
  config.trajectory = formation::WaypointTrajectory::Uniform(
      {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0), Vec3(0, 0, 0)}, 3.0, 1.0);
  formation::VehicleController controller(config);  // throws on an invalid config

  Vehicle vehicle;
  vehicle.params = model::AttitudeModelParams::From(config.params);
  const double ts = config.rti.sample_time;  // control period [s]
  const double end = 24.0;                   // [s]
  double max_error = 0.0;                    // largest |p - reference| after the first leg [m]
  int fallbacks = 0;
  Vec<2> reach = Vec<2>::Zero();  // farthest x and y from the hover point [m]
  formation::FlightPhase phase = formation::FlightPhase::kIdle;
  for (int ms = 0; ms <= static_cast<int>(end * 1000); ++ms) {
    const double t = ms * 1e-3;
    // Measurements in, at their sensors' rates.
    Measurement m;
    if (ms % 4 == 0) {  // IMU, 250 Hz
      m = vehicle.Imu(t);
      m.vehicle = config.vehicle;
      controller.Process(m);
    }
    if (ms % 50 == 0 || ms % 50 == 17 || ms % 50 == 33) {  // motion capture, 60 Hz
      m = vehicle.Mocap(t);
      m.vehicle = config.vehicle;
      controller.Process(m);
    }
    if (ms % 100 == 0) {  // battery, 10 Hz
      m = Measurement{};
      m.kind = SensorKind::kBattery;
      m.vehicle = config.vehicle;
      m.stamp = m.arrival = t;
      m.voltage = 15.8;
      controller.Process(m);
    }
    // Command out, every control period: collective thrust and attitude references.
    if (ms % static_cast<int>(std::lround(ts * 1000)) == 0) {
      const formation::ControlOutput out = controller.Control(t);
      vehicle.command = Vec3(out.thrust, out.roll, out.pitch);
      vehicle.yaw_ref = out.yaw;
      if (out.phase != phase) {
        std::printf("%5.2f s  %-8s at (%.2f, %.2f, %.2f)\n", t,
                    std::string(formation::ToString(out.phase)).c_str(), vehicle.x[0], vehicle.x[1],
                    vehicle.x[2]);
        phase = out.phase;
      }
      if (out.fallback) ++fallbacks;
      if (t > config.trajectory_start + 3.0 && out.reference.allFinite()) {
        max_error = std::max(max_error, (vehicle.x.head<3>() - out.reference).norm());
      }
      if (out.phase == formation::FlightPhase::kNmpc) {  // the corners reached
        reach = reach.cwiseMax(vehicle.x.head<2>() - controller.anchor().head<2>());
      }
    }
    vehicle.Step(1e-3);
  }
  const Vec3 end_point = controller.anchor();  // the square ends where it started
  const double final_error = (vehicle.x.head<3>() - end_point).norm();
  std::printf(
      "square flown to x + %.3f m, y + %.3f m: largest tracking error %.3f m, back at the start "
      "to %.3f m, %d NMPC fallbacks\n",
      reach.x(), reach.y(), max_error, final_error, fallbacks);
  const bool ok = controller.phase() == formation::FlightPhase::kNmpc && max_error < 0.3 &&
                  reach.minCoeff() > 0.95 && final_error < 0.05 && fallbacks == 0;
  std::printf("%s\n", ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}
