// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/sim/world_settings.hpp"

/// High-fidelity multi-vehicle simulator on MuJoCo (the only layer that includes MuJoCo;
/// mujoco.h stays inside world.cpp). Frames: world ENU z up; body x forward, y left, z up;
/// Euler ZYX (roll, pitch, yaw). See docs/simulator.md for every model and its units.
namespace fnmpc::sim {

using Vec4 = Eigen::Vector4d;

/// Reference for the emulated autopilot: total thrust and absolute Euler angles.
struct AttitudeCommand {
  double thrust = 0.0;  ///< total commanded thrust [N] (used when `throttle` is NaN)
  double roll = 0.0;    ///< [rad]
  double pitch = 0.0;   ///< [rad]
  double yaw = 0.0;     ///< absolute yaw angle [rad]
  /// Optional collective throttle in [0, 1] (clamped), as sent to a real autopilot. When
  /// set (not NaN) it replaces `thrust`: the autopilot's collective thrust is then
  /// 4 * Thrust(throttle, V) at the present battery voltage V, so a controller that converts
  /// its thrust with a stale or wrong voltage sees the resulting thrust error.
  double throttle = kNaN;
};

/// What the emulated autopilot is doing (World::GetAutopilotStatus).
struct AutopilotStatus {
  bool armed = false;           ///< last command above idle (or direct throttles)
  bool failsafe = false;        ///< command-timeout failsafe engaged
  double failsafe_time = kNaN;  ///< when it engaged [s]
  bool disarmed_by_failsafe = false;
  double disarm_time = kNaN;   ///< land detector stopped the motors [s]
  bool motors_killed = false;  ///< KillMotors() (fault injection)
  double motors_killed_time = kNaN;
  double last_command_time = kNaN;  ///< time of the last SetCommand [s]
};

/// Ground truth of one vehicle.
struct TrueState {
  Vec3 position = Vec3::Constant(kNaN);      ///< centre of mass, world [m]
  Vec3 velocity = Vec3::Constant(kNaN);      ///< world [m/s]
  Vec3 euler = Vec3::Constant(kNaN);         ///< roll, pitch, yaw [rad]
  Vec3 body_rates = Vec3::Constant(kNaN);    ///< angular velocity in the body frame [rad/s]
  Vec3 acceleration = Vec3::Constant(kNaN);  ///< world, over the last step [m/s^2]
  Vec4 rotor_rpm = Vec4::Constant(kNaN);     ///< [rpm]
  Vec4 throttle = Vec4::Constant(kNaN);      ///< applied throttles in [0, 1]
  double thrust = kNaN;                      ///< total rotor thrust [N]
  double voltage = kNaN;                     ///< battery terminal voltage [V]
  double soc = kNaN;                         ///< battery state of charge [-]
  double current = kNaN;                     ///< battery current [A]
  /// Aerodynamic force, world [N]: wind and wake drag, plus with the reality models the
  /// rotors' thrust in their actual inflow and ground effect minus their still-air thrust at
  /// the same speeds, and rotor drag.
  Vec3 aero_force = Vec3::Zero();
  Vec3 aero_torque = Vec3::Zero();  ///< wind + downwash torque about the CoM, world [N m]
};

/// Thrown by World::StepOnce when MuJoCo reports a numerical instability (its warnings for
/// NaN, Inf or huge positions, velocities or accelerations, after which MuJoCo silently resets
/// the state to the initial one) or a full contact or constraint buffer (MuJoCo then drops
/// the contacts beyond it: vehicles would sink through the ground or each other): the
/// simulation cannot go on honestly. The message holds the time and, for an instability,
/// every vehicle's position and velocity just before the failed step.
class SimulationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Multi-quadrotor world. Rotors are numbered in X configuration: 0 front right (CCW seen
/// from above), 1 rear left (CCW), 2 front left (CW), 3 rear right (CW).
class World {
 public:
  /// Height of the centre of mass of a vehicle resting on its landing gear [m].
  static constexpr double kRestHeight = sim::kRestHeight;

  /// Builds the MJCF model and allocates every buffer. Throws std::invalid_argument on a
  /// bad configuration and std::runtime_error if MuJoCo rejects the model.
  explicit World(const WorldConfig& config);
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  /// Sets the autopilot reference of `vehicle` (switches it to attitude mode).
  void SetCommand(int vehicle, const AttitudeCommand& command);
  /// Bypasses the autopilot: the four throttles (clamped to [0, 1]) go straight to the ESCs.
  void SetThrottles(int vehicle, const Vec4& throttles);
  /// Fault injection: the motors of `vehicle` stop now and for good (rotor speeds and
  /// thrust zero from this step, no spin-down lag; commands are ignored).
  void KillMotors(int vehicle);
  /// Teleports `vehicle` (CoM position [m], Euler [rad]) with zero velocity; for tests
  /// and scenario resets. Rotor speeds and battery are kept.
  void SetPose(int vehicle, const Vec3& position, const Vec3& euler);
  /// Like SetPose, with the world-frame velocity [m/s] and body rates [rad/s] given.
  void SetState(int vehicle, const Vec3& position, const Vec3& euler, const Vec3& velocity,
                const Vec3& body_rates);

  /// Runs f(i) for every i in [0, n) and returns when all are done, in any order and on any
  /// thread (e.g. a worker pool's ForEach; the first exception of f rethrown).
  using ParallelFor = std::function<void(int n, const std::function<void(int)>& f)>;
  /// Steps the per-vehicle work of each physics step that costs (the sensors and the
  /// aerodynamic pass; the rest is a few operations per vehicle) through `parallel_for`;
  /// empty: one thread. Every
  /// vehicle's work touches only its own state and reads the others' start-of-step
  /// kinematics, and the measurements are queued in vehicle order afterwards: the results
  /// are bit-identical to one thread (tests/sim/parallel_step_test.cpp).
  void SetParallelFor(ParallelFor parallel_for);

  /// Advances round(duration / physics_dt) physics steps (duration >= 0) [s].
  void Step(double duration);
  /// Advances exactly one physics step. Throws SimulationError when MuJoCo reports an
  /// instability or a full contact buffer during the step (the world is unusable afterwards).
  void StepOnce();

  /// Pops the earliest delivered measurement (arrival <= time()), in arrival order
  /// (ties: stamp, then generation order). Returns false when none is due.
  bool PopMeasurement(Measurement* out);
  /// Measurements generated but not yet popped (delivered or still in flight).
  [[nodiscard]] std::size_t queued_measurements() const;

  /// State of the emulated autopilot of `vehicle` (failsafe, disarm, killed motors).
  [[nodiscard]] AutopilotStatus GetAutopilotStatus(int vehicle) const;
  /// Ground truth of `vehicle` at time().
  [[nodiscard]] TrueState GetTrueState(int vehicle) const;
  /// Simulation time [s].
  [[nodiscard]] double time() const;
  [[nodiscard]] double physics_dt() const;
  [[nodiscard]] int num_vehicles() const;
  /// The generated MJCF text (for inspection and the docs).
  [[nodiscard]] const std::string& model_xml() const;

  /// Builds the MJCF text of a world without loading it (pure function).
  static std::string BuildMjcf(const WorldConfig& config);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fnmpc::sim
