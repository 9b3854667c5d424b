// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/world.hpp"

#include <mujoco/mujoco.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <random>
#include <sstream>
#include <stdexcept>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/sim/cell_list.hpp"
#include "fnmpc/sim/free_joint_force.hpp"
#include "fnmpc/sim/mjcf_model.hpp"

namespace fnmpc::sim {

namespace {

constexpr double kRpmToRadPerSec = 2.0 * M_PI / 60.0;
constexpr double kTimeEps = 1e-9;  // [s] tolerance of the sample schedules
// Landing gear geometry, body frame [m]: feet spheres under the arms.
constexpr double kFootRadius = 0.01;
constexpr double kFootZ = -(World::kRestHeight - kFootRadius);
constexpr double kHubHalfSize = 0.06;
constexpr double kHubHalfHeight = 0.03;

/// Shortest text that reads back to exactly v.
std::string Num(double v) {
  std::array<char, 32> buf{};
  const auto res = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), res.ptr);
}

void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

void CheckSpec(const SensorSpec& s, const std::string& who, std::string_view name) {
  const std::string ctx = "[World] " + who + " sensor '" + std::string(name) + "': ";
  if (!s.enabled) return;
  Require(s.rate_hz > 0.0 && std::isfinite(s.rate_hz),
          ctx + "rate_hz must be > 0, got " + std::to_string(s.rate_hz));
  Require(s.latency_s >= 0.0 && std::isfinite(s.latency_s),
          ctx + "latency_s must be >= 0, got " + std::to_string(s.latency_s));
  Require(
      s.dropout_probability >= 0.0 && s.dropout_probability < 1.0,
      ctx + "dropout_probability must be in [0, 1), got " + std::to_string(s.dropout_probability));
  Require(s.noise.allFinite() && (s.noise.array() >= 0.0).all() && s.noise2.allFinite() &&
              (s.noise2.array() >= 0.0).all(),
          ctx + "noise standard deviations must be finite and >= 0");
  Require(s.range_noise_growth >= 0.0,
          ctx + "range_noise_growth must be >= 0, got " + std::to_string(s.range_noise_growth));
  Require(s.max_range > 0.0, ctx + "max_range must be > 0, got " + std::to_string(s.max_range));
  Require(s.field_of_view > 0.0,
          ctx + "field_of_view must be > 0, got " + std::to_string(s.field_of_view));
}

const SensorSpec& SpecOf(const SensorsConfig& c, int kind) {
  switch (static_cast<SensorKind>(kind)) {
    case SensorKind::kMocapPose:
      return c.mocap;
    case SensorKind::kImu:
      return c.imu;
    case SensorKind::kOpticalFlow:
      return c.optical_flow;
    case SensorKind::kCompass:
      return c.compass;
    case SensorKind::kBattery:
      return c.battery;
    case SensorKind::kRelative:
      break;
  }
  return c.relative;
}

Vec3 EulerOf(const Mat3& r) { return EulerZyx(r); }

/// Thrust of one rotor [N] at steady state for a throttle, by Newton warm-started at
/// *guess with the robust bracketing inverse as fallback. Below the idle throttle
/// (the polynomial's value at zero thrust) the rotor does not turn.
double ThrustForThrottle(const model::ThrottlePolynomial& p, double throttle, double voltage,
                         double* guess) {
  if (throttle <= 0.0 || throttle <= p.Throttle(0.0, voltage)) return 0.0;
  double f = *guess;
  if (f > 0.0) {
    for (int it = 0; it < 6; ++it) {
      const double r = p.Throttle(f, voltage) - throttle;
      if (std::abs(r) < 1e-13) {
        *guess = f;
        return f;
      }
      const double d = p.DThrottleDThrust(f, voltage);
      if (!(d > 0.0)) break;
      f -= r / d;
      if (!(f > 0.0)) break;
    }
  }
  f = p.Thrust(throttle, voltage);
  if (!std::isfinite(f)) f = p.Thrust(throttle, voltage, 200.0);
  if (!std::isfinite(f)) f = 0.0;
  *guess = f;
  return f;
}

struct Queued {
  Measurement m;
  std::uint64_t seq = 0;
};
/// Heap order: the smallest arrival (then stamp, then sequence) on top.
bool Later(const Queued& a, const Queued& b) {
  if (a.m.arrival != b.m.arrival) return a.m.arrival > b.m.arrival;
  if (a.m.stamp != b.m.stamp) return a.m.stamp > b.m.stamp;
  return a.seq > b.seq;
}

}  // namespace

Vec3 DiscreteGustVelocity(const std::vector<DiscreteGust>& gusts, double t) {
  Vec3 v = Vec3::Zero();
  for (const DiscreteGust& g : gusts) {
    const double x = (t - g.start) / g.duration;
    if (x < 0.0 || x > 1.0) continue;
    v += 0.5 * (1.0 - std::cos(2.0 * M_PI * x)) * g.amplitude;
  }
  return v;
}

void ValidateSensors(const SensorsConfig& s, const std::string& who) {
  CheckSpec(s.mocap, who, "mocap");
  CheckSpec(s.imu, who, "imu");
  CheckSpec(s.optical_flow, who, "optical_flow");
  CheckSpec(s.compass, who, "compass");
  CheckSpec(s.battery, who, "battery");
  CheckSpec(s.relative, who, "relative");
}

void SensorRealitySettings::Validate() const {
  for (double x : {accel_bias, gyro_bias, accel_bias_walk, gyro_bias_walk, latency_jitter,
                   mocap_outlier_size}) {
    Require(x >= 0.0 && std::isfinite(x),
            "[World] sensor_reality: biases, walks, jitter and outlier size must be >= 0");
  }
  Require(burst_share >= 0.0 && burst_share < 0.5,
          "[World] sensor_reality.burst_share must be in [0, 0.5)");
  Require(burst_length > 0.0 && std::isfinite(burst_length),
          "[World] sensor_reality.burst_length must be > 0");
  Require(mocap_outlier_rate >= 0.0 && mocap_outlier_rate <= 1.0,
          "[World] sensor_reality.mocap_outlier_rate must be in [0, 1]");
  Require(estimate_time_constant > 0.0 && std::isfinite(estimate_time_constant),
          "[World] sensor_reality.estimate_time_constant must be > 0");
}

void WorldConfig::Validate() const {
  Require(!vehicles.empty(), "[World] at least one vehicle is required");
  Require(physics_dt > 0.0 && physics_dt <= 0.01,
          "[World] physics_dt must be in (0, 0.01] s, got " + std::to_string(physics_dt));
  Require(autopilot_rate_hz > 0.0 && std::isfinite(autopilot_rate_hz),
          "[World] autopilot_rate_hz must be > 0, got " + std::to_string(autopilot_rate_hz));
  Require(motor_time_constant > 0.0,
          "[World] motor_time_constant must be > 0, got " + std::to_string(motor_time_constant));
  Require(gravity >= 0.0 && std::isfinite(gravity),
          "[World] gravity must be >= 0, got " + std::to_string(gravity));
  Require(drag_coefficient.allFinite() && (drag_coefficient.array() >= 0.0).all(),
          "[World] drag_coefficient must be >= 0");
  Require(relative_index_min_vehicles >= 0,
          "[World] relative_index_min_vehicles must be >= 0, got " +
              std::to_string(relative_index_min_vehicles));
  Require(contacts_per_vehicle >= 1 && contacts_per_vehicle <= 1000,
          "[World] contacts_per_vehicle must be in [1, 1000], got " +
              std::to_string(contacts_per_vehicle));
  const BatterySettings& b = battery;
  Require(b.full_voltage > b.empty_voltage && b.empty_voltage > 0.0,
          "[World] battery needs full_voltage > empty_voltage > 0, got " +
              std::to_string(b.full_voltage) + " and " + std::to_string(b.empty_voltage));
  Require(b.capacity_ah > 0.0,
          "[World] battery capacity_ah must be > 0, got " + std::to_string(b.capacity_ah));
  Require(b.internal_resistance >= 0.0, "[World] battery internal_resistance must be >= 0, got " +
                                            std::to_string(b.internal_resistance));
  Require(b.efficiency > 0.0 && b.efficiency <= 1.0,
          "[World] battery efficiency must be in (0, 1], got " + std::to_string(b.efficiency));
  Require(b.initial_soc > 0.0 && b.initial_soc <= 1.0,
          "[World] battery initial_soc must be in (0, 1], got " + std::to_string(b.initial_soc));
  downwash.Validate();
  if (sensor_reality.enabled) sensor_reality.Validate();
  if (reality.wake) reality.wake_turbulence.Validate();
  Require(reality.rotor_drag >= 0.0 && std::isfinite(reality.rotor_drag),
          "[World] reality.rotor_drag must be >= 0");
  Require(reality.blade.radius > 0.0 && reality.blade.solidity > 0.0 &&
              reality.blade.lift_slope > 0.0 && reality.blade.air_density > 0.0,
          "[World] reality.blade needs radius, solidity, lift_slope and air_density > 0");
  Require(wind.velocity.allFinite(), "[World] wind velocity must be finite");
  Require(wind.gust_std >= 0.0,
          "[World] wind gust_std must be >= 0, got " + std::to_string(wind.gust_std));
  Require(wind.gust_time_constant > 0.0, "[World] wind gust_time_constant must be > 0, got " +
                                             std::to_string(wind.gust_time_constant));
  if (wind.turbulence) wind.dryden.Validate();
  for (const DiscreteGust& g : wind.discrete_gusts) {
    Require(std::isfinite(g.start) && g.duration > 0.0 && std::isfinite(g.duration) &&
                g.amplitude.allFinite(),
            "[World] discrete gust needs a finite start, duration > 0 and a finite amplitude");
  }
  {
    const CommandTimeoutSettings& c = command_timeout;
    Require(c.timeout > 0.0 && std::isfinite(c.timeout),
            "[World] command_timeout.timeout must be > 0, got " + std::to_string(c.timeout));
    Require(c.descent_speed > 0.0 && std::isfinite(c.descent_speed),
            "[World] command_timeout.descent_speed must be > 0, got " +
                std::to_string(c.descent_speed));
    Require(c.velocity_gain > 0.0 && std::isfinite(c.velocity_gain),
            "[World] command_timeout.velocity_gain must be > 0, got " +
                std::to_string(c.velocity_gain));
    Require(c.land_speed > 0.0 && std::isfinite(c.land_speed),
            "[World] command_timeout.land_speed must be > 0, got " + std::to_string(c.land_speed));
    Require(c.land_detect_time >= 0.0 && std::isfinite(c.land_detect_time),
            "[World] command_timeout.land_detect_time must be >= 0, got " +
                std::to_string(c.land_detect_time));
  }
  for (std::size_t i = 0; i < vehicles.size(); ++i) {
    const std::string who = "vehicle " + std::to_string(i);
    const VehicleSpec& v = vehicles[i];
    try {
      v.params.Validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("[World] " + who + ": " + e.what());
    }
    Require(v.position.allFinite() && std::isfinite(v.yaw),
            "[World] " + who + ": initial position and yaw must be finite");
    Require(!ground || v.position.z() >= World::kRestHeight - 1e-3,
            "[World] " + who + ": initial z must be >= World::kRestHeight (" +
                Num(World::kRestHeight) + " m, resting on the ground), got " + Num(v.position.z()));
    Require(std::isnan(v.motor_time_constant) ||
                (v.motor_time_constant > 0.0 && std::isfinite(v.motor_time_constant)),
            "[World] " + who + ": motor_time_constant must be NaN or > 0, got " +
                std::to_string(v.motor_time_constant));
    Require(
        std::isnan(v.initial_throttle) || (v.initial_throttle >= 0.0 && v.initial_throttle <= 1.0),
        "[World] " + who + ": initial_throttle must be NaN or in [0, 1], got " +
            std::to_string(v.initial_throttle));
    ValidateSensors(v.sensors, who);
  }
}

std::string World::BuildMjcf(const WorldConfig& c) {
  std::ostringstream x;
  x << "<mujoco model=\"fnmpc_world\">\n"
    << "  <compiler autolimits=\"true\" angle=\"radian\"/>\n"
    << "  <option timestep=\"" << Num(c.physics_dt) << "\" gravity=\"0 0 " << Num(-c.gravity)
    << "\" integrator=\"Euler\"/>\n"
    // MuJoCo 2.2's default contact buffer (100) holds 25 vehicles on their four feet: the rest
    // fell through the ground. Room for feet and hub of every vehicle, vehicle-vehicle
    // contacts besides; pyramidal friction cones use 4 constraint rows per contact (condim 3).
    << "  <size nconmax=\"" << c.contacts_per_vehicle * (c.vehicles.size() + 4) << "\" njmax=\""
    << 4 * c.contacts_per_vehicle * (c.vehicles.size() + 4) << "\"/>\n"
    << "  <default><geom friction=\"1 0.005 0.0001\" rgba=\"0.6 0.6 0.6 1\"/></default>\n"
    << "  <worldbody>\n";
  if (c.ground) {
    x << "    <geom name=\"ground\" type=\"plane\" size=\"100 100 0.1\"/>\n";
  }
  for (std::size_t i = 0; i < c.vehicles.size(); ++i) {
    const VehicleSpec& v = c.vehicles[i];
    const model::VehicleParams& p = v.params;
    const std::string n = "vehicle" + std::to_string(i);
    const double a = p.arm_length / std::sqrt(2.0);
    x << "    <body name=\"" << n << "\" pos=\"" << Num(v.position.x()) << " "
      << Num(v.position.y()) << " " << Num(v.position.z()) << "\" quat=\""
      << Num(std::cos(v.yaw / 2)) << " 0 0 " << Num(std::sin(v.yaw / 2)) << "\">\n"
      << "      <freejoint name=\"" << n << "_free\"/>\n"
      << "      <inertial pos=\"0 0 0\" mass=\"" << Num(p.mass) << "\" diaginertia=\""
      << Num(p.inertia.x()) << " " << Num(p.inertia.y()) << " " << Num(p.inertia.z()) << "\"/>\n"
      << "      <geom name=\"" << n << "_hub\" type=\"box\" size=\"" << kHubHalfSize << " "
      << kHubHalfSize << " " << kHubHalfHeight << "\"/>\n";
    const std::array<std::array<double, 2>, 4> xy{{{a, -a}, {-a, a}, {a, a}, {-a, -a}}};
    for (int r = 0; r < 4; ++r) {
      const std::string px = Num(xy[r][0]), py = Num(xy[r][1]);
      x << "      <geom name=\"" << n << "_foot" << r << "\" type=\"sphere\" size=\"" << kFootRadius
        << "\" pos=\"" << px << " " << py << " " << Num(kFootZ) << "\"/>\n";
      if (!c.visual_geometry) continue;
      x << "      <geom name=\"" << n << "_arm" << r
        << "\" type=\"capsule\" contype=\"0\" conaffinity=\"0\" size=\"0.01\" fromto=\"0 0 0 " << px
        << " " << py << " 0\"/>\n"
        << "      <geom name=\"" << n << "_rotor" << r
        << "\" type=\"cylinder\" contype=\"0\" conaffinity=\"0\" size=\"0.127 0.003\" pos=\"" << px
        << " " << py << " 0.03\" rgba=\"" << (r < 2 ? "0.2 0.4 0.9" : "0.9 0.3 0.2") << " 0.4\"/>\n"
        << "      <site name=\"" << n << "_rotor" << r << "\" pos=\"" << px << " " << py
        << " 0.03\"/>\n";
    }
    x << "    </body>\n";
  }
  x << "  </worldbody>\n</mujoco>\n";
  return x.str();
}

/// Per-vehicle simulation state (workspace).
struct Vehicle {
  model::VehicleParams params;
  SensorsConfig sensors;
  int body = -1, qpos = -1, qvel = -1;
  std::array<Vec3, 4> rotor_b;   // rotor centres, body frame [m]
  std::array<double, 4> spin{};  // +1 CCW, -1 CW (seen from above)
  Eigen::Matrix4d mix_inv;       // [T, tau_x, tau_y, tau_z] -> rotor thrusts
  double motor_alpha = 0.0;      // exact discretisation of the motor lag over one step
  double hover_rpm = 1.0;        // rotor speed of hover, m g = 4 T_k rpm^2 [rpm]
  bool direct = false;
  AttitudeCommand command;
  Vec4 throttle = Vec4::Zero();
  Vec4 rpm = Vec4::Zero();
  Vec4 rpm_target = Vec4::Zero();
  Vec4 thrust_guess = Vec4::Constant(3.0);
  double fmax_guess = 10.0;
  double collective_guess = 3.0;  // warm start of the collective-throttle inverse [N]
  double voltage = 0.0, soc = 1.0, current = 0.0;
  Vec3 v_prev = Vec3::Zero();
  Vec3 p_prev = Vec3::Zero();  // position before the last physics step (instability report)
  Vec3 accel = Vec3::Zero();
  Vec3 aero_force = Vec3::Zero(), aero_torque = Vec3::Zero();
  // This step's total wrench at the centre of mass, world frame (propulsion + aerodynamics).
  Vec3 force_w = Vec3::Zero(), torque_w = Vec3::Zero();
  Vec3 com_b = Vec3::Zero();  // centre of mass from the body origin, body frame (body_ipos)
  AutopilotStatus status;
  double failsafe_yaw = 0.0;  // yaw held by the command-timeout failsafe [rad]
  double land_timer = 0.0;    // land detector: time with the conditions met [s]
  std::array<std::int64_t, kNumSensorKinds> sample_index{};
  // Sensor reality (SensorRealitySettings): biases, burst state, own stream, attitude estimate.
  Vec3 accel_bias = Vec3::Zero(), gyro_bias = Vec3::Zero();
  std::array<bool, kNumSensorKinds> in_burst{};
  std::mt19937_64 reality_rng;
  std::normal_distribution<double> reality_normal{0.0, 1.0};
  std::uniform_real_distribution<double> reality_uniform{0.0, 1.0};
  Mat3 attitude_estimate = Mat3::Identity();
  Vec3 autopilot_gyro = Vec3::Zero();  // the autopilot's own gyro reading [rad/s]
  std::mt19937_64 rng;
  std::normal_distribution<double> normal{0.0, 1.0};
  std::uniform_real_distribution<double> uniform{0.0, 1.0};
};

struct World::Impl {
  WorldConfig config;
  std::string xml;
  mjModel* m = nullptr;
  mjData* d = nullptr;
  std::vector<Vehicle> vehicles;
  std::int64_t step = 0;
  std::int64_t autopilot_index = 0;
  Vec3 gust = Vec3::Zero();
  std::unique_ptr<DrydenTurbulence> turbulence;  // wind.turbulence only
  Mat3 wind_frame = Mat3::Identity();            // (u, v, w) of the turbulence -> world
  std::mt19937_64 gust_rng;
  std::normal_distribution<double> gust_normal{0.0, 1.0};
  std::vector<Queued> queue;  // binary heap, see Later()
  std::uint64_t seq = 0;
  // Per-step scratch, sized at construction.
  std::vector<Mat3> rot;
  std::vector<double> total_thrust;
  std::vector<WakeHistory> wakes;            // reality.wake: one per vehicle
  std::vector<WakeFluctuation> fluctuation;  // reality.wake: [source * n + observer]
  // Relative sensing through a cell list (config.relative_index_min_vehicles): the grid of
  // the positions at step `cells_step`, its cell side (0: every pair is tested) and scratch.
  CellList cells;
  std::int64_t cells_step = -1;
  double cell_side = 0.0;
  std::vector<Vec3> cell_positions;
  std::vector<int> near;

  ~Impl() {
    if (d != nullptr) mj_deleteData(d);
    if (m != nullptr) mj_deleteModel(m);
  }

  [[nodiscard]] double Time() const { return static_cast<double>(step) * config.physics_dt; }

  [[nodiscard]] Mat3 Rotation(const Vehicle& v) const {
    const double* q = d->qpos + v.qpos + 3;
    return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  }
  [[nodiscard]] Vec3 Position(const Vehicle& v) const {
    return Eigen::Map<const Vec3>(d->qpos + v.qpos);
  }
  [[nodiscard]] Vec3 Velocity(const Vehicle& v) const {
    return Eigen::Map<const Vec3>(d->qvel + v.qvel);
  }
  [[nodiscard]] Vec3 Rates(const Vehicle& v) const {
    return Eigen::Map<const Vec3>(d->qvel + v.qvel + 3);
  }

  void Load() {
    m = CompileMjcf(xml, "[World]");
    d = mj_makeData(m);
    if (d == nullptr) throw std::runtime_error("[World] mj_makeData failed");
  }

  /// Command-timeout failsafe (CommandTimeoutSettings): engages on a stale command stream
  /// of an armed vehicle, then replaces the command by level attitude and a vertical-speed
  /// loop to the descent speed; the land detector disarms.
  void CommandTimeout(Vehicle& v) {
    const CommandTimeoutSettings& c = config.command_timeout;
    AutopilotStatus& st = v.status;
    const double t = Time();
    if (!c.enabled || v.direct || st.motors_killed || st.disarmed_by_failsafe) return;
    if (!st.failsafe) {
      if (!st.armed || !std::isfinite(st.last_command_time) ||
          t - st.last_command_time <= c.timeout + kTimeEps) {
        return;
      }
      st.failsafe = true;
      st.failsafe_time = t;
      v.failsafe_yaw = EulerOf(Rotation(v)).z();
      v.land_timer = 0.0;
    }
    const Mat3 r = Rotation(v);
    const double vz = Velocity(v).z();
    const double accel = c.velocity_gain * (-c.descent_speed - vz);  // about hover [m/s^2]
    const double tilt = std::max(0.5, r(2, 2));                      // cos roll cos pitch
    AttitudeCommand cmd;
    cmd.thrust = std::max(0.0, v.params.mass * (config.gravity + accel) / tilt);
    cmd.yaw = v.failsafe_yaw;
    if (std::abs(vz) < c.land_speed && accel < 0.0) {
      v.land_timer += 1.0 / config.autopilot_rate_hz;
    } else {
      v.land_timer = 0.0;
    }
    if (v.land_timer >= c.land_detect_time - kTimeEps) {
      st.disarmed_by_failsafe = true;
      st.disarm_time = t;
      cmd.thrust = 0.0;
    }
    v.command = cmd;
  }

  void Autopilot(Vehicle& v) {
    const model::VehicleParams& p = v.params;
    const double volt = v.voltage;
    Vec4 f_ss;
    if (v.status.motors_killed) {
      v.throttle.setZero();
      v.rpm_target.setZero();
      return;
    }
    CommandTimeout(v);
    // Collective thrust [N]: from the throttle command through the polynomial at the
    // present voltage when it is set, else the thrust command.
    double commanded = v.command.thrust;
    if (!std::isnan(v.command.throttle)) {
      const double thr = std::clamp(v.command.throttle, 0.0, 1.0);
      commanded = 4.0 * ThrustForThrottle(p.throttle, thr, volt, &v.collective_guess);
    }
    v.status.armed = v.direct || commanded > 0.0;
    if (!v.direct && !(commanded > 0.0)) {
      // Zero thrust command: the autopilot idles the motors (as a disarmed vehicle).
      v.throttle.setZero();
      f_ss.setZero();
    } else if (v.direct) {
      for (int r = 0; r < 4; ++r) {
        f_ss[r] = ThrustForThrottle(p.throttle, v.throttle[r], volt, &v.thrust_guess[r]);
      }
    } else {
      const bool own = config.sensor_reality.enabled && config.sensor_reality.autopilot_estimate;
      const Mat3 rot_wb = own ? v.attitude_estimate : Rotation(v);
      const Vec3 eul = EulerOf(rot_wb);
      const Vec3 w = own ? v.autopilot_gyro : Rates(v);
      const AttitudeCommand& c = v.command;
      const Vec3 k = p.attitude_gain;
      Vec3 e(k.x() * (c.roll + p.bias.roll) - eul.x(), k.y() * (c.pitch + p.bias.pitch) - eul.y(),
             WrapAngle(k.z() * c.yaw - eul.z()));
      const Vec3 torque =
          p.inertia.cwiseProduct(p.attitude_kp.cwiseProduct(e) - p.attitude_kd.cwiseProduct(w));
      const double thrust = std::max(0.0, p.bias.thrust_scale * commanded);
      const Vec4 f_base = v.mix_inv * Vec4(thrust, torque.x(), torque.y(), 0.0);
      const Vec4 f_yaw = v.mix_inv.col(3) * torque.z();
      double fmax = ThrustForThrottle(p.throttle, 1.0, volt, &v.fmax_guess);
      if (!(fmax > 0.0)) fmax = kInf;
      // Roll, pitch and thrust first: shrink the yaw part until every rotor fits.
      double alpha = 1.0;
      for (int r = 0; r < 4; ++r) {
        const double val = f_base[r] + f_yaw[r];
        if (f_yaw[r] < 0.0 && val < 0.0)
          alpha = std::min(alpha, std::max(0.0, -f_base[r] / f_yaw[r]));
        if (f_yaw[r] > 0.0 && val > fmax) {
          alpha = std::min(alpha, std::max(0.0, (fmax - f_base[r]) / f_yaw[r]));
        }
      }
      for (int r = 0; r < 4; ++r) {
        const double f = std::clamp(f_base[r] + alpha * f_yaw[r], 0.0, fmax);
        double thr = f > 0.0 ? p.throttle.Throttle(f, volt) : 0.0;
        if (thr >= 0.0 && thr <= 1.0) {
          f_ss[r] = f;
        } else {
          thr = std::clamp(thr, 0.0, 1.0);
          f_ss[r] = ThrustForThrottle(p.throttle, thr, volt, &v.thrust_guess[r]);
        }
        v.throttle[r] = thr;
      }
    }
    for (int r = 0; r < 4; ++r)
      v.rpm_target[r] = std::sqrt(std::max(0.0, f_ss[r]) / p.thrust_constant);
  }

  /// Once per autopilot tick: bias random walks, and the autopilot's own attitude estimate
  /// (gyro with bias and noise integrated, corrected toward a noisy external attitude).
  void UpdateSensorReality(Vehicle& v) {
    const SensorRealitySettings& sr = config.sensor_reality;
    const double dt = 1.0 / config.autopilot_rate_hz;
    auto gauss3 = [&v]() {
      return Vec3(v.reality_normal(v.reality_rng), v.reality_normal(v.reality_rng),
                  v.reality_normal(v.reality_rng));
    };
    v.accel_bias += sr.accel_bias_walk * std::sqrt(dt) * gauss3();
    v.gyro_bias += sr.gyro_bias_walk * std::sqrt(dt) * gauss3();
    if (!sr.autopilot_estimate) return;
    const Vec3 gyro_noise = v.sensors.imu.enabled ? v.sensors.imu.noise2 : Vec3::Zero();
    v.autopilot_gyro = Rates(v) + v.gyro_bias + gyro_noise.cwiseProduct(gauss3());
    // External attitude (mocap-like noise), error in the body frame of the estimate.
    const Vec3 att_noise = v.sensors.mocap.enabled ? v.sensors.mocap.noise2 : Vec3::Zero();
    const Vec3 e_true = EulerOf(Rotation(v)) + att_noise.cwiseProduct(gauss3());
    const Mat3 r_meas = RotationZyx(e_true.x(), e_true.y(), e_true.z());
    const Mat3 m = v.attitude_estimate.transpose() * r_meas;
    const Vec3 err(0.5 * (m(2, 1) - m(1, 2)), 0.5 * (m(0, 2) - m(2, 0)), 0.5 * (m(1, 0) - m(0, 1)));
    const Vec3 omega = v.autopilot_gyro + err / sr.estimate_time_constant;
    const double angle = omega.norm() * dt;
    if (angle > 0.0) {
      v.attitude_estimate =
          v.attitude_estimate * Eigen::AngleAxisd(angle, omega.normalized()).toRotationMatrix();
    }
    // Re-orthonormalise.
    v.attitude_estimate = Eigen::Quaterniond(v.attitude_estimate).normalized().toRotationMatrix();
  }

  // Candidates for the relative sensor of an observer at p within `range` [m] into `near`
  // (true), from the cell list of this step's positions, built on first use; false: test
  // every vehicle (too few vehicles, no finite range, or a non-finite position).
  bool NearVehicles(const Vec3& p, double range) {
    const int n = static_cast<int>(vehicles.size());
    if (!(cell_side > 0.0) || n < config.relative_index_min_vehicles || !(range <= cell_side)) {
      return false;
    }
    if (cells_step != step) {
      cell_positions.resize(static_cast<std::size_t>(n));
      bool finite = true;
      for (int j = 0; j < n; ++j) {
        cell_positions[j] = Position(vehicles[j]);
        finite = finite && cell_positions[j].allFinite();
      }
      if (!finite) return false;
      cells.Build(cell_positions, cell_side);
      cells_step = step;
    }
    if (!p.allFinite()) return false;
    // The body-frame range equals the world distance up to rounding: a small margin.
    cells.Near(p, range * (1.0 + 1e-9) + 1e-9, &near);
    return true;
  }

  void Push(const Measurement& meas) {
    queue.push_back({meas, seq++});
    std::push_heap(queue.begin(), queue.end(), Later);
  }

  void Sample(int vi, double t) {
    Vehicle& v = vehicles[vi];
    for (int kind = 0; kind < kNumSensorKinds; ++kind) {
      const SensorSpec& s = SpecOf(v.sensors, kind);
      if (!s.enabled) continue;
      std::int64_t& idx = v.sample_index[kind];
      if (t + kTimeEps < static_cast<double>(idx) / s.rate_hz) continue;
      // The next sample index after t in O(1) whatever the rate (a rate above the physics
      // rate samples once per step); the loop only corrects the rounding of the product.
      idx =
          std::max(idx + 1, static_cast<std::int64_t>(std::floor((t + kTimeEps) * s.rate_hz)) + 1);
      while (static_cast<double>(idx) / s.rate_hz <= t + kTimeEps) ++idx;
      const Mat3 rot_wb = rot[vi];
      Measurement meas;
      meas.kind = static_cast<SensorKind>(kind);
      meas.vehicle = vi;
      meas.stamp = t;
      meas.arrival = t + s.latency_s;
      const SensorRealitySettings& sr = config.sensor_reality;
      if (sr.enabled) {
        meas.arrival += sr.latency_jitter * v.reality_uniform(v.reality_rng);
        // Bursts hit the radio-linked streams only (motion capture and the relative sensor's
        // link); the IMU, flow, compass and battery are wired on board.
        // Gilbert-Elliott: p(enter) = share / length, p(leave) = 1 / length (per sample).
        const bool radio =
            meas.kind == SensorKind::kMocapPose || meas.kind == SensorKind::kRelative;
        const double samples = std::max(1.0, sr.burst_length * s.rate_hz);
        const double leave = 1.0 / samples;
        const double enter = sr.burst_share / (1.0 - sr.burst_share) * leave;
        bool& burst = v.in_burst[kind];
        if (radio) {
          const double u = v.reality_uniform(v.reality_rng);
          burst = burst ? u >= leave : u < enter;
        }
        if (burst) continue;
      }
      auto noise3 = [&](const Vec3& sd) {
        return Vec3(sd.x() * v.normal(v.rng), sd.y() * v.normal(v.rng), sd.z() * v.normal(v.rng));
      };
      if (meas.kind == SensorKind::kRelative) {
        const Vec3 p_obs = Position(v);
        const double yaw_obs = EulerOf(rot_wb).z();
        // Every vehicle in ascending index order, or the cell list's candidates (ascending, a
        // superset of those within max_range): the same draws in the same order.
        const bool indexed = NearVehicles(p_obs, s.max_range);
        const int count =
            indexed ? static_cast<int>(near.size()) : static_cast<int>(vehicles.size());
        for (int k = 0; k < count; ++k) {
          const int j = indexed ? near[static_cast<std::size_t>(k)] : k;
          if (j == vi) continue;
          const Vec3 d_b = rot_wb.transpose() * (Position(vehicles[j]) - p_obs);
          const double range = d_b.norm();
          if (range > s.max_range || range <= 0.0) continue;
          if (s.field_of_view < 2.0 * M_PI &&
              std::acos(std::clamp(d_b.x() / range, -1.0, 1.0)) > 0.5 * s.field_of_view) {
            continue;
          }
          if (v.uniform(v.rng) < s.dropout_probability) continue;
          RelativeObservation& o = meas.relative;
          o.target = j;
          o.range = range + s.noise.x() * (1.0 + s.range_noise_growth * range) * v.normal(v.rng);
          o.bearing = WrapAngle(std::atan2(d_b.y(), d_b.x()) + s.noise.y() * v.normal(v.rng));
          o.elevation = std::clamp(std::asin(d_b.z() / range) + s.noise.z() * v.normal(v.rng),
                                   -M_PI / 2, M_PI / 2);
          o.relative_yaw =
              WrapAngle(EulerOf(rot[j]).z() - yaw_obs + s.noise2.x() * v.normal(v.rng));
          Push(meas);
        }
        continue;
      }
      if (v.uniform(v.rng) < s.dropout_probability) continue;
      switch (meas.kind) {
        case SensorKind::kMocapPose: {
          meas.position = Position(v) + noise3(s.noise);
          if (sr.enabled && v.reality_uniform(v.reality_rng) < sr.mocap_outlier_rate) {
            const Vec3 u(v.reality_normal(v.reality_rng), v.reality_normal(v.reality_rng),
                         v.reality_normal(v.reality_rng));
            meas.position += sr.mocap_outlier_size * u.normalized();
          }
          Vec3 e = EulerOf(rot_wb) + noise3(s.noise2);
          e.z() = WrapAngle(e.z());
          meas.euler = e;
          break;
        }
        case SensorKind::kImu: {
          const Vec3 g(0.0, 0.0, -config.gravity);
          meas.accel = rot_wb.transpose() * (v.accel - g) + noise3(s.noise);
          meas.gyro = Rates(v) + noise3(s.noise2);
          if (sr.enabled) {
            meas.accel += v.accel_bias;
            meas.gyro += v.gyro_bias;
          }
          break;
        }
        case SensorKind::kOpticalFlow:
          meas.velocity = Velocity(v) + noise3(s.noise);
          break;
        case SensorKind::kCompass:
          meas.yaw = WrapAngle(EulerOf(rot_wb).z() + s.noise.x() * v.normal(v.rng));
          break;
        case SensorKind::kBattery:
          meas.voltage = v.voltage + s.noise.x() * v.normal(v.rng);
          break;
        case SensorKind::kRelative:
          break;
      }
      Push(meas);
    }
  }

  void UpdateBattery(Vehicle& v) {
    const BatterySettings& b = config.battery;
    double power = 0.0;
    for (int r = 0; r < 4; ++r) {
      power += v.params.torque_constant * v.rpm[r] * v.rpm[r] * v.rpm[r] * kRpmToRadPerSec;
    }
    v.current = power / (b.efficiency * std::max(v.voltage, 1e-3));
    if (b.fixed_voltage) {
      v.voltage = b.full_voltage;
      return;
    }
    v.soc = std::max(0.0, v.soc - v.current * config.physics_dt / (3600.0 * b.capacity_ah));
    v.voltage = b.empty_voltage + (b.full_voltage - b.empty_voltage) * v.soc -
                b.internal_resistance * v.current;
    v.voltage = std::max(v.voltage, 0.1 * b.empty_voltage);
  }

  /// Air velocity [m/s] of the other vehicles' wakes at `point` as seen by vehicle i: the
  /// steady jets, or with reality.wake the advected mean plus the fluctuation.
  Vec3 WakeAir(int i, const Vec3& point) const {
    const DownwashSettings& dw = config.downwash;
    const int n = static_cast<int>(vehicles.size());
    Vec3 air = Vec3::Zero();
    for (int j = 0; j < n; ++j) {
      if (j == i) continue;
      if (!config.reality.wake) {
        air += DownwashVelocity(dw, Position(vehicles[j]), rot[j].col(2), total_thrust[j], point);
        continue;
      }
      double uc = 0.0, hw = 0.0, r = 0.0;
      Vec3 axis;
      air += wakes[j].MeanVelocity(Time(), point, &uc, &hw, &axis, &r);
      air += fluctuation[j * n + i].Velocity(axis, uc, hw, r);
    }
    return air;
  }

  void ApplyAero() {
    if (config.reality.rotor_aerodynamics || config.reality.wake) {
      ApplyRealAero();
      return;
    }
    const DownwashSettings& dw = config.downwash;
    const WindSettings& wind = config.wind;
    const Vec3 c_rotor = 0.25 * config.drag_coefficient;  // drag split over the 4 rotor points
    const int n = static_cast<int>(vehicles.size());
    Vec3 wind_air = wind.velocity + gust;
    if (turbulence) wind_air += wind_frame * turbulence->value();
    if (!wind.discrete_gusts.empty()) wind_air += DiscreteGustVelocity(wind.discrete_gusts, Time());
    for (int i = 0; i < n; ++i) {
      Vehicle& v = vehicles[i];
      v.aero_force.setZero();
      v.aero_torque.setZero();
      const Vec3 pos = Position(v);
      const Vec3 vel = Velocity(v);
      for (int r = 0; r < 4; ++r) {
        const Vec3 arm_w = rot[i] * v.rotor_b[r];
        const Vec3 point = pos + arm_w;
        Vec3 air = Vec3::Zero();
        if (wind.enabled) air += wind_air;
        if (dw.enabled) {
          for (int j = 0; j < n; ++j) {
            if (j == i) continue;
            air +=
                DownwashVelocity(dw, Position(vehicles[j]), rot[j].col(2), total_thrust[j], point);
          }
        }
        const Vec3 f = QuadraticDrag(rot[i], c_rotor, air - vel);
        v.aero_force += f;
        v.aero_torque += arm_w.cross(f);
      }
    }
  }

  /// MuJoCo's instability warnings (mj_checkPos / mj_checkVel / mj_checkAcc: a NaN, Inf or
  /// value above mjOption::max... in qpos, qvel or qacc). MuJoCo answers them by resetting the
  /// data to the initial state and goes on, which would teleport every vehicle back to its
  /// start; the counters are never cleared here, so any count means an instability. A full
  /// contact or constraint buffer (WorldConfig::contacts_per_vehicle) is reported first.
  void CheckStability(double t) const {
    const int full_contacts = d->warning[mjWARN_CONTACTFULL].number;
    const int full_rows = d->warning[mjWARN_CNSTRFULL].number;
    if (full_contacts > 0 || full_rows > 0) {
      std::ostringstream os;
      os << std::setprecision(6) << "[World] MuJoCo's "
         << (full_contacts > 0 ? "contact" : "constraint") << " buffer is full at t = " << t
         << " s (room for " << m->nconmax << " contacts and " << m->njmax
         << " constraint rows: WorldConfig::contacts_per_vehicle = " << config.contacts_per_vehicle
         << " for " << vehicles.size() << " vehicles); the contacts beyond it would be dropped";
      throw SimulationError(os.str());
    }
    int count = 0;
    for (const int w : {mjWARN_BADQPOS, mjWARN_BADQVEL, mjWARN_BADQACC}) {
      count += d->warning[w].number;
    }
    if (count == 0) return;
    std::ostringstream os;
    os << std::setprecision(6) << "[World] MuJoCo instability at t = " << t
       << " s (warnings: bad qpos " << d->warning[mjWARN_BADQPOS].number << ", bad qvel "
       << d->warning[mjWARN_BADQVEL].number << ", bad qacc " << d->warning[mjWARN_BADQACC].number
       << "); state before the step:";
    for (std::size_t i = 0; i < vehicles.size(); ++i) {
      const Vehicle& v = vehicles[i];
      os << " vehicle " << i << " position (" << v.p_prev.x() << ", " << v.p_prev.y() << ", "
         << v.p_prev.z() << ") m velocity (" << v.v_prev.x() << ", " << v.v_prev.y() << ", "
         << v.v_prev.z() << ") m/s;";
    }
    throw SimulationError(os.str());
  }

  /// ApplyAero with the reality models: per rotor the air of the wind and the wakes, drag on
  /// it, the thrust change of the actual inflow and ground effect, rotor drag.
  void ApplyRealAero() {
    const AeroRealitySettings& re = config.reality;
    const WindSettings& wind = config.wind;
    const Vec3 c_rotor = 0.25 * config.drag_coefficient;
    const int n = static_cast<int>(vehicles.size());
    Vec3 wind_air = Vec3::Zero();
    if (wind.enabled) {
      wind_air = wind.velocity + gust;
      if (turbulence) wind_air += wind_frame * turbulence->value();
      if (!wind.discrete_gusts.empty())
        wind_air += DiscreteGustVelocity(wind.discrete_gusts, Time());
    }
    const double t = Time();
    if (re.wake && config.downwash.enabled) {
      // Fluctuations advance with the scales at the observer's centre of mass.
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          if (i == j) continue;
          double uc = 0.0, hw = 0.0;
          wakes[j].MeanVelocity(t, Position(vehicles[i]), &uc, &hw);
          fluctuation[j * n + i].Step(config.physics_dt, uc, hw);
        }
      }
    }
    for (int i = 0; i < n; ++i) {
      Vehicle& v = vehicles[i];
      v.aero_force.setZero();
      v.aero_torque.setZero();
      const Vec3 pos = Position(v);
      const Vec3 vel = Velocity(v);
      const Vec3 axis = rot[i].col(2);
      for (int r = 0; r < 4; ++r) {
        const Vec3 arm_w = rot[i] * v.rotor_b[r];
        const Vec3 point = pos + arm_w;
        Vec3 air = wind_air;
        if (config.downwash.enabled) air += WakeAir(i, point);
        const Vec3 rel = air - vel;
        Vec3 f = QuadraticDrag(rot[i], c_rotor, rel);
        if (re.rotor_aerodynamics && !v.status.motors_killed) {
          const double still = v.params.thrust_constant * v.rpm[r] * v.rpm[r];
          const double omega = v.rpm[r] * kRpmToRadPerSec;
          double ratio = AxialInflowThrustRatio(re.blade, still, omega, -rel.dot(axis));
          if (config.ground) ratio *= GroundEffectRatio(re.blade.radius, point.z());
          f += (ratio - 1.0) * still * axis;
          f += RotorDrag(re.rotor_drag, v.params.mass, v.rpm[r] / v.hover_rpm, axis, rel);
        }
        v.aero_force += f;
        v.aero_torque += arm_w.cross(f);
      }
    }
  }

  void StepOnce() {
    const double t = Time();
    const double dt = config.physics_dt;
    const int n = static_cast<int>(vehicles.size());
    for (int i = 0; i < n; ++i) rot[i] = Rotation(vehicles[i]);
    // 1. Autopilot ticks on its own schedule.
    if (t + kTimeEps >= static_cast<double>(autopilot_index) / config.autopilot_rate_hz) {
      do {
        ++autopilot_index;
      } while (static_cast<double>(autopilot_index) / config.autopilot_rate_hz <= t + kTimeEps);
      if (config.sensor_reality.enabled) {
        for (auto& v : vehicles) UpdateSensorReality(v);
      }
      for (auto& v : vehicles) Autopilot(v);
    }
    // 2. Sensors sample the state at t.
    for (int i = 0; i < n; ++i) Sample(i, t);
    // 3. Motors, battery, propulsion wrench.
    for (int i = 0; i < n; ++i) {
      Vehicle& v = vehicles[i];
      const model::VehicleParams& p = v.params;
      v.rpm += v.motor_alpha * (v.rpm_target - v.rpm);
      if (v.status.motors_killed) v.rpm.setZero();
      UpdateBattery(v);
      Vec3 torque_b = Vec3::Zero();
      double thrust = 0.0;
      for (int r = 0; r < 4; ++r) {
        const double w2 = v.rpm[r] * v.rpm[r];
        const double f = p.thrust_constant * w2;
        thrust += f;
        torque_b.x() += v.rotor_b[r].y() * f;
        torque_b.y() -= v.rotor_b[r].x() * f;
        torque_b.z() -= v.spin[r] * p.torque_constant * w2;
      }
      total_thrust[i] = thrust;
      if (config.reality.wake) wakes[i].Record(t, Position(v), rot[i].col(2), thrust);
      v.force_w = rot[i].col(2) * thrust;
      v.torque_w = rot[i] * torque_b;
    }
    // 4. Wind, gusts and downwash.
    if (config.wind.enabled && config.wind.gust_std > 0.0) {
      const double phi = std::exp(-dt / config.wind.gust_time_constant);
      const double sd = config.wind.gust_std * std::sqrt(1.0 - phi * phi);
      for (int a = 0; a < 3; ++a) gust[a] = phi * gust[a] + sd * gust_normal(gust_rng);
    }
    if (turbulence) turbulence->Step();
    if (config.wind.enabled || config.downwash.enabled || config.reality.rotor_aerodynamics) {
      ApplyAero();
      for (auto& v : vehicles) {
        v.force_w += v.aero_force;
        v.torque_w += v.aero_torque;
      }
    }
    // Each vehicle's wrench goes straight onto its free joint's dofs: MuJoCo 2.2 would map
    // xfrc_applied through dense 3 x nv Jacobians per body, O(N^2) per step (FreeJointForce).
    for (int i = 0; i < n; ++i) {
      const Vehicle& v = vehicles[i];
      Eigen::Map<Vec<6>>(d->qfrc_applied + v.qvel) =
          FreeJointForce(rot[i], v.com_b, v.force_w, v.torque_w);
    }
    for (auto& v : vehicles) {
      v.v_prev = Velocity(v);
      v.p_prev = Position(v);
    }
    // 5. Physics.
    mj_step(m, d);
    CheckStability(t);
    ++step;
    for (auto& v : vehicles) v.accel = (Velocity(v) - v.v_prev) / dt;
  }
};

World::World(const WorldConfig& config) : impl_(std::make_unique<Impl>()) {
  config.Validate();
  Impl& w = *impl_;
  w.config = config;
  w.xml = BuildMjcf(config);
  w.Load();
  const int n = static_cast<int>(config.vehicles.size());
  w.vehicles.resize(n);
  w.rot.assign(n, Mat3::Identity());
  // Cell side of the relative-sensing grid: the largest range of an enabled relative sensor
  // (0, every pair tested, when one of them is unbounded).
  for (const VehicleSpec& spec : config.vehicles) {
    const SensorSpec& r = spec.sensors.relative;
    if (!r.enabled) continue;
    w.cell_side = std::isfinite(r.max_range) && w.cell_side >= 0.0
                      ? std::max(w.cell_side, r.max_range)
                      : -1.0;
  }
  w.cell_side = std::max(w.cell_side, 0.0);
  w.total_thrust.assign(n, 0.0);
  std::seed_seq gust_seed{static_cast<std::uint32_t>(config.seed),
                          static_cast<std::uint32_t>(config.seed >> 32), 0xFFFFu};
  w.gust_rng.seed(gust_seed);
  if (config.wind.enabled && config.wind.turbulence) {
    w.turbulence =
        std::make_unique<DrydenTurbulence>(config.wind.dryden, config.physics_dt, config.seed);
    const Vec3 horizontal(config.wind.velocity.x(), config.wind.velocity.y(), 0.0);
    if (horizontal.norm() > 0.0) {
      const Vec3 u = horizontal.normalized();
      w.wind_frame.col(0) = u;
      w.wind_frame.col(1) = Vec3::UnitZ().cross(u);
      w.wind_frame.col(2) = Vec3::UnitZ();
    }
  }
  for (int i = 0; i < n; ++i) {
    const VehicleSpec& spec = config.vehicles[i];
    Vehicle& v = w.vehicles[i];
    v.params = spec.params;
    v.sensors = spec.sensors;
    const std::string name = "vehicle" + std::to_string(i);
    v.body = mj_name2id(w.m, mjOBJ_BODY, name.c_str());
    const int joint = mj_name2id(w.m, mjOBJ_JOINT, (name + "_free").c_str());
    if (v.body < 0 || joint < 0) throw std::runtime_error("[World] " + name + " not in the model");
    v.qpos = w.m->jnt_qposadr[joint];
    v.qvel = w.m->jnt_dofadr[joint];
    if (w.m->jnt_type[joint] != mjJNT_FREE) {
      throw std::runtime_error("[World] " + name + "_free is not a free joint");
    }
    v.com_b = Vec3(w.m->body_ipos + 3 * v.body);
    const double a = spec.params.arm_length / std::sqrt(2.0);
    v.rotor_b = {Vec3(a, -a, 0), Vec3(-a, a, 0), Vec3(a, a, 0), Vec3(-a, -a, 0)};
    v.spin = {1.0, 1.0, -1.0, -1.0};
    const double ratio = spec.params.torque_constant / spec.params.thrust_constant;
    Eigen::Matrix4d mix;
    for (int r = 0; r < 4; ++r) {
      mix.col(r) << 1.0, v.rotor_b[r].y(), -v.rotor_b[r].x(), -v.spin[r] * ratio;
    }
    v.mix_inv = mix.inverse();
    const double tau = std::isnan(spec.motor_time_constant) ? config.motor_time_constant
                                                            : spec.motor_time_constant;
    v.motor_alpha = 1.0 - std::exp(-config.physics_dt / tau);
    v.hover_rpm = std::sqrt(spec.params.mass * std::max(config.gravity, 1.0) /
                            (4.0 * spec.params.thrust_constant));
    v.voltage = config.battery.full_voltage;
    v.soc = config.battery.fixed_voltage ? 1.0 : config.battery.initial_soc;
    if (!config.battery.fixed_voltage) {
      v.voltage = config.battery.empty_voltage +
                  (config.battery.full_voltage - config.battery.empty_voltage) * v.soc;
    }
    std::seed_seq seed{static_cast<std::uint32_t>(config.seed),
                       static_cast<std::uint32_t>(config.seed >> 32),
                       static_cast<std::uint32_t>(i)};
    v.rng.seed(seed);
    if (config.sensor_reality.enabled) {
      std::seed_seq rseed{static_cast<std::uint32_t>(config.seed),
                          static_cast<std::uint32_t>(config.seed >> 32),
                          static_cast<std::uint32_t>(i), 0x5E45u};
      v.reality_rng.seed(rseed);
      const SensorRealitySettings& sr = config.sensor_reality;
      for (int a = 0; a < 3; ++a) {
        v.accel_bias[a] = sr.accel_bias * v.reality_normal(v.reality_rng);
        v.gyro_bias[a] = sr.gyro_bias * v.reality_normal(v.reality_rng);
      }
      v.attitude_estimate = RotationZyx(0.0, 0.0, spec.yaw);
    }
    if (std::isfinite(spec.initial_throttle)) {
      v.direct = true;
      v.throttle.setConstant(spec.initial_throttle);
      w.Autopilot(v);
      v.rpm = v.rpm_target;
    } else {
      v.command.yaw = spec.yaw;
    }
  }
  if (config.reality.wake) {
    w.wakes.reserve(n);
    w.fluctuation.reserve(static_cast<std::size_t>(n * n));
    for (int j = 0; j < n; ++j) {
      w.wakes.emplace_back(config.downwash, config.reality.wake_turbulence);
      for (int i = 0; i < n; ++i) {
        w.fluctuation.emplace_back(config.reality.wake_turbulence, config.seed, j, i);
      }
    }
  }
  w.queue.reserve(static_cast<std::size_t>(256 * n * (n + 6)));
  mj_forward(w.m, w.d);
}

World::~World() = default;

namespace {
void CheckIndex(int vehicle, int n) {
  if (vehicle < 0 || vehicle >= n) {
    throw std::invalid_argument("[World] vehicle index out of range, got " +
                                std::to_string(vehicle) + " with " + std::to_string(n) +
                                " vehicles");
  }
}
}  // namespace

void World::SetCommand(int vehicle, const AttitudeCommand& command) {
  CheckIndex(vehicle, num_vehicles());
  Vehicle& v = impl_->vehicles[vehicle];
  // Latched failsafe or killed motors: the autopilot no longer listens.
  if (v.status.failsafe || v.status.motors_killed) return;
  v.direct = false;
  v.command = command;
  v.status.last_command_time = impl_->Time();
}

void World::KillMotors(int vehicle) {
  CheckIndex(vehicle, num_vehicles());
  Vehicle& v = impl_->vehicles[vehicle];
  if (v.status.motors_killed) return;
  v.status.motors_killed = true;
  v.status.motors_killed_time = impl_->Time();
  v.status.armed = false;
  v.throttle.setZero();
  v.rpm.setZero();
  v.rpm_target.setZero();
}

AutopilotStatus World::GetAutopilotStatus(int vehicle) const {
  CheckIndex(vehicle, num_vehicles());
  return impl_->vehicles[vehicle].status;
}

void World::SetThrottles(int vehicle, const Vec4& throttles) {
  CheckIndex(vehicle, num_vehicles());
  Vehicle& v = impl_->vehicles[vehicle];
  v.direct = true;
  v.throttle = throttles.cwiseMax(0.0).cwiseMin(1.0);
}

void World::SetPose(int vehicle, const Vec3& position, const Vec3& euler) {
  SetState(vehicle, position, euler, Vec3::Zero(), Vec3::Zero());
}

void World::SetState(int vehicle, const Vec3& position, const Vec3& euler, const Vec3& velocity,
                     const Vec3& body_rates) {
  CheckIndex(vehicle, num_vehicles());
  Impl& w = *impl_;
  Vehicle& v = w.vehicles[vehicle];
  const Eigen::Quaterniond q(RotationZyx(euler.x(), euler.y(), euler.z()));
  double* qpos = w.d->qpos + v.qpos;
  qpos[0] = position.x();
  qpos[1] = position.y();
  qpos[2] = position.z();
  qpos[3] = q.w();
  qpos[4] = q.x();
  qpos[5] = q.y();
  qpos[6] = q.z();
  Eigen::Map<Vec3> lin(w.d->qvel + v.qvel);
  Eigen::Map<Vec3> ang(w.d->qvel + v.qvel + 3);
  lin = velocity;
  ang = body_rates;
  v.v_prev = velocity;
  v.accel.setZero();
  if (w.config.sensor_reality.enabled)
    v.attitude_estimate = RotationZyx(euler.x(), euler.y(), euler.z());
  mj_forward(w.m, w.d);
}

void World::Step(double duration) {
  if (!(duration >= 0.0) || !std::isfinite(duration)) {
    throw std::invalid_argument("[World] Step duration must be finite and >= 0, got " +
                                std::to_string(duration));
  }
  const auto n = static_cast<std::int64_t>(std::llround(duration / impl_->config.physics_dt));
  for (std::int64_t k = 0; k < n; ++k) impl_->StepOnce();
}

void World::StepOnce() { impl_->StepOnce(); }

bool World::PopMeasurement(Measurement* out) {
  auto& q = impl_->queue;
  if (q.empty() || q.front().m.arrival > impl_->Time() + kTimeEps) return false;
  std::pop_heap(q.begin(), q.end(), Later);
  *out = q.back().m;
  q.pop_back();
  return true;
}

std::size_t World::queued_measurements() const { return impl_->queue.size(); }

TrueState World::GetTrueState(int vehicle) const {
  CheckIndex(vehicle, num_vehicles());
  const Impl& w = *impl_;
  const Vehicle& v = w.vehicles[vehicle];
  TrueState s;
  s.position = w.Position(v);
  s.velocity = w.Velocity(v);
  s.euler = EulerOf(w.Rotation(v));
  s.body_rates = w.Rates(v);
  s.acceleration = v.accel;
  s.rotor_rpm = v.rpm;
  s.throttle = v.throttle;
  s.thrust = v.params.thrust_constant * v.rpm.squaredNorm();
  s.voltage = v.voltage;
  s.soc = v.soc;
  s.current = v.current;
  s.aero_force = v.aero_force;
  s.aero_torque = v.aero_torque;
  return s;
}

double World::time() const { return impl_->Time(); }
double World::physics_dt() const { return impl_->config.physics_dt; }
int World::num_vehicles() const { return static_cast<int>(impl_->vehicles.size()); }
const std::string& World::model_xml() const { return impl_->xml; }

}  // namespace fnmpc::sim
