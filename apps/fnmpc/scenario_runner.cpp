// SPDX-License-Identifier: BSD-3-Clause
#include "apps/fnmpc/scenario_runner.hpp"

#include <fmt/core.h>
#include <fmt/ostream.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <stdexcept>

#include "apps/fnmpc/output_files.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/formation/trajectory.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/model/true_plant.hpp"
#include "fnmpc/sim/world.hpp"

namespace fnmpc::app {

namespace {

using formation::FlightPhase;
using json = nlohmann::json;

double Median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}
double Max(const std::vector<double>& v) {
  return v.empty() ? kNaN : *std::max_element(v.begin(), v.end());
}
double Mean(const std::vector<double>& v) {
  if (v.empty()) return kNaN;
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}
/// NaN -> null in JSON.
json Num(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

struct VehicleLog {
  std::unique_ptr<CheckedFile> csv;
  std::vector<double> errors;         // follower: mean over neighbours of |dx_j - d_j|, own window
  std::vector<double> flight_errors;  // follower: the same from take-off to touchdown
  double max_altitude = -kInf;        // highest CoM height above the resting height [m]
  double envelope_time = kNaN;        // first time outside the flight envelope [s]
  std::string envelope_reason;
  std::vector<double> steady_errors;
  std::vector<std::vector<double>> nb_errors;  // per neighbour
  std::vector<std::vector<double>> nb_steady;
  std::vector<double> tracking;  // leader |p - p_ref|
  std::vector<double> solver_time, solver_cpu, kkt, cost;
  long over_budget = 0, steps = 0, fallbacks = 0, guarded = 0, failures = 0;
  long reinitialisations = 0;
  double failsafe_time = kNaN;
  std::string failsafe_reason;
  double first_step_time = kNaN;
  double touchdown_vz = kNaN, touchdown_time = kNaN;
  double max_thrust_jump_at_switch = kNaN;
  bool motors_off = false;
  // Per control step in the formation window (followers): time, steady flag, errors to the
  // neighbours and the neighbours in the cost (fault report: errors after a kill).
  struct Sample {
    double t;
    bool steady;
    std::array<double, formation::kMaxNeighbours> err;
    int active;
  };
  std::vector<Sample> samples;
};

/// The scenario's faults as `fnmpc run` applies them (config::ScenarioFaults): measurement
/// filters (dropout windows, outliers) with their own seeded stream, the kill and motors-off
/// events, and what happened, for the summary's `faults` section.
class FaultInjector {
 public:
  FaultInjector(const config::ScenarioFaults& f, std::uint64_t seed)
      : f_(f), dropped_(f.sensor_dropouts.size(), 0) {
    std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                      0xFA17u};
    rng_.seed(seq);
  }

  /// False when the measurement is lost (dropout window); adds the outlier error otherwise.
  bool Filter(Measurement* m) {
    for (std::size_t w = 0; w < f_.sensor_dropouts.size(); ++w) {
      const config::SensorDropoutWindow& d = f_.sensor_dropouts[w];
      if (m->vehicle == d.index && m->kind == d.sensor && m->stamp >= d.from && m->stamp <= d.to) {
        ++dropped_[w];
        return false;
      }
    }
    ++measurements_;
    if (f_.outlier_rate > 0.0 && uniform_(rng_) < f_.outlier_rate) {
      AddOutlier(m);
      ++outliers_;
    }
    return true;
  }

  [[nodiscard]] long dropped(std::size_t w) const { return dropped_[w]; }
  [[nodiscard]] long measurements() const { return measurements_; }
  [[nodiscard]] long outliers() const { return outliers_; }

 private:
  /// An error of size s on every channel of the measurement, in the channel's unit: a random
  /// direction for vectors (norm s), a random sign for scalars.
  void AddOutlier(Measurement* m) {
    const double s = f_.outlier_size;
    auto dir = [this, s] {
      Vec3 u(normal_(rng_), normal_(rng_), normal_(rng_));
      const double n = u.norm();
      return n > 0.0 ? Vec3(s * u / n) : Vec3(s, 0.0, 0.0);
    };
    auto signed_size = [this, s] { return uniform_(rng_) < 0.5 ? -s : s; };
    switch (m->kind) {
      case SensorKind::kMocapPose:
        m->position += dir();
        m->euler += dir();
        m->euler.z() = WrapAngle(m->euler.z());
        break;
      case SensorKind::kImu:
        m->accel += dir();
        m->gyro += dir();
        break;
      case SensorKind::kOpticalFlow:
        m->velocity += dir();
        break;
      case SensorKind::kCompass:
        m->yaw = WrapAngle(m->yaw + signed_size());
        break;
      case SensorKind::kBattery:
        m->voltage += signed_size();
        break;
      case SensorKind::kRelative: {
        RelativeObservation& o = m->relative;
        o.range = std::abs(o.range + signed_size());
        o.bearing = WrapAngle(o.bearing + signed_size());
        o.elevation = std::clamp(o.elevation + signed_size(), -M_PI / 2, M_PI / 2);
        o.relative_yaw = WrapAngle(o.relative_yaw + signed_size());
        break;
      }
    }
  }

  const config::ScenarioFaults& f_;
  std::vector<long> dropped_;
  long measurements_ = 0, outliers_ = 0;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
};

/// What happened to a vehicle downed by a fault (first ground contact after the fault).
struct DownedLog {
  double impact_time = kNaN, impact_vz = kNaN;
  Vec3 impact_position = Vec3::Constant(kNaN);
};

}  // namespace

formation::WaypointTrajectory LeaderTrajectory(const config::ScenarioConfig& s,
                                               std::uint64_t seed) {
  if (s.leader_mode == "manual") {
    return formation::WaypointTrajectory::RandomWalk(s.walk_box, s.walk_moves, s.walk_min_leg,
                                                     s.walk_max_leg, s.walk_min_hold,
                                                     s.walk_max_hold, seed * 7919 + 17);
  }
  std::vector<Vec3> points{Vec3::Zero()};
  for (const Vec3& p : s.waypoints) points.push_back(p);
  return formation::WaypointTrajectory::Uniform(points, s.leg_duration, s.hold_duration);
}

formation::ControllerConfig ControllerConfigFor(const config::ScenarioConfig& sc, int i,
                                                const formation::WaypointTrajectory& trajectory) {
  if (i < 0 || i >= static_cast<int>(sc.vehicles.size())) {
    throw std::invalid_argument("[ControllerConfigFor] no vehicle " + std::to_string(i) +
                                " in scenario " + sc.name);
  }
  const auto& v = sc.vehicles[i];
  formation::ControllerConfig c;
  c.vehicle = i;
  c.leader = v.leader;
  c.params = v.params;
  c.sensors = v.sensors;
  c.rti.horizon = sc.horizon;
  c.rti.sample_time = sc.sample_time;
  c.rti.integrator_steps = sc.integrator_steps;
  c.rti.max_iterations = sc.max_iterations;
  c.rti.max_initial_iterations = sc.max_initial_iterations;
  c.rti.kkt_threshold = sc.kkt_threshold;
  c.rti.cpu_budget = sc.cpu_budget;
  c.weights = v.leader ? sc.leader_weights : sc.follower_weights;
  c.thrust_min = sc.thrust_min;
  c.thrust_max = sc.thrust_max;
  c.pid.max_thrust = sc.thrust_max;
  c.max_attitude_ref = sc.max_attitude_ref;
  c.max_speed = sc.max_speed;
  c.safety = sc.safety;
  for (const auto& n : v.neighbours) c.neighbours.push_back({n.index, n.desired});
  // Collision avoidance: every other vehicle the relative sensor may report.
  if (v.sensors.relative.enabled) {
    for (int j = 0; j < static_cast<int>(sc.vehicles.size()); ++j) {
      if (j != i) c.sensed_vehicles.push_back(j);
    }
  }
  c.frame = v.frame_control ? ocp::TargetFrame::kControl : ocp::TargetFrame::kInertial;
  c.relative_position_bound = v.relative_position_bound;
  c.trajectory = trajectory;
  c.trajectory_start = sc.trajectory_start;
  c.takeoff_time = sc.takeoff_time;
  c.takeoff_height = std::isfinite(v.takeoff_height) ? v.takeoff_height : sc.takeoff_height;
  c.climb_speed = sc.climb_speed;
  c.hover_before_switch = sc.hover_before_switch;
  c.blend_time = sc.blend_time;
  c.landing_time = config::LandingTime(sc, i);
  c.descent_speed = sc.descent_speed;
  c.ground_height = sim::World::kRestHeight;
  c.use_throttle = sc.use_throttle;
  return c;
}

sim::WorldConfig WorldConfigFor(const config::ScenarioConfig& sc, std::uint64_t seed) {
  const bool manual = sc.leader_mode == "manual";
  const int nv = static_cast<int>(sc.vehicles.size());
  sim::WorldConfig wc;
  for (int i = 0; i < nv; ++i) {
    const auto& v = sc.vehicles[i];
    sim::VehicleSpec spec;
    spec.params = v.params;
    spec.sensors = v.sensors;
    spec.position = Vec3(v.start.x(), v.start.y(), sim::World::kRestHeight);
    spec.yaw = v.yaw;
    if (manual && i == sc.leader) spec.position = sc.manual_start;
    wc.vehicles.push_back(spec);
  }
  wc.visual_geometry = false;
  wc.downwash.enabled = sc.downwash;
  wc.battery.fixed_voltage = !sc.battery_sag;
  wc.seed = seed;
  if (sc.reality.enabled) ApplyReality(sc, seed, &wc);
  return wc;
}

void ApplyReality(const config::ScenarioConfig& sc, std::uint64_t seed, sim::WorldConfig* wc) {
  const config::ScenarioReality& r = sc.reality;
  for (int i = 0; i < static_cast<int>(sc.vehicles.size()); ++i) {
    const auto& v = sc.vehicles[i];
    sim::VehicleSpec& spec = wc->vehicles[i];
    if (v.has_plant) {
      spec.params = v.plant;
      spec.motor_time_constant = v.plant_motor_time_constant;  // NaN: the world's
    } else {
      const model::TruePlant t =
          model::DrawTruePlant(v.params, wc->motor_time_constant, r.plant, seed, i);
      spec.params = t.params;
      spec.motor_time_constant = t.motor_time_constant;
    }
  }
  wc->reality.rotor_aerodynamics = r.rotor_aerodynamics;
  wc->reality.wake = r.wake;
  wc->sensor_reality.enabled = r.sensors;
  {
    const config::ScenarioReality::SensorModels& x = r.sensor_models;
    sim::SensorRealitySettings& y = wc->sensor_reality;
    auto set = [](double from, double* to) {
      if (std::isfinite(from)) *to = from;
    };
    set(x.accel_bias, &y.accel_bias);
    set(x.gyro_bias, &y.gyro_bias);
    set(x.accel_bias_walk, &y.accel_bias_walk);
    set(x.gyro_bias_walk, &y.gyro_bias_walk);
    set(x.latency_jitter, &y.latency_jitter);
    set(x.burst_share, &y.burst_share);
    set(x.burst_length, &y.burst_length);
    set(x.mocap_outlier_rate, &y.mocap_outlier_rate);
    set(x.mocap_outlier_size, &y.mocap_outlier_size);
    set(x.estimate_time_constant, &y.estimate_time_constant);
    if (x.autopilot_estimate >= 0) y.autopilot_estimate = x.autopilot_estimate == 1;
  }
  if (r.wake) wc->downwash.enabled = true;
  const bool turbulence = std::isfinite(r.turbulence_w20) || r.turbulence_sigma.allFinite();
  sim::WindSettings& w = wc->wind;
  w.enabled = r.wind.norm() > 0.0 || r.gust_std > 0.0 || turbulence || !r.gusts.empty();
  w.velocity = r.wind;
  w.gust_std = r.gust_std;
  w.gust_time_constant = r.gust_time_constant;
  w.turbulence = turbulence;
  if (turbulence) {
    const double airspeed =
        std::isfinite(r.turbulence_airspeed) ? r.turbulence_airspeed : r.wind.norm();
    if (std::isfinite(r.turbulence_w20)) {
      w.dryden = sim::LowAltitudeDryden(r.turbulence_w20, r.turbulence_height, airspeed);
    } else {
      w.dryden.sigma = r.turbulence_sigma;
      w.dryden.length_scale = r.turbulence_length_scale;
      w.dryden.airspeed = airspeed;
    }
  }
  for (const config::ScenarioGust& g : r.gusts) {
    w.discrete_gusts.push_back({g.time, g.duration, g.amplitude});
  }
}

double FormationError(const config::ScenarioConfig& sc, int i, const std::vector<Vec3>& positions,
                      double yaw, std::array<double, formation::kMaxNeighbours>* per_neighbour,
                      std::array<Vec3, formation::kMaxNeighbours>* relative) {
  const auto& v = sc.vehicles.at(static_cast<std::size_t>(i));
  if (per_neighbour) per_neighbour->fill(kNaN);
  if (relative) relative->fill(Vec3::Constant(kNaN));
  if (v.leader) return kNaN;
  double sum = 0.0;
  for (std::size_t j = 0; j < v.neighbours.size(); ++j) {
    Vec3 r = positions.at(static_cast<std::size_t>(v.neighbours[j].index)) -
             positions.at(static_cast<std::size_t>(i));
    if (v.frame_control) r = RotationZ(yaw).transpose() * r;
    const double e = (r - v.neighbours[j].desired).norm();
    if (per_neighbour) (*per_neighbour)[j] = e;
    if (relative) (*relative)[j] = r;
    sum += e;
  }
  return sum / static_cast<double>(v.neighbours.size());
}

config::ScenarioConfig Shortened(const config::ScenarioConfig& scenario, double duration) {
  config::ScenarioConfig s = scenario;
  const double landing_margin = 7.0;
  s.duration = duration;
  s.landing_time = duration - landing_margin;
  if (s.leader_mode == "waypoints") {
    const double per_leg = s.leg_duration + s.hold_duration;
    const int legs = std::max(1, static_cast<int>((s.landing_time - s.trajectory_start) / per_leg));
    if (static_cast<int>(s.waypoints.size()) > legs) s.waypoints.resize(legs);
  } else {
    const double per_move = s.walk_max_leg + s.walk_max_hold;
    s.walk_moves = std::max(1, static_cast<int>((s.landing_time - s.trajectory_start) / per_move));
  }
  if (!(s.landing_time > s.trajectory_start)) {
    throw std::invalid_argument("[Shortened] duration too short for take-off, one leg and landing");
  }
  return s;
}

json RunScenario(const config::ScenarioConfig& sc, const RunOptions& options,
                 const std::string& dir) {
  const double duration = options.duration > 0.0 ? options.duration : sc.duration;
  const bool manual = sc.leader_mode == "manual";
  const int nv = static_cast<int>(sc.vehicles.size());
  const formation::WaypointTrajectory trajectory = LeaderTrajectory(sc, options.seed);

  // ---- World. The autopilots' command-timeout failsafe is on: a vehicle whose controller
  // stops (fault kill_controller) is landed by its autopilot, as a real one would.
  sim::WorldConfig world_config = WorldConfigFor(sc, options.seed);
  world_config.command_timeout.enabled = true;
  sim::World world(world_config);
  const config::ScenarioFaults& faults = sc.faults;
  FaultInjector injector(faults, options.seed);
  std::vector<char> killed(nv, 0);
  std::vector<DownedLog> downed(nv);
  std::vector<double> prev_vz(nv, 0.0);
  long injected_failures = 0;

  // ---- Controllers (a manually moved leader has none).
  std::vector<std::unique_ptr<formation::VehicleController>> ctrl(nv);
  for (int i = 0; i < nv; ++i) {
    if (manual && i == sc.leader) continue;
    formation::ControllerConfig cc = ControllerConfigFor(sc, i, trajectory);
    cc.safety.injected_failure_rate = faults.solver_failure_rate;  // 0: off
    cc.safety.injected_failure_seed = options.seed;
    ctrl[i] = std::make_unique<formation::VehicleController>(cc);
  }

  // ---- Logs.
  std::filesystem::create_directories(dir);
  if (sc.reality.enabled) {
    // The true plant each vehicle flies (the controllers keep their vehicle files).
    for (int i = 0; i < nv; ++i) {
      const std::string path = PathInside(dir, "plant-" + sc.vehicles[i].name + ".yaml");
      try {
        config::SaveVehicleFile(world_config.vehicles[i].params, path);
      } catch (const std::exception& e) {
        throw std::runtime_error("cannot write " + path + ": " + e.what());
      }
    }
  }
  std::vector<VehicleLog> logs(nv);
  for (int i = 0; i < nv; ++i) {
    const auto& v = sc.vehicles[i];
    VehicleLog& L = logs[i];
    L.csv = std::make_unique<CheckedFile>(PathInside(dir, v.name + ".csv"));
    L.nb_errors.resize(v.neighbours.size());
    L.nb_steady.resize(v.neighbours.size());
    L.csv->Write(kVehicleLogCsvHeader);
  }
  fmt::memory_buffer row;  // one CSV row, reused
  std::string stopped;     // why the loop ended early ("interrupted"), empty: it did not
  std::string sim_error;   // the simulator's instability report

  const double dt = world.physics_dt();
  if (!(std::isfinite(duration) && duration > 0.0 && duration <= config::kMaxScenarioDuration)) {
    throw std::invalid_argument("[RunScenario] duration must be in (0, " +
                                std::to_string(config::kMaxScenarioDuration) + "] s, got " +
                                std::to_string(duration));
  }
  const int steps = static_cast<int>(std::lround(duration / dt));
  const int every = std::max(1, static_cast<int>(std::lround(sc.sample_time / dt)));
  double min_separation = kInf;
  std::vector<formation::ControlOutput> prev(nv);
  Measurement m;
  int next_progress = 0;

  for (int step = 0; step <= steps; ++step) {
    if (options.stop != nullptr && *options.stop != 0) {
      stopped = "interrupted";
      break;
    }
    const double t = world.time();
    if (manual) {
      Vec3 p, v;
      trajectory.Sample(t - sc.trajectory_start, &p, &v);
      world.SetState(sc.leader, sc.manual_start + p, Vec3(0, 0, sc.vehicles[sc.leader].yaw), v,
                     Vec3::Zero());
    }
    if (faults.motors_off.active() && t >= faults.motors_off.time - 1e-9 &&
        !world.GetAutopilotStatus(faults.motors_off.index).motors_killed) {
      world.KillMotors(faults.motors_off.index);
      if (options.progress) {
        std::fprintf(stderr, "\n%s t = %.2f s: motors of %s off (fault)\n", options.label.c_str(),
                     t, sc.vehicles[faults.motors_off.index].name.c_str());
      }
    }
    // A vehicle downed by a fault: its first ground contact (CoM within 1.5 cm of its
    // resting height), checked every physics step for the vertical speed at contact.
    for (int i = 0; i < nv; ++i) {
      const bool downed_by_fault = killed[i] != 0 || (faults.motors_off.index == i &&
                                                      world.GetAutopilotStatus(i).motors_killed);
      if (!downed_by_fault || !std::isnan(downed[i].impact_time)) continue;
      // Contact: the CoM within 1.5 cm of its resting height, or a hard or tilted impact that
      // the contact stops higher (CoM below 0.3 m above rest, about a tilted foot's reach, and
      // an upward jump of the vertical speed of more than 0.02 m/s in one 1 ms step: > 2 g of
      // contact deceleration). The speed is the one just before the contact.
      const sim::TrueState x = world.GetTrueState(i);
      const double z = x.position.z() - sim::World::kRestHeight;
      const bool jump = x.velocity.z() - prev_vz[i] > 0.02;
      if (z < 0.015 || (z < 0.3 && jump)) {
        downed[i].impact_time = t;
        downed[i].impact_vz = std::min(prev_vz[i], x.velocity.z());
        downed[i].impact_position = x.position;
      }
      prev_vz[i] = x.velocity.z();
    }
    while (world.PopMeasurement(&m)) {
      if (!injector.Filter(&m)) continue;
      for (int i = 0; i < nv; ++i) {
        if (ctrl[i] && !killed[i]) ctrl[i]->Process(m);
      }
    }
    if (step % every == 0) {
      std::vector<sim::TrueState> truth(nv);
      std::vector<Vec3> positions(nv);
      for (int i = 0; i < nv; ++i) {
        truth[i] = world.GetTrueState(i);
        positions[i] = truth[i].position;
      }
      for (int i = 0; i < nv; ++i) {
        for (int j = i + 1; j < nv; ++j) {
          min_separation = std::min(min_separation, (truth[i].position - truth[j].position).norm());
        }
      }
      // Leader reference and steady-state flag (formation window: trajectory start to landing).
      Vec3 ref_off, ref_v;
      trajectory.Sample(t - sc.trajectory_start, &ref_off, &ref_v);
      // Each vehicle's own window ends at its own landing (never at another one's).
      const bool settled = trajectory.TimeSinceStop(t - sc.trajectory_start) >= sc.settle_time;
      Vec3 leader_ref = Vec3::Constant(kNaN);
      if (manual) {
        leader_ref = sc.manual_start + ref_off;
      } else if (ctrl[sc.leader] && ctrl[sc.leader]->anchor().allFinite()) {
        leader_ref = ctrl[sc.leader]->anchor() + ref_off;
      }
      for (int i = 0; i < nv; ++i) {
        const auto& v = sc.vehicles[i];
        VehicleLog& L = logs[i];
        const bool window = t >= sc.trajectory_start && t < config::LandingTime(sc, i);
        const bool steady = window && settled;
        formation::ControlOutput out;
        if (faults.kill_controller.index == i && !killed[i] &&
            t >= faults.kill_controller.time - 1e-9) {
          killed[i] = 1;  // no more Process, Control or SetCommand: the autopilot is alone
          if (options.progress) {
            std::fprintf(stderr, "\n%s t = %.2f s: controller of %s killed (fault)\n",
                         options.label.c_str(), t, v.name.c_str());
          }
        }
        if (killed[i]) {
          out.time = t;
          if (std::isnan(L.touchdown_time) && std::isfinite(downed[i].impact_time)) {
            L.touchdown_time = downed[i].impact_time;
            L.touchdown_vz = downed[i].impact_vz;
          }
          L.motors_off = truth[i].rotor_rpm.norm() < 1.0;
        } else if (ctrl[i]) {
          out = ctrl[i]->Control(t);
          sim::AttitudeCommand cmd;
          cmd.thrust = out.thrust;
          cmd.throttle = out.throttle;
          cmd.roll = out.roll;
          cmd.pitch = out.pitch;
          cmd.yaw = out.yaw;
          world.SetCommand(i, cmd);
          ctrl[i]->Diagnose(&out);  // after the command: not on the command path
          if (out.recovery == formation::RecoveryAction::kReinitialise) ++L.reinitialisations;
          if (out.recovery == formation::RecoveryAction::kFailsafe) {
            L.failsafe_time = t;
            L.failsafe_reason = std::string(formation::ToString(out.recovery_reason));
            if (options.progress) {
              std::fprintf(stderr, "\n%s t = %.2f s: %s hands over to the failsafe (%s)\n",
                           options.label.c_str(), t, v.name.c_str(), L.failsafe_reason.c_str());
            }
          }
          if (out.nmpc) {
            if (formation::InjectedSolverFailure(ctrl[i]->config().safety, i, t, sc.sample_time))
              ++injected_failures;
            ++L.steps;
            if (std::isnan(L.first_step_time)) {
              L.first_step_time = out.solver_time;
              L.max_thrust_jump_at_switch = std::abs(out.thrust - prev[i].thrust);
            }
            L.solver_time.push_back(out.solver_time);
            L.solver_cpu.push_back(out.solver_cpu_time);
            if (out.solver_time > sc.sample_time) ++L.over_budget;
            if (out.fallback) ++L.fallbacks;
            if (out.status != rti::RtiStatus::kSuccess) ++L.failures;
            L.kkt.push_back(out.kkt);
            L.cost.push_back(out.cost);
          }
          if (out.guarded) ++L.guarded;
          // Touchdown: the first control step of the landing phase with the true CoM within
          // 1.5 cm of its resting height (the feet touch); its true vertical speed is kept.
          if ((out.phase == FlightPhase::kLanding || out.phase == FlightPhase::kLanded ||
               out.phase == FlightPhase::kFailsafe) &&
              std::isnan(L.touchdown_time) &&
              truth[i].position.z() < sim::World::kRestHeight + 0.015) {
            L.touchdown_vz = truth[i].velocity.z();
            L.touchdown_time = t;
          }
          if (out.phase == FlightPhase::kLanded) L.motors_off = true;
          // Motors off (fault): its touchdown is the impact, not what its controller sees
          // after the crash.
          if (faults.motors_off.index == i && std::isfinite(downed[i].impact_time)) {
            L.touchdown_time = downed[i].impact_time;
            L.touchdown_vz = downed[i].impact_vz;
          }
          prev[i] = out;
        } else {
          out.phase = FlightPhase::kNmpc;
          out.time = t;
        }
        const sim::TrueState& x = truth[i];
        // Flight envelope (from the truth): altitude above the ground and horizontal distance
        // from the start; the first excursion is kept.
        {
          const double altitude = x.position.z() - sim::World::kRestHeight;
          const Vec3 start = world_config.vehicles[static_cast<std::size_t>(i)].position;
          const double distance = (x.position - start).head<2>().norm();
          L.max_altitude = std::max(L.max_altitude, altitude);
          if (std::isnan(L.envelope_time) && (!(altitude <= sc.envelope.max_altitude) ||
                                              !(distance <= sc.envelope.max_distance))) {
            L.envelope_time = t;
            L.envelope_reason = fmt::format(
                "left the flight envelope at t = {:.2f} s: altitude {:.2f} m (max_altitude "
                "{:.2f}), "
                "{:.2f} m from its start (max_distance {:.2f}), at ({:.2f}, {:.2f}, {:.2f}) m",
                t, altitude, sc.envelope.max_altitude, distance, sc.envelope.max_distance,
                x.position.x(), x.position.y(), x.position.z());
          }
        }
        // Formation errors from the truth: (p_j - p_i) in the target frame minus d_j.
        // Every neighbour's error; the CSV has columns for the first two.
        std::array<Vec3, formation::kMaxNeighbours> rel, est_rel;
        rel.fill(Vec3::Constant(kNaN));
        est_rel.fill(Vec3::Constant(kNaN));
        std::array<double, formation::kMaxNeighbours> err;
        err.fill(kNaN);
        double ferr = kNaN;
        if (!v.leader) {
          ferr = FormationError(sc, i, positions, x.euler.z(), &err, &rel);
          for (std::size_t j = 0; j < v.neighbours.size(); ++j) {
            if (ctrl[i] && j < ctrl[i]->estimates().neighbours.size()) {
              est_rel[j] = ctrl[i]->estimates().neighbours[j].head<3>();
            }
            if (window) L.nb_errors[j].push_back(err[j]);
            if (steady) L.nb_steady[j].push_back(err[j]);
          }
          if (window) L.errors.push_back(ferr);
          if (t >= sc.takeoff_time && std::isnan(L.touchdown_time)) L.flight_errors.push_back(ferr);
          if (steady) L.steady_errors.push_back(ferr);
          if (window) L.samples.push_back({t, steady, err, out.active_neighbours});
        }
        double track = kNaN;
        if (v.leader && leader_ref.allFinite()) {
          track = (x.position - leader_ref).norm();
          if (window && !manual) L.tracking.push_back(track);
        }
        const auto& e = ctrl[i] ? ctrl[i]->estimates().own : estimation::VehicleEstimate{};
        const std::int64_t rej = ctrl[i] ? ctrl[i]->estimator_rejections() : 0;
        row.clear();
        fmt::format_to(
            std::back_inserter(row),
            "{:.3f},{},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
            "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
            "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
            "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
            "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
            "{:d},{:.6g},{:.6g},{:.6g},{:.6g},{},{},{:d},{},{:d},{},{:.4f},{:.4f},{},{},{},"
            "{:.5f},{:.5f},{:.5f}\n",
            t, killed[i] ? std::string_view("killed") : formation::ToString(out.phase),
            x.position.x(), x.position.y(), x.position.z(), x.velocity.x(), x.velocity.y(),
            x.velocity.z(), x.euler.x(), x.euler.y(), x.euler.z(), e.position.x(), e.position.y(),
            e.position.z(), e.velocity.x(), e.velocity.y(), e.velocity.z(), e.euler.x(),
            e.euler.y(), e.euler.z(), out.thrust, out.throttle, out.roll, out.pitch, out.yaw,
            out.nmpc_thrust, out.nmpc_roll, out.nmpc_pitch, leader_ref.x(), leader_ref.y(),
            leader_ref.z(), v.leader ? track : kNaN, rel[0].x(), rel[0].y(), rel[0].z(),
            est_rel[0].x(), est_rel[0].y(), est_rel[0].z(), err[0], rel[1].x(), rel[1].y(),
            rel[1].z(), est_rel[1].x(), est_rel[1].y(), est_rel[1].z(), err[1], ferr,
            steady ? 1 : 0, out.cost, out.kkt, out.solver_time, out.solver_cpu_time,
            out.sqp_iterations, out.qp_iterations, out.fallback ? 1 : 0, rti::ToString(out.status),
            out.guarded ? 1 : 0, rej, x.voltage, out.voltage, formation::ToString(out.recovery),
            formation::ToString(out.recovery_reason), out.active_neighbours, x.aero_force.x(),
            x.aero_force.y(), x.aero_force.z());
        L.csv->Write(std::string_view(row.data(), row.size()));
      }
      if (options.progress && t >= next_progress) {
        std::fprintf(stderr, "\r%s t = %5.1f / %.1f s", options.label.c_str(), t, duration);
        std::fflush(stderr);
        next_progress += 5;
      }
    }
    if (step < steps) {
      try {
        world.StepOnce();
      } catch (const sim::SimulationError& e) {
        sim_error = e.what();
        break;
      }
    }
  }
  if (options.progress)
    std::fprintf(stderr, "\r%s t = %5.1f / %.1f s\n", options.label.c_str(), duration, duration);

  // ---- Metrics.
  json vehicles = json::object();
  double steady_worst = kNaN, mean_worst = kNaN, max_worst = kNaN;
  double flight_mean_worst = kNaN, flight_max_worst = kNaN;
  std::vector<double> all_times;
  double time_max = 0.0, time_max_first = 0.0;
  long fallbacks = 0, failures = 0, over_budget = 0, nmpc_steps = 0, guarded = 0;
  long recoveries = 0, failsafes = 0;
  bool landed_safely = true;
  auto worse = [](double a, double b) {
    return std::isnan(a) ? b : (std::isnan(b) ? a : std::max(a, b));
  };
  for (int i = 0; i < nv; ++i) {
    const auto& v = sc.vehicles[i];
    VehicleLog& L = logs[i];
    L.csv->Finish();
    json j;
    j["role"] = v.leader ? "leader" : "follower";
    if (!v.leader) {
      j["formation_error_mean_m"] = Num(Mean(L.errors));
      j["formation_error_steady_state_mean_m"] = Num(Mean(L.steady_errors));
      j["formation_error_max_m"] = Num(Max(L.errors));
      j["formation_window_s"] = {sc.trajectory_start, config::LandingTime(sc, i)};
      j["formation_error_flight_mean_m"] = Num(Mean(L.flight_errors));
      j["formation_error_flight_max_m"] = Num(Max(L.flight_errors));
      j["steady_state_samples"] = L.steady_errors.size();
      json nbs = json::object();
      for (std::size_t n = 0; n < v.neighbours.size(); ++n) {
        nbs[v.neighbours[n].vehicle] = {{"mean_m", Num(Mean(L.nb_errors[n]))},
                                        {"steady_state_mean_m", Num(Mean(L.nb_steady[n]))},
                                        {"max_m", Num(Max(L.nb_errors[n]))}};
      }
      j["formation_error_by_neighbour"] = nbs;
      json order = json::array();  // CSV columns err0, err1 follow this order
      for (const auto& n : v.neighbours) order.push_back(n.vehicle);
      j["neighbours"] = order;
      steady_worst = worse(steady_worst, Mean(L.steady_errors));
      mean_worst = worse(mean_worst, Mean(L.errors));
      max_worst = worse(max_worst, Max(L.errors));
      flight_mean_worst = worse(flight_mean_worst, Mean(L.flight_errors));
      flight_max_worst = worse(flight_max_worst, Max(L.flight_errors));
    } else if (!manual) {
      j["tracking_error_mean_m"] = Num(Mean(L.tracking));
      j["tracking_error_max_m"] = Num(Max(L.tracking));
    }
    if (ctrl[i]) {
      // Step 0 of the NMPC carries the initial convergence (Algorithm 1: iterate to KKT <
      // threshold); it is included in the max and reported apart.
      j["nmpc_steps"] = L.steps;
      j["solver_time_median_s"] = Num(Median(L.solver_time));
      j["solver_time_max_s"] = Num(Max(L.solver_time));
      j["solver_cpu_time_max_s"] = Num(Max(L.solver_cpu));
      j["solver_time_first_step_s"] = Num(L.first_step_time);
      j["solver_steps_over_budget_share"] =
          L.steps > 0 ? static_cast<double>(L.over_budget) / static_cast<double>(L.steps) : 0.0;
      j["kkt_median"] = Num(Median(L.kkt));
      j["kkt_max"] = Num(Max(L.kkt));
      j["cost_median"] = Num(Median(L.cost));
      j["cost_max"] = Num(Max(L.cost));
      j["fallbacks"] = L.fallbacks;
      j["recoveries"] = L.reinitialisations;
      j["failsafes"] = std::isfinite(L.failsafe_time) ? 1 : 0;
      j["failsafe_time_s"] = Num(L.failsafe_time);
      j["failsafe_reason"] = L.failsafe_reason.empty() ? json(nullptr) : json(L.failsafe_reason);
      recoveries += L.reinitialisations;
      failsafes += std::isfinite(L.failsafe_time) ? 1 : 0;
      j["solver_failures"] = L.failures;
      j["guarded_commands"] = L.guarded;
      j["estimator_rejections"] = ctrl[i]->estimator_rejections();
      j["thrust_jump_at_switch_n"] = Num(L.max_thrust_jump_at_switch);
      const sim::TrueState x = world.GetTrueState(i);
      const double tilt =
          std::acos(std::clamp(std::cos(x.euler.x()) * std::cos(x.euler.y()), -1.0, 1.0));
      const bool touched = std::isfinite(L.touchdown_vz);
      const bool ok = touched && L.motors_off &&
                      std::abs(L.touchdown_vz) < sc.touchdown_speed_max &&
                      tilt < sc.max_tilt_landed && x.position.z() < sim::World::kRestHeight + 0.05;
      j["touchdown_time_s"] = Num(L.touchdown_time);
      j["touchdown_vertical_speed_mps"] = Num(L.touchdown_vz);
      j["final_tilt_rad"] = tilt;
      j["motors_off_at_end"] = L.motors_off;
      j["landed_safely"] = ok;
      landed_safely = landed_safely && ok;
      all_times.insert(all_times.end(), L.solver_time.begin(), L.solver_time.end());
      time_max = worse(time_max, Max(L.solver_time));
      if (L.solver_time.size() > 1) {
        time_max_first = worse(time_max_first,
                               *std::max_element(L.solver_time.begin() + 1, L.solver_time.end()));
      }
      fallbacks += L.fallbacks;
      failures += L.failures;
      over_budget += L.over_budget;
      nmpc_steps += L.steps;
      guarded += L.guarded;
    } else {
      j["moved_by_hand"] = true;
    }
    j["max_altitude_m"] = Num(L.max_altitude);
    j["left_envelope_time_s"] = Num(L.envelope_time);
    vehicles[v.name] = j;
  }
  // ---- Faults: what happened, per fault.
  json fj = json::object();
  std::vector<std::string> fault_lines;
  std::vector<int> downed_by;  // vehicles a fault took down (kill, motors off)
  auto vec2 = [](const Vec3& p) { return p.allFinite() ? json{p.x(), p.y()} : json(nullptr); };
  if (faults.kill_controller.active()) {
    const int k = faults.kill_controller.index;
    downed_by.push_back(k);
    const sim::AutopilotStatus ap = world.GetAutopilotStatus(k);
    const bool safe = vehicles[sc.vehicles[k].name].value("landed_safely", false);
    json j{{"vehicle", sc.vehicles[k].name},
           {"time_s", faults.kill_controller.time},
           {"autopilot_failsafe", ap.failsafe},
           {"autopilot_failsafe_time_s", Num(ap.failsafe_time)},
           {"autopilot_disarm_time_s", Num(ap.disarm_time)},
           {"touchdown_time_s", Num(downed[k].impact_time)},
           {"touchdown_vertical_speed_mps", Num(downed[k].impact_vz)},
           {"touchdown_position_m", vec2(downed[k].impact_position)},
           {"autopilot_landed", ap.disarmed_by_failsafe},
           {"landed_safely", safe}};
    // The other followers that had it as a neighbour: when it left their cost and their
    // errors to every neighbour after the kill and after the drop (window, steady state).
    json others = json::object();
    for (int i = 0; i < nv; ++i) {
      const auto& v = sc.vehicles[i];
      if (i == k || v.leader) continue;
      bool sees = false;
      for (const auto& n : v.neighbours) sees = sees || n.index == k;
      if (!sees) continue;
      const auto& smp = logs[i].samples;
      double dropped = kNaN;
      for (const auto& q : smp) {
        if (q.t >= faults.kill_controller.time &&
            q.active < static_cast<int>(v.neighbours.size())) {
          dropped = q.t;
          break;
        }
      }
      json errs = json::object();
      for (std::size_t n = 0; n < v.neighbours.size() && n < 2; ++n) {
        std::vector<double> after_kill, after_drop, after_kill_all;
        for (const auto& q : smp) {
          if (q.t < faults.kill_controller.time) continue;
          after_kill_all.push_back(q.err[n]);
          if (q.steady) after_kill.push_back(q.err[n]);
          if (q.steady && std::isfinite(dropped) && q.t >= dropped) after_drop.push_back(q.err[n]);
        }
        errs[v.neighbours[n].vehicle] = {{"mean_after_kill_m", Num(Mean(after_kill_all))},
                                         {"max_after_kill_m", Num(Max(after_kill_all))},
                                         {"steady_state_mean_after_kill_m", Num(Mean(after_kill))},
                                         {"steady_state_mean_after_drop_m", Num(Mean(after_drop))},
                                         {"steady_state_samples_after_drop", after_drop.size()}};
      }
      others[v.name] = {{"dropped_from_cost_s", Num(dropped)}, {"formation_error", errs}};
      fault_lines.push_back(fmt::format(
          "fault kill_controller: {} {}", v.name,
          std::isfinite(dropped) ? fmt::format("dropped {} from its cost at t = {:.2f} s",
                                               sc.vehicles[k].name, dropped)
                                 : fmt::format("kept {} in its cost", sc.vehicles[k].name)));
    }
    j["followers"] = others;
    fj["kill_controller"] = j;
    fault_lines.insert(
        fault_lines.begin(),
        fmt::format("fault kill_controller: {} at t = {:.2f} s; autopilot failsafe {}; "
                    "touchdown {} ; motors {} ; landed safely {}",
                    sc.vehicles[k].name, faults.kill_controller.time,
                    ap.failsafe ? fmt::format("at t = {:.2f} s", ap.failsafe_time) : "never",
                    std::isfinite(downed[k].impact_time)
                        ? fmt::format("at t = {:.2f} s, v_z {:.2f} m/s, at ({:.2f}, {:.2f}) m",
                                      downed[k].impact_time, downed[k].impact_vz,
                                      downed[k].impact_position.x(), downed[k].impact_position.y())
                        : std::string("none"),
                    ap.disarmed_by_failsafe ? fmt::format("off at t = {:.2f} s", ap.disarm_time)
                                            : std::string("not stopped by the autopilot"),
                    safe));
  }
  if (faults.motors_off.active()) {
    const int k = faults.motors_off.index;
    downed_by.push_back(k);
    fj["motors_off"] = {{"vehicle", sc.vehicles[k].name},
                        {"time_s", faults.motors_off.time},
                        {"impact_time_s", Num(downed[k].impact_time)},
                        {"impact_vertical_speed_mps", Num(downed[k].impact_vz)},
                        {"impact_position_m", vec2(downed[k].impact_position)}};
    fault_lines.push_back(fmt::format(
        "fault motors_off: {} at t = {:.2f} s; {}", sc.vehicles[k].name, faults.motors_off.time,
        std::isfinite(downed[k].impact_time)
            ? fmt::format(
                  "hit the ground at t = {:.2f} s with v_z {:.2f} m/s at ({:.2f}, {:.2f}) m",
                  downed[k].impact_time, downed[k].impact_vz, downed[k].impact_position.x(),
                  downed[k].impact_position.y())
            : std::string("did not reach the ground")));
  }
  if (!faults.sensor_dropouts.empty()) {
    json arr = json::array();
    for (std::size_t w = 0; w < faults.sensor_dropouts.size(); ++w) {
      const auto& d = faults.sensor_dropouts[w];
      arr.push_back({{"vehicle", d.vehicle},
                     {"sensor", std::string(ToString(d.sensor))},
                     {"from_s", d.from},
                     {"to_s", d.to},
                     {"dropped", injector.dropped(w)}});
      fault_lines.push_back(
          fmt::format("fault sensor_dropout: {} {} from {:.2f} to {:.2f} s: {} "
                      "measurements dropped",
                      d.vehicle, ToString(d.sensor), d.from, d.to, injector.dropped(w)));
    }
    fj["sensor_dropouts"] = arr;
  }
  if (faults.outlier_rate > 0.0) {
    fj["outliers"] = {{"rate", faults.outlier_rate},
                      {"size", faults.outlier_size},
                      {"measurements", injector.measurements()},
                      {"corrupted", injector.outliers()}};
    fault_lines.push_back(fmt::format("fault outliers: {} of {} measurements given an error of {}",
                                      injector.outliers(), injector.measurements(),
                                      faults.outlier_size));
  }
  if (faults.solver_failure_rate > 0.0) {
    fj["solver_failures"] = {{"rate", faults.solver_failure_rate},
                             {"injected", injected_failures},
                             {"nmpc_steps", nmpc_steps},
                             {"recoveries", recoveries},
                             {"failsafes", failsafes}};
    fault_lines.push_back(fmt::format(
        "fault solver_failures: {} of {} NMPC steps forced to fall back; {} re-initialisations, "
        "{} failsafes",
        injected_failures, nmpc_steps, recoveries, failsafes));
  }
  if (faults.any()) {
    bool others_safe = true;
    json names = json::array();
    for (int k : downed_by) names.push_back(sc.vehicles[k].name);
    for (int i = 0; i < nv; ++i) {
      if (std::find(downed_by.begin(), downed_by.end(), i) != downed_by.end()) continue;
      if (!ctrl[i]) continue;  // moved by hand
      others_safe = others_safe && vehicles[sc.vehicles[i].name].value("landed_safely", false);
    }
    fj["downed_vehicles"] = names;
    fj["landed_safely_except_downed"] = others_safe;
    for (const std::string& line : fault_lines) {
      std::fprintf(stderr, "%s %s\n", options.label.c_str(), line.c_str());
    }
  }

  // ---- Failures: why this run must not count as a success, per vehicle.
  const bool complete = stopped.empty() && sim_error.empty();
  json run_failures = json::array();
  for (int i = 0; i < nv; ++i) {
    const auto& v = sc.vehicles[i];
    const VehicleLog& L = logs[i];
    auto fail = [&](const std::string& reason) {
      run_failures.push_back({{"vehicle", v.name}, {"reason", reason}});
    };
    if (std::isfinite(L.envelope_time)) fail(L.envelope_reason);
    const bool downed_by_fault =
        std::find(downed_by.begin(), downed_by.end(), i) != downed_by.end();
    if (!ctrl[i] || downed_by_fault) continue;  // moved by hand, or downed on purpose
    const double takeoff_height =
        std::isfinite(v.takeoff_height) ? v.takeoff_height : sc.takeoff_height;
    if (complete && !(L.max_altitude >= 0.5 * takeoff_height)) {
      fail(fmt::format("never took off: highest altitude {:.3f} m, take-off height {:.2f} m",
                       L.max_altitude, takeoff_height));
    }
    if (std::isfinite(L.failsafe_time)) {
      fail(fmt::format("failsafe at t = {:.2f} s ({})", L.failsafe_time, L.failsafe_reason));
    }
    const json& vj = vehicles[v.name];
    if (complete && !vj.value("landed_safely", false)) {
      fail(fmt::format(
          "not landed safely at the end: touchdown vertical speed {} (max {} m/s), motors off "
          "{}, final tilt {:.3f} rad (max {})",
          vj["touchdown_vertical_speed_mps"].is_number()
              ? fmt::format("{:.3f} m/s", vj["touchdown_vertical_speed_mps"].get<double>())
              : std::string("none (no touchdown)"),
          sc.touchdown_speed_max, vj.value("motors_off_at_end", false),
          vj.value("final_tilt_rad", kNaN), sc.max_tilt_landed));
    }
  }

  json s;
  s["scenario"] = sc.name;
  s["complete"] = complete;
  if (!stopped.empty()) s["stopped"] = stopped;
  if (!sim_error.empty()) s["error"] = sim_error;
  s["failures"] = run_failures;
  s["warnings"] = sc.warnings;
  s["seed"] = options.seed;
  s["duration_s"] = duration;
  s["downwash"] = sc.downwash;
  s["reality"] = sc.reality.enabled;
  // The scenario's default window; a follower with its own landing_time uses its own
  // (vehicles.<name>.formation_window_s).
  s["formation_window_s"] = {sc.trajectory_start, sc.landing_time};
  s["steady_state_formation_error_m"] = Num(steady_worst);
  s["mean_formation_error_m"] = Num(mean_worst);
  s["max_formation_error_m"] = Num(max_worst);
  s["mean_formation_error_flight_m"] = Num(flight_mean_worst);
  s["max_formation_error_flight_m"] = Num(flight_max_worst);
  s["solver_time_max_s"] = Num(time_max);
  s["solver_time_max_after_first_step_s"] = Num(time_max_first);
  s["solver_time_median_s"] = Num(Median(all_times));
  s["solver_steps_over_budget_share"] =
      nmpc_steps > 0 ? static_cast<double>(over_budget) / static_cast<double>(nmpc_steps) : 0.0;
  s["sample_time_s"] = sc.sample_time;
  s["nmpc_steps"] = nmpc_steps;
  s["fallbacks"] = fallbacks;
  s["recoveries"] = recoveries;
  s["failsafes"] = failsafes;
  s["solver_failures"] = failures;
  s["solver_converged_every_step"] = failures == 0 && fallbacks == 0 && nmpc_steps > 0;
  s["guarded_commands"] = guarded;
  s["min_separation_m"] = Num(min_separation);
  s["landed_safely"] = landed_safely;
  s["vehicles"] = vehicles;
  if (faults.any()) s["faults"] = fj;
  WriteFileAtomically(PathInside(dir, "summary.json"),
                      s.dump(2, ' ', false, json::error_handler_t::replace) + "\n");
  return s;
}

json AggregateRuns(const std::vector<json>& runs) {
  json a;
  if (runs.empty()) return a;
  auto values = [&runs](const std::string& key) {
    std::vector<double> v;
    for (const json& r : runs) {
      if (r.contains(key) && r[key].is_number()) v.push_back(r[key].get<double>());
    }
    return v;
  };
  a["scenario"] = runs.front()["scenario"];
  a["runs"] = runs.size();
  for (const char* k : {"steady_state_formation_error_m", "mean_formation_error_m",
                        "solver_time_median_s", "solver_steps_over_budget_share"}) {
    a[k] = Num(Mean(values(k)));
  }
  for (const char* k :
       {"max_formation_error_m", "max_formation_error_flight_m", "mean_formation_error_flight_m",
        "solver_time_max_s", "solver_time_max_after_first_step_s", "fallbacks", "recoveries",
        "failsafes", "solver_failures", "guarded_commands"}) {
    a[k] = Num(Max(values(k)));
  }
  {
    const auto v = values("min_separation_m");
    a["min_separation_m"] = v.empty() ? json(nullptr) : json(*std::min_element(v.begin(), v.end()));
  }
  a["steady_state_formation_error_worst_run_m"] =
      Num(Max(values("steady_state_formation_error_m")));
  bool landed = true, converged = true;
  for (const json& r : runs) {
    landed = landed && r.value("landed_safely", false);
    converged = converged && r.value("solver_converged_every_step", false);
  }
  a["landed_safely"] = landed;
  bool complete = true;
  json failures = json::array();
  for (std::size_t r = 0; r < runs.size(); ++r) {
    complete = complete && runs[r].value("complete", false);
    if (!runs[r].contains("failures")) continue;
    for (json f : runs[r]["failures"]) {
      f["run"] = runs[r].value("dir", std::to_string(r + 1));
      failures.push_back(f);
    }
  }
  a["complete"] = complete;
  a["failures"] = failures;
  a["warnings"] = runs.front().value("warnings", json::array());
  a["solver_converged_every_step"] = converged;
  a["sample_time_s"] = runs.front()["sample_time_s"];
  a["formation_window_s"] = runs.front()["formation_window_s"];
  a["aggregation"] =
      "means: mean over runs; max_*, solver_time_max_*, fallbacks, failures: worst run; "
      "min_separation_m: smallest; flags: all runs";
  a["run_summaries"] = runs;
  return a;
}

}  // namespace fnmpc::app
