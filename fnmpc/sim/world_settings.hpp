// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/model/vehicle_params.hpp"
#include "fnmpc/sim/downwash.hpp"
#include "fnmpc/sim/dryden.hpp"
#include "fnmpc/sim/rotor_aero.hpp"
#include "fnmpc/sim/wake.hpp"

/// The settings of the simulator (sim::World, world.hpp): what the world is built from, with
/// their checks, without the simulator itself (config includes this, not world.hpp).
namespace fnmpc::sim {

/// Height of the centre of mass of a vehicle resting on its landing gear [m]
/// (World::kRestHeight).
inline constexpr double kRestHeight = 0.1;

/// One vehicle of the world.
struct VehicleSpec {
  model::VehicleParams params;  ///< physical and identified parameters (vehicle file)
  /// Initial position of the centre of mass [m]. On the ground it rests at z = kRestHeight.
  Vec3 position{0.0, 0.0, 0.1};
  double yaw = 0.0;       ///< initial yaw [rad]; roll and pitch start at zero
  SensorsConfig sensors;  ///< rates, latencies, noise, dropout (sensors YAML)
  /// When finite: the vehicle starts in direct-throttle mode with these throttles on all
  /// four rotors and the rotors already at their steady-state speed (e.g. start in hover).
  double initial_throttle = kNaN;
  /// This vehicle's motor time constant [s]; NaN: WorldConfig::motor_time_constant.
  double motor_time_constant = kNaN;
};

/// Battery: open-circuit voltage linear in the state of charge, series resistance.
/// V = V_empty + (V_full - V_empty) soc - R I, I = P_mech / (efficiency V),
/// P_mech = sum over rotors of T_q rpm^2 omega, d soc / dt = -I / (3600 capacity).
struct BatterySettings {
  bool fixed_voltage = false;          ///< true: the voltage stays at full_voltage (no sag)
  double full_voltage = 16.8;          ///< [V] (4S LiPo, 4.2 V per cell)
  double empty_voltage = 13.2;         ///< [V] open-circuit voltage at soc = 0
  double capacity_ah = 5.2;            ///< [A h]
  double internal_resistance = 0.025;  ///< [Ohm]
  double efficiency = 0.7;             ///< electrical to shaft power [-]
  double initial_soc = 1.0;            ///< state of charge at t = 0, in (0, 1]
};

/// A discrete "1-cosine" gust (MIL-F-8785C sec. 3.7.2.4 shape, full cosine as in CS-25.341):
/// v(t) = amplitude (1 - cos(2 pi (t - start) / duration)) / 2 for start <= t <= start +
/// duration, zero otherwise.
struct DiscreteGust {
  double start = 0.0;             ///< [s]
  double duration = 1.0;          ///< [s], > 0
  Vec3 amplitude = Vec3::Zero();  ///< peak velocity, world frame [m/s]

  /// Its keys (an item of the scenario's `reality.wind.discrete_gusts`).
  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("time", &start, NonNegative().Required(), "[s] start, before the scenario's duration");
    a->Visit("duration", &duration, Positive(), "[s] length");
    a->Visit("amplitude", &amplitude, Finite(), "[m/s] peak velocity [x, y, z], world frame");
  }
};

/// Constant wind plus gusts: the gust is a first-order Gauss-Markov (Ornstein-Uhlenbeck)
/// process per axis, uniform in space, with stationary standard deviation gust_std; plus,
/// when `turbulence` is set, Dryden turbulence (DrydenTurbulence, u along the horizontal
/// mean wind, w up) and the discrete gusts. All uniform in space.
struct WindSettings {
  bool enabled = false;
  Vec3 velocity = Vec3::Zero();     ///< constant wind, world frame [m/s]
  double gust_std = 0.0;            ///< [m/s], >= 0
  double gust_time_constant = 2.0;  ///< correlation time [s], > 0
  bool turbulence = false;          ///< Dryden turbulence on
  DrydenSettings dryden;            ///< its intensities, scale lengths and airspeed
  std::vector<DiscreteGust> discrete_gusts;

  /// The keys of the scenario's `reality.wind` that map onto these fields (the switches
  /// `enabled` and `turbulence` follow from them; the turbulence block is the scenario's own).
  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("velocity", &velocity, Finite(), "[m/s] constant wind [x, y, z], world frame");
    a->Visit("gusts.std", &gust_std, NonNegative(),
             "[m/s] Gauss–Markov gusts per axis: stationary standard deviation (0: off)");
    a->Visit("gusts.time_constant", &gust_time_constant, Positive(), "[s] their correlation time");
    a->VisitList("discrete_gusts", &discrete_gusts,
                 "1-cosine gusts: v(t) = amplitude (1 − cos(2π (t − time) / duration)) / 2");
  }
};

/// Velocity [m/s] of the discrete gusts at time t [s] (sum over the gusts).
Vec3 DiscreteGustVelocity(const std::vector<DiscreteGust>& gusts, double t);

/// Command-timeout failsafe of the emulated autopilot, after the common autopilot behaviour
/// on a lost offboard link (PX4 offboard mode: with no new setpoint for COM_OF_LOSS_T the
/// vehicle leaves offboard and runs the failsafe action of COM_OBL_ACT, e.g. Land; without a
/// position estimate Land becomes Descend: level attitude and a slow descent; the land
/// detector then disarms). Armed vehicle (last command with a thrust or throttle above idle),
/// no SetCommand for `timeout`: roll and pitch 0, yaw held, collective thrust from a
/// vertical-speed loop to -descent_speed; once the vertical speed stays below
/// `land_speed` with the loop asking for less than hover thrust for `land_detect_time`, the
/// motors stop (disarmed) and stay off. Latched: later commands are ignored, as the real
/// autopilot needs an operator's mode switch to leave the failsafe.
struct CommandTimeoutSettings {
  bool enabled = false;           ///< off by default (tests drive the autopilot by hand)
  double timeout = 1.0;           ///< no command this long -> failsafe [s]
  double descent_speed = 0.7;     ///< [m/s] (PX4 MPC_LAND_SPEED default 0.7 m/s)
  double velocity_gain = 2.0;     ///< vertical-speed loop gain [1/s]
  double land_speed = 0.1;        ///< land detector: |v_z| below this [m/s]
  double land_detect_time = 1.0;  ///< ... for this long -> motors off [s]
};

/// Aerodynamic reality models (docs/simulator.md "Reality"); all off is the ideal plant (pinned
/// bit for bit by tests/sim/reality_off_test.cpp).
struct AeroRealitySettings {
  /// Each rotor's thrust in its actual axial inflow (AxialInflowThrustRatio, with the air of
  /// the wind and the other vehicles' wakes), ground effect (GroundEffectRatio) and rotor
  /// drag (RotorDrag) on top of the quadratic body drag.
  bool rotor_aerodynamics = false;
  RotorBlade blade;
  /// Mass-normalised rotor drag coefficient d [1/s] at hover rotor speed: the mean of the
  /// d_x = 0.544 and d_y = 0.386 identified by Faessler et al. 2018 (RA-L 3(2)).
  double rotor_drag = 0.465;
  /// The wakes (when downwash.enabled) advected from the upper vehicle's past states, with
  /// turbulent fluctuations (WakeHistory, WakeFluctuation), instead of the steady jet.
  bool wake = false;
  WakeTurbulenceSettings wake_turbulence;
};

/// Sensor and autopilot reality models (docs/simulator.md "Reality"); off is the
/// ideal sensors of SensorsConfig. Draws come from their own seeded stream.
struct SensorRealitySettings {
  bool enabled = false;
  /// IMU biases: initial standard deviation and random walk (per axis). Initial values: the
  /// residual after a level/gyro calibration, well inside the uncalibrated offsets of a
  /// MPU-6000-class IMU (InvenSense product specification rev. 3.4: +-20 deg/s, +-50 mg).
  double accel_bias = 0.05;        ///< [m/s^2]
  double gyro_bias = 0.005;        ///< [rad/s] (0.3 deg/s)
  double accel_bias_walk = 0.002;  ///< [m/s^2 / sqrt(s)]
  double gyro_bias_walk = 0.0003;  ///< [rad/s / sqrt(s)]
  double latency_jitter = 0.003;   ///< extra delivery delay, uniform in [0, jitter] [s]
  /// Bursty dropouts (Gilbert-Elliott two-state chain per vehicle and sensor): share of
  /// samples lost in bursts and the mean burst length.
  double burst_share = 0.01;          ///< [-]
  double burst_length = 0.1;          ///< [s]
  double mocap_outlier_rate = 0.002;  ///< share of mocap samples with an outlier (marker swap)
  double mocap_outlier_size = 0.05;   ///< outlier position error [m]
  /// Autopilot attitude loop on its own estimate: gyro (with its bias and noise) integrated at
  /// the autopilot rate, corrected toward the external (mocap-like, noisy) attitude with this
  /// time constant, as an autopilot fusing external vision.
  bool autopilot_estimate = true;
  double estimate_time_constant = 0.5;  ///< [s]

  /// The models' parameters with their keys (scenario block `reality.sensor_models`); the
  /// switch `enabled` is the owner's (`reality.sensors`).
  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("accel_bias", &accel_bias, NonNegative(), "[m/s²] initial IMU accelerometer bias sd");
    a->Visit("gyro_bias", &gyro_bias, NonNegative(), "[rad/s] initial gyro bias sd");
    a->Visit("accel_bias_walk", &accel_bias_walk, NonNegative(),
             "[m/s² / √s] accelerometer bias random walk");
    a->Visit("gyro_bias_walk", &gyro_bias_walk, NonNegative(),
             "[rad/s / √s] gyro bias random walk");
    a->Visit("latency_jitter", &latency_jitter, NonNegative(),
             "[s] extra delivery delay, uniform in [0, jitter]");
    a->Visit("burst_share", &burst_share, NonNegative().Below(0.5, ""),
             "share of samples lost in bursts (Gilbert–Elliott chain per vehicle and sensor)");
    a->Visit("burst_length", &burst_length, Positive(), "[s] mean burst length");
    a->Visit("mocap_outlier_rate", &mocap_outlier_rate, NonNegative().AtMost(1.0, ""),
             "share of mocap samples with an outlier (marker swap)");
    a->Visit("mocap_outlier_size", &mocap_outlier_size, NonNegative(),
             "[m] outlier position error");
    a->Visit("autopilot_estimate", &autopilot_estimate, AnyValue(),
             "the autopilot's attitude loop on its own gyro-driven estimate; false: on the truth");
    a->Visit("estimate_time_constant", &estimate_time_constant, Positive(),
             "[s] that estimate's correction toward the external attitude");
  }

  void Validate() const;
};

/// Everything the world is built from.
struct WorldConfig {
  std::vector<VehicleSpec> vehicles;
  double physics_dt = 0.001;          ///< MuJoCo time step [s]
  double autopilot_rate_hz = 250.0;   ///< attitude controller rate [Hz]
  double motor_time_constant = 0.02;  ///< first-order rotor speed lag [s]
  double gravity = kGravity;          ///< [m/s^2], along -z; 0 for a free body
  bool ground = true;                 ///< ground plane with contact at z = 0
  /// Adds the contact-free arm, rotor-disc and rotor-site elements to the MJCF. They do not
  /// change the physics (mass and inertia are explicit) but cost MuJoCo kinematics time.
  bool visual_geometry = true;
  /// Body-axis quadratic drag coefficients [N s^2/m^2] (wind, gusts and downwash).
  Vec3 drag_coefficient{0.03, 0.03, 0.05};
  BatterySettings battery;
  DownwashSettings downwash;
  WindSettings wind;
  CommandTimeoutSettings command_timeout;  ///< autopilot failsafe on a lost command stream
  AeroRealitySettings reality;             ///< aerodynamic reality models (off: ideal plant)
  SensorRealitySettings sensor_reality;    ///< sensor and autopilot reality (off: ideal)
  std::uint64_t seed = 1;                  ///< all noise, dropouts and gusts derive from it
  /// With at least this many vehicles, relative sensing looks up the vehicles near each
  /// observer in a uniform grid (sim/cell_list.hpp, cells of the largest `max_range`) instead
  /// of testing every pair; the measurements are the same (tests/sim/cell_list_test.cpp).
  /// Every pair is tested when some enabled relative sensor has an infinite `max_range`.
  int relative_index_min_vehicles = 32;
  /// Each vehicle evaluates only the wakes that can reach it (AeroPass::Prepare: the jet's
  /// radial cut-off and spreading, DownwashSettings, bound the region a wake acts in; the
  /// candidates come from a cell list). The dropped contributions are exactly zero in the
  /// model, so results are the same as with false (every pair evaluated, O(N^2) per step;
  /// tests/sim/aero_culling_test.cpp). false: every pair, for checks and timing.
  bool aero_culling = true;
  /// Room in MuJoCo's contact buffer per vehicle, plus as much for four more vehicles
  /// (`nconmax` = contacts_per_vehicle (N + 4); each contact takes 4 constraint rows). The
  /// default holds a vehicle's four feet and its hub on the ground with room for
  /// vehicle-vehicle contacts. MuJoCo 2.2 keeps one of its buffers at rows x rows, i.e.
  /// quadratic in N: at 100 vehicles about 210 MB and 1.8 s to build with the default (see
  /// docs/benchmarks.md "Scaling"). A step that needs more room throws SimulationError.
  int contacts_per_vehicle = 10;

  /// Throws std::invalid_argument with context on a bad value (also checks each
  /// vehicle's params and sensors).
  void Validate() const;
};

/// Settings checks shared with the World constructor: throws std::invalid_argument naming
/// `who` (e.g. "vehicle 2") and the sensor on a rate <= 0, latency < 0, dropout outside
/// [0, 1), negative noise or non-positive range / field of view.
void ValidateSensors(const SensorsConfig& sensors, const std::string& who);

}  // namespace fnmpc::sim
