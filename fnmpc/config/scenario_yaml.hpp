// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "fnmpc/config/settings_doc.hpp"
#include "fnmpc/config/yaml_reader.hpp"
#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/formation/controller_settings.hpp"
#include "fnmpc/formation/neighbour_limits.hpp"
#include "fnmpc/formation/nmpc_weights.hpp"
#include "fnmpc/formation/recovery.hpp"
#include "fnmpc/model/true_plant.hpp"
#include "fnmpc/model/vehicle_params.hpp"
#include "fnmpc/sim/world_settings.hpp"

/// Formation scenario files (config/scenarios/*.yaml, every key documented in
/// docs/scenarios.md): plain structs, mapped onto the controllers and the world by the app.
namespace fnmpc::config {

/// One neighbour of a follower: the observed vehicle and the desired relative position
/// p_neighbour - p_self [m] in the follower's target frame.
struct ScenarioNeighbour {
  std::string vehicle;  ///< name of the neighbour
  int index = -1;       ///< resolved index into ScenarioConfig::vehicles
  Vec3 desired = Vec3::Zero();
};

/// One vehicle of the scenario.
struct ScenarioVehicle {
  std::string name;
  bool leader = false;
  Vec3 start = Vec3::Zero();  ///< start position x, y [m] (z: resting on the ground)
  double yaw = 0.0;           ///< initial yaw [rad]
  model::VehicleParams params;
  SensorsConfig sensors;
  std::vector<ScenarioNeighbour> neighbours;    ///< followers: 1 to formation::kMaxNeighbours
  bool frame_control = false;                   ///< desired offsets in {c} (true) or {m} (false)
  Vec3 relative_position_bound{6.0, 6.0, 2.0};  ///< soft bound on |dx_j| per axis [m]
  double takeoff_height = kNaN;  ///< per-vehicle take-off height [m]; NaN: phases.takeoff_height
  double landing_time = kNaN;    ///< per-vehicle start of the landing [s]; NaN: phases.landing_time
  /// `plant_file`: the vehicle's true plant given explicitly (vehicle-file format with the
  /// `bias` block as the true attitude biases and thrust scale); flown instead of a draw
  /// when reality is on. The controller keeps `params`.
  bool has_plant = false;
  model::VehicleParams plant;
  double plant_motor_time_constant = kNaN;  ///< [s]; NaN: the simulator's 0.02 s
};

/// Dryden turbulence of `reality.wind.turbulence`: from w20/height (MIL-F-8785C low altitude)
/// when w20 is given, else from sigma/length_scale; off when neither is.
struct ScenarioTurbulence {
  double w20 = kNaN;                      ///< [m/s]
  double height = kNaN;                   ///< [m]
  Vec3 sigma = Vec3::Constant(kNaN);      ///< [m/s]
  Vec3 length_scale{200.0, 200.0, 50.0};  ///< [m]
  double airspeed = kNaN;                 ///< [m/s]; NaN: |wind velocity|
  [[nodiscard]] bool enabled() const { return std::isfinite(w20) || sigma.allFinite(); }

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("w20", &w20, NonNegative(),
             "[m/s] wind at 20 ft: MIL-F-8785C low-altitude intensities and scales (with "
             "`height`; not with `sigma`, `length_scale`)");
    a->Visit("height", &height, AnyValue().AtLeast(3.048, "m").AtMost(304.8, "m"),
             "[m] height of the low-altitude model (10–1000 ft); required with `w20`");
    a->Visit("sigma", &sigma, NonNegativeEntries(),
             "[m/s] intensities of u, v, w given directly; required without `w20`");
    a->Visit("length_scale", &length_scale, Positive(),
             "[m] scale lengths of u, v, w with `sigma`");
    a->Visit("airspeed", &airspeed, Positive(),
             "[m/s] converts the spectra to time; default |`wind.velocity`|, required when "
             "that is zero");
  }
};

/// The `reality:` block (docs/scenarios.md, docs/simulator.md "Reality"): what makes the
/// simulated plant differ from the controllers' model. Off when the block is absent, on when
/// it is given (even empty) unless `enabled: false`. Its parts are the simulator's and the
/// plant model's own settings structs.
struct ScenarioReality {
  bool enabled = false;
  model::PlantSpread plant;        ///< spread of the true plant around the vehicle file
  bool rotor_aerodynamics = true;  ///< thrust in the actual inflow, ground effect, rotor drag
  bool wake = true;  ///< every vehicle's advected, fluctuating wake (also with downwash: false)
  bool sensors =
      true;  ///< IMU biases, latency jitter, bursty dropouts, mocap outliers, own attitude estimate
  sim::SensorRealitySettings sensor_models;  ///< their parameters (`enabled`: `sensors`)
  sim::WindSettings wind;         ///< velocity, gusts, discrete gusts (`enabled` follows)
  ScenarioTurbulence turbulence;  ///< `wind.turbulence`

  /// Every key of the block (below `reality.`), accepted values and meaning.
  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("enabled", &enabled, AnyValue(),
             "switch of the whole block; a `reality:` block without it is on, no block is off; "
             "`fnmpc run --reality on|off` overrides it");
    a->Visit("rotor_aerodynamics", &rotor_aerodynamics, AnyValue(),
             "rotor thrust in the actual axial inflow (BEMT), ground effect, rotor drag");
    a->Visit("wake", &wake, AnyValue(),
             "every vehicle's advected, turbulent wake acting on the others' rotors and body (also "
             "when `downwash: false`; `--downwash off` turns it off)");
    a->Visit("sensors", &sensors, AnyValue(),
             "IMU bias random walk, latency jitter, bursty dropouts, mocap outliers, and the "
             "autopilot's attitude loop on its own gyro-driven estimate (`sensor_models`)");
    a->Nested("sensor_models", &sensor_models);
    a->Nested("plant", &plant);
    a->Nested("wind", &wind);
    a->Nested("wind.turbulence", &turbulence);
  }
};

/// NMPC weights: the controllers' own struct.
using ScenarioWeights = formation::NmpcWeights;

/// A fault that downs one vehicle at a time (`faults.kill_controller`, `faults.motors_off`).
struct VehicleFault {
  std::string vehicle;  ///< name; empty: no such fault
  int index = -1;       ///< resolved index into ScenarioConfig::vehicles; -1: none
  double time = kNaN;   ///< when it happens [s]
  [[nodiscard]] bool active() const { return index >= 0; }
};

/// A window in which one sensor of one vehicle delivers nothing (`faults.sensor_dropouts`).
struct SensorDropoutWindow {
  std::string vehicle;
  int index = -1;
  SensorKind sensor = SensorKind::kMocapPose;
  double from = 0.0, to = 0.0;  ///< stamps in [from, to] are dropped [s]
};

/// The scenario's `faults:` block (docs/scenarios.md), applied by `fnmpc run`; all off by
/// default. Randomness (outliers, solver failures) is drawn from the run's seed.
struct ScenarioFaults {
  VehicleFault kill_controller;  ///< the vehicle's controller stops; its autopilot lands it
  VehicleFault motors_off;       ///< the vehicle's motors stop; it falls
  std::vector<SensorDropoutWindow> sensor_dropouts;
  double outlier_rate = 0.0;         ///< share of all measurements given an outlier, [0, 1]
  double outlier_size = 0.0;         ///< its size in the sensor's units (m, rad, m/s, ...)
  double solver_failure_rate = 0.0;  ///< share of NMPC steps forced to fall back, [0, 1]
  [[nodiscard]] bool any() const {
    return kill_controller.active() || motors_off.active() || !sensor_dropouts.empty() ||
           outlier_rate > 0.0 || solver_failure_rate > 0.0;
  }
};

/// The flight envelope a run is judged against (block `envelope:`): a vehicle above
/// max_altitude or farther than max_distance (horizontally) from its start fails the run.
struct FlightEnvelope {
  double max_altitude = 5.0;
  double max_distance = 20.0;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("max_altitude", &max_altitude, fnmpc::Positive(),
             "[m] above the ground; a vehicle above it at any control step fails the run "
             "(`failures` in summary.json, exit code 3, docs/failure.md)");
    a->Visit("max_distance", &max_distance, fnmpc::Positive(),
             "[m] horizontal distance from the vehicle's start, likewise; the defaults are the "
             "limits of the safety campaign (docs/safety.md)");
  }
};

/// How a run is judged (block `metrics:`).
struct RunCriteria {
  double settle_time = 3.0;
  double touchdown_speed_max = 0.6;
  double max_tilt_landed = 0.3;
  double collision_distance = 0.3;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("settle_time", &settle_time, fnmpc::NonNegative(),
             "[s] steady state: the leader's reference has been at rest at least this long");
    a->Visit("touchdown_speed_max", &touchdown_speed_max, fnmpc::Positive(),
             "[m/s] landed safely: |v_z| at touchdown below this; a faster touchdown is a "
             "hard touchdown, a failure of the run");
    a->Visit("max_tilt_landed", &max_tilt_landed, fnmpc::Positive(),
             "[rad] landed safely: final tilt below this");
    a->Visit("collision_distance", &collision_distance, fnmpc::Positive(),
             "[m] a collision: two vehicles' true CoMs closer than this at a control step fail "
             "the run (`failures`, exit 3, docs/failure.md); the verdict's threshold, not the "
             "controllers' r_min (`safety.collision_radius`)");
  }
};

/// The simulated link of cooperative mode (block `link:`, `controller.compensation:
/// cooperative`): what carries each vehicle's plan (formation::PlanMessage) to the vehicles
/// that have it as a formation neighbour (fnmpc/experiment/plan_link.hpp).
struct LinkSettings {
  double latency = 0.01;
  double loss_rate = 0.0;
  double bandwidth = 1e6;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("latency", &latency, fnmpc::NonNegative().AtMost(1.0, "s"),
             "[s] delay from the end of a plan's transmission to its delivery");
    a->Visit("loss_rate", &loss_rate, fnmpc::NonNegative().AtMost(1.0, ""),
             "probability that a receiver loses a message, drawn per message and receiver "
             "(deterministic per run seed; 1: every message lost, cooperative then flies as "
             "wake)");
    a->Visit("bandwidth", &bandwidth, fnmpc::Positive(),
             "[bit/s] each vehicle's transmitter: a plan takes its size (32 + 28 (N + 1) bytes) "
             "over this to send, and queues behind the one still being sent");
  }
};

/// The scenario's defaults of the controllers' shared settings where they differ from
/// formation::ControllerSettings' own: the leader's first leg at 12 s, landing at 50 s.
inline formation::ControllerSettings ScenarioControllerDefaults() {
  formation::ControllerSettings c;
  c.trajectory_start = 12.0;
  c.landing_time = 50.0;
  return c;
}

/// Upper bounds on the work a scenario may ask for (docs/failure.md, "Limits").
inline constexpr double kMaxScenarioDuration = 3600.0;  ///< [s] simulated
inline constexpr int kMaxLeaderMoves = 1000;
inline constexpr int kMaxWaypoints = 1000;
inline constexpr int kMaxVehicles = 128;
inline constexpr double kPhysicsStep = 0.001;  ///< the simulator's physics step [s]

/// The whole scenario. It extends the settings every vehicle's controller shares
/// (formation::ControllerSettings: keys controller.*, phases.*, safety.*, leader.start_time),
/// with the scenario's own defaults (ScenarioControllerDefaults); ControllerConfigFor adds
/// what is each vehicle's own.
struct ScenarioConfig : formation::ControllerSettings {
  ScenarioConfig() : formation::ControllerSettings(ScenarioControllerDefaults()) {}

  std::string name;
  std::string description;
  std::string file;        ///< path it was read from
  double duration = 60.0;  ///< simulated time [s]
  std::uint64_t seed = 1;
  bool downwash = false;
  bool battery_sag = true;  ///< false: fixed 16.8 V
  ScenarioReality reality;  ///< block `reality:`; `fnmpc run --reality on|off` overrides
  std::vector<ScenarioVehicle> vehicles;
  int leader = -1;  ///< index of the leader
  // Leader motion.
  std::string leader_mode = "waypoints";  ///< "waypoints" (NMPC) or "manual" (moved by hand)
  std::vector<Vec3> waypoints;            ///< offsets from the hover point [m]
  double leg_duration = 4.0, hold_duration = 4.0;  ///< [s]
  Vec3 walk_box{1.15, 1.15, 1.15};                 ///< manual: box size [m] (1.5 m^3)
  int walk_moves = 8;
  double walk_min_leg = 1.5, walk_max_leg = 3.0, walk_min_hold = 3.0, walk_max_hold = 5.0;
  Vec3 manual_start{0.0, 0.0, 1.0};                  ///< manual: leader held at this position [m]
  ScenarioWeights leader_weights, follower_weights;  ///< the controllers' weights by role
  ScenarioFaults faults;    ///< block `faults:` (fault injection of `fnmpc run`)
  RunCriteria metrics;      ///< block `metrics:`
  FlightEnvelope envelope;  ///< block `envelope:`
  LinkSettings link;        ///< block `link:` (cooperative mode's simulated link)
  /// Things a user may mean but should know (a leader without motion capture, a neighbour
  /// out of sensor reach at the start), "file:line:column: key '...': what"; printed by
  /// `fnmpc run` and recorded in summary.json.
  std::vector<std::string> warnings;

  /// The scenario's settings that map onto settings structs, with their keys (the rest of
  /// the file, vehicles, leader motion, reality and faults, is parsed by ParseScenario).
  /// docs/scenarios.md's settings table is generated from this (ScenarioSettingsDocs).
  template <class Archive>
  void Serialize(Archive* a) {
    formation::ControllerSettings::Serialize(a);
    a->Nested("controller.weights.leader", &leader_weights);
    a->Nested("controller.weights.follower", &follower_weights);
    a->Nested("metrics", &metrics);
    a->Nested("envelope", &envelope);
    a->Nested("link", &link);
  }
};

/// Reads and validates a scenario file; relative file paths (vehicle_file, sensors_file)
/// are resolved against the scenario's directory. Throws ConfigError with
/// file:line:column and the key on unknown keys, missing keys and bad values.
ScenarioConfig LoadScenarioFile(const std::string& path);
ScenarioConfig ParseScenario(YamlMap map);

/// Every key of ScenarioConfig::Serialize with its default, accepted values and meaning:
/// the source of docs/scenarios.md's settings table (checked by scenario_settings_doc_test).
std::vector<SettingDoc> ScenarioSettingsDocs();
/// The same for the `reality:` block (ScenarioReality::Serialize, keys `reality.*`).
std::vector<SettingDoc> RealitySettingsDocs();

/// Effective landing time of vehicle i [s] (its own or the scenario's).
double LandingTime(const ScenarioConfig& s, int i);
/// End of the formation window: the earliest landing time of any vehicle [s].
double FormationWindowEnd(const ScenarioConfig& s);

/// Checks a run duration [s] given on the command line (`--duration`): finite, > 0 and not
/// longer than the scenario's own duration; throws ConfigError naming the flag otherwise.
void CheckDurationFlag(const ScenarioConfig& s, double duration);

}  // namespace fnmpc::config
