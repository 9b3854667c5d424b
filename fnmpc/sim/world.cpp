// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/world.hpp"

#include <mujoco/mujoco.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <functional>
#include <iomanip>
#include <random>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/sim/aero_pass.hpp"
#include "fnmpc/sim/autopilot_model.hpp"
#include "fnmpc/sim/battery.hpp"
#include "fnmpc/sim/cell_list.hpp"
#include "fnmpc/sim/free_joint_force.hpp"
#include "fnmpc/sim/mjcf_model.hpp"
#include "fnmpc/sim/sensor_sampling.hpp"
#include "fnmpc/sim/world_vehicle.hpp"

namespace fnmpc::sim {

using detail::Kinematics;
using detail::kTimeEps;
using detail::ShortestText;
using detail::Vehicle;

namespace {

// Landing gear geometry, body frame [m]: feet spheres under the arms.
constexpr double kFootRadius = 0.01;
constexpr double kFootZ = -(World::kRestHeight - kFootRadius);
constexpr double kHubHalfSize = 0.06;
constexpr double kHubHalfHeight = 0.03;

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

std::string World::BuildMjcf(const WorldConfig& c) {
  std::ostringstream x;
  x << "<mujoco model=\"fnmpc_world\">\n"
    << "  <compiler autolimits=\"true\" angle=\"radian\"/>\n"
    << "  <option timestep=\"" << ShortestText(c.physics_dt) << "\" gravity=\"0 0 "
    << ShortestText(-c.gravity)
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
    x << "    <body name=\"" << n << "\" pos=\"" << ShortestText(v.position.x()) << " "
      << ShortestText(v.position.y()) << " " << ShortestText(v.position.z()) << "\" quat=\""
      << ShortestText(std::cos(v.yaw / 2)) << " 0 0 " << ShortestText(std::sin(v.yaw / 2))
      << "\">\n"
      << "      <freejoint name=\"" << n << "_free\"/>\n"
      << "      <inertial pos=\"0 0 0\" mass=\"" << ShortestText(p.mass) << "\" diaginertia=\""
      << ShortestText(p.inertia.x()) << " " << ShortestText(p.inertia.y()) << " "
      << ShortestText(p.inertia.z()) << "\"/>\n"
      << "      <geom name=\"" << n << "_hub\" type=\"box\" size=\"" << kHubHalfSize << " "
      << kHubHalfSize << " " << kHubHalfHeight << "\"/>\n";
    const std::array<std::array<double, 2>, 4> xy{{{a, -a}, {-a, a}, {a, a}, {-a, -a}}};
    for (int r = 0; r < 4; ++r) {
      const std::string px = ShortestText(xy[r][0]), py = ShortestText(xy[r][1]);
      x << "      <geom name=\"" << n << "_foot" << r << "\" type=\"sphere\" size=\"" << kFootRadius
        << "\" pos=\"" << px << " " << py << " " << ShortestText(kFootZ) << "\"/>\n";
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
  // Per-step scratch, sized at construction: every vehicle's kinematics at the start of the
  // step and its rotor thrust.
  std::vector<Kinematics> kin;
  std::vector<double> total_thrust;
  std::unique_ptr<detail::AeroPass> aero;
  World::ParallelFor parallel_for;  // empty: one thread
  // Relative sensing through a cell list (config.relative_index_min_vehicles): the grid of
  // this step's positions, its cell side (0: every pair is tested) and scratch.
  CellList cells;
  double cell_side = 0.0;
  std::vector<Vec3> cell_positions;

  ~Impl() {
    if (d != nullptr) mj_deleteData(d);
    if (m != nullptr) mj_deleteModel(m);
  }

  [[nodiscard]] double Time() const { return static_cast<double>(step) * config.physics_dt; }

  [[nodiscard]] Eigen::Vector4d Quaternion(const Vehicle& v) const {
    return Eigen::Map<const Eigen::Vector4d>(d->qpos + v.qpos + 3);
  }
  [[nodiscard]] Mat3 Rotation(const Vehicle& v) const {
    return detail::QuaternionRotation(Quaternion(v));
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

  void Push(const Measurement& meas) {
    queue.push_back({meas, seq++});
    std::push_heap(queue.begin(), queue.end(), Later);
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

  [[nodiscard]] Kinematics KinematicsOf(const Vehicle& v) const {
    return {Position(v), Velocity(v), Rates(v), Rotation(v), Quaternion(v)};
  }

  /// The relative sensor's cell list of this step's positions when some relative sample is
  /// due and the index is in use (enough vehicles, finite ranges and positions).
  detail::RelativeIndex RelativeIndexFor(double t) {
    const int n = static_cast<int>(vehicles.size());
    if (!(cell_side > 0.0) || n < config.relative_index_min_vehicles) return {};
    bool due = false;
    for (const Vehicle& v : vehicles) due = due || detail::RelativeSampleDue(v, t);
    if (!due) return {};
    cell_positions.resize(static_cast<std::size_t>(n));
    for (int j = 0; j < n; ++j) {
      cell_positions[j] = kin[j].position;
      if (!cell_positions[j].allFinite()) return {};
    }
    cells.Build(cell_positions, cell_side);
    return {&cells, cell_side};
  }

  /// The uniform air of the wind, gusts, turbulence and discrete gusts [m/s] (zero when the
  /// wind is off).
  [[nodiscard]] Vec3 WindAir() const {
    const WindSettings& wind = config.wind;
    if (!wind.enabled) return Vec3::Zero();
    Vec3 air = wind.velocity + gust;
    if (turbulence) air += wind_frame * turbulence->value();
    if (!wind.discrete_gusts.empty()) air += DiscreteGustVelocity(wind.discrete_gusts, Time());
    return air;
  }

  /// f(i) for every vehicle i, through parallel_for when set.
  void EachVehicle(const std::function<void(int)>& f) {
    const int n = static_cast<int>(vehicles.size());
    if (parallel_for && n > 1) {
      parallel_for(n, f);
    } else {
      for (int i = 0; i < n; ++i) f(i);
    }
  }

  void StepOnce() {
    const double t = Time();
    const double dt = config.physics_dt;
    const int n = static_cast<int>(vehicles.size());
    for (int i = 0; i < n; ++i) kin[i] = KinematicsOf(vehicles[i]);
    // 1. Autopilot ticks on its own schedule.
    if (t + kTimeEps >= static_cast<double>(autopilot_index) / config.autopilot_rate_hz) {
      do {
        ++autopilot_index;
      } while (static_cast<double>(autopilot_index) / config.autopilot_rate_hz <= t + kTimeEps);
      for (int i = 0; i < n; ++i) {
        if (config.sensor_reality.enabled) {
          detail::UpdateSensorReality(config, kin[i], vehicles[i]);
        }
        detail::AutopilotTick(config, t, kin[i], vehicles[i]);
      }
    }
    // 2. Sensors sample the state at t (each vehicle from its own streams), queued in vehicle
    // order, each in generation order.
    const detail::RelativeIndex index = RelativeIndexFor(t);
    EachVehicle([&](int i) {
      Vehicle& v = vehicles[i];
      detail::SampleSensors(config, i, t, kin, index, v, &v.samples);
    });
    for (Vehicle& v : vehicles) {
      for (const Measurement& meas : v.samples) Push(meas);
    }
    // 3. Motors, battery, propulsion wrench.
    for (int i = 0; i < n; ++i) {
      Vehicle& v = vehicles[i];
      const model::VehicleParams& p = v.params;
      const Mat3& rot = kin[i].rotation;
      v.rpm += v.motor_alpha * (v.rpm_target - v.rpm);
      if (v.status.motors_killed) v.rpm.setZero();
      StepBattery(config.battery, p.torque_constant, v.rpm, dt, &v.battery);
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
      if (aero->records_wakes()) aero->Record(i, t, kin[i].position, rot.col(2), thrust);
      v.force_w = rot.col(2) * thrust;
      v.torque_w = rot * torque_b;
    }
    // 4. Wind, gusts and the aerodynamic pass (after every vehicle's thrust and wake record).
    if (config.wind.enabled && config.wind.gust_std > 0.0) {
      const double phi = std::exp(-dt / config.wind.gust_time_constant);
      const double sd = config.wind.gust_std * std::sqrt(1.0 - phi * phi);
      for (int a = 0; a < 3; ++a) gust[a] = phi * gust[a] + sd * gust_normal(gust_rng);
    }
    if (turbulence) turbulence->Step();
    if (aero->active()) {
      const Vec3 wind_air = WindAir();
      aero->Prepare(kin);
      EachVehicle([&](int i) {
        Vehicle& v = vehicles[i];
        aero->StepFluctuations(i, t, kin);
        aero->VehicleWrench(i, t, wind_air, kin, total_thrust, v);
        v.force_w += v.aero_force;
        v.torque_w += v.aero_torque;
      });
    }
    // Each vehicle's wrench goes straight onto its free joint's dofs: MuJoCo 2.2 would map
    // xfrc_applied through dense 3 x nv Jacobians per body, O(N^2) per step (FreeJointForce).
    for (int i = 0; i < n; ++i) {
      const Vehicle& v = vehicles[i];
      Eigen::Map<Vec<6>>(d->qfrc_applied + v.qvel) =
          FreeJointForce(kin[i].rotation, v.com_b, v.force_w, v.torque_w);
    }
    for (int i = 0; i < n; ++i) {
      Vehicle& v = vehicles[i];
      v.v_prev = kin[i].velocity;
      v.p_prev = kin[i].position;
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
  w.kin.resize(static_cast<std::size_t>(n));
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
    v.battery = InitialBattery(config.battery);
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
      detail::AutopilotTick(config, w.Time(), w.KinematicsOf(v), v);
      v.rpm = v.rpm_target;
    } else {
      v.command.yaw = spec.yaw;
    }
  }
  w.aero = std::make_unique<detail::AeroPass>(w.config, n);
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

void World::SetParallelFor(ParallelFor parallel_for) {
  impl_->parallel_for = std::move(parallel_for);
}

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
  s.euler = EulerZyx(w.Rotation(v));
  s.body_rates = w.Rates(v);
  s.acceleration = v.accel;
  s.rotor_rpm = v.rpm;
  s.throttle = v.throttle;
  s.thrust = v.params.thrust_constant * v.rpm.squaredNorm();
  s.voltage = v.battery.voltage;
  s.soc = v.battery.soc;
  s.current = v.battery.current;
  s.aero_force = v.aero_force;
  s.aero_torque = v.aero_torque;
  return s;
}

double World::time() const { return impl_->Time(); }
double World::physics_dt() const { return impl_->config.physics_dt; }
int World::num_vehicles() const { return static_cast<int>(impl_->vehicles.size()); }
const std::string& World::model_xml() const { return impl_->xml; }

}  // namespace fnmpc::sim
