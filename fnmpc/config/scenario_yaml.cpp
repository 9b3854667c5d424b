// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/scenario_yaml.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

#include "fnmpc/config/sensors_yaml.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"

namespace fnmpc::config {

namespace {

std::string Resolve(const YamlMap& m, const std::string& path) {
  if (path.empty() || std::filesystem::path(path).is_absolute() || m.directory().empty())
    return path;
  return (std::filesystem::path(m.directory()) / path).lexically_normal().string();
}

double Positive(YamlMap& m, const std::string& key, double fallback) {
  const double v = m.Double(key, fallback);
  if (!(v > 0.0) || !std::isfinite(v))
    throw m.ErrorAt(key, "must be > 0, got " + std::to_string(v));
  return v;
}

double NonNegative(YamlMap& m, const std::string& key, double fallback) {
  const double v = m.Double(key, fallback);
  if (!(v >= 0.0) || !std::isfinite(v))
    throw m.ErrorAt(key, "must be >= 0, got " + std::to_string(v));
  return v;
}

Vec3 Positive3(YamlMap& m, const std::string& key, const Vec3& fallback) {
  const Vec3 v = m.Vector3(key, fallback);
  if (!(v.array() > 0.0).all() || !v.allFinite()) throw m.ErrorAt(key, "every entry must be > 0");
  return v;
}

std::pair<double, double> Range(YamlMap& m, const std::string& key, double lo, double hi) {
  if (!m.Has(key)) return {lo, hi};
  const std::vector<double> v = m.Doubles(key, 2);
  if (!(v[0] >= 0.0 && v[1] >= v[0]))
    throw m.ErrorAt(key, "must be [min, max] with 0 <= min <= max");
  return {v[0], v[1]};
}

ScenarioWeights ParseWeights(YamlMap m) {
  ScenarioWeights w;
  auto nonneg3 = [&m](const std::string& key, const Vec3& fallback) {
    const Vec3 v = m.Vector3(key, fallback);
    if (!(v.array() >= 0.0).all()) throw m.ErrorAt(key, "weights must be >= 0");
    return v;
  };
  w.position = nonneg3("position", w.position);
  w.velocity = nonneg3("velocity", w.velocity);
  w.attitude = NonNegative(m, "attitude", w.attitude);
  w.thrust = Positive(m, "thrust", w.thrust);
  w.attitude_ref = Positive(m, "attitude_ref", w.attitude_ref);
  w.terminal_factor = NonNegative(m, "terminal_factor", w.terminal_factor);
  w.thrust_rate = NonNegative(m, "thrust_rate", w.thrust_rate);
  w.attitude_ref_rate = NonNegative(m, "attitude_ref_rate", w.attitude_ref_rate);
  w.collision = NonNegative(m, "collision", w.collision);
  m.Finish();
  return w;
}

/// Index of the vehicle named by `key` of `m`; an error at that key when unknown.
int VehicleIndex(YamlMap& m, const std::string& key, const ScenarioConfig& s, std::string* name) {
  *name = m.String(key);
  for (std::size_t i = 0; i < s.vehicles.size(); ++i) {
    if (s.vehicles[i].name == *name) return static_cast<int>(i);
  }
  throw m.ErrorAt(key, "unknown vehicle '" + *name + "'");
}

/// A time inside the run, [0, duration) [s].
double RunTime(YamlMap& m, const std::string& key, const ScenarioConfig& s) {
  const double t = m.Double(key);
  if (!(t >= 0.0 && t < s.duration))
    throw m.ErrorAt(key, "must be in [0, duration) s, got " + std::to_string(t));
  return t;
}

double Share(YamlMap& m, const std::string& key) {
  const double p = m.Double(key);
  if (!(p >= 0.0 && p <= 1.0)) throw m.ErrorAt(key, "must be in [0, 1], got " + std::to_string(p));
  return p;
}

VehicleFault ParseVehicleFault(YamlMap m, const ScenarioConfig& s) {
  VehicleFault f;
  f.index = VehicleIndex(m, "vehicle", s, &f.vehicle);
  f.time = RunTime(m, "time", s);
  m.Finish();
  return f;
}

ScenarioFaults ParseFaults(YamlMap fm, const ScenarioConfig& s) {
  ScenarioFaults f;
  if (fm.Has("kill_controller")) {
    f.kill_controller = ParseVehicleFault(fm.Map("kill_controller"), s);
    if (s.leader_mode == "manual" && f.kill_controller.index == s.leader) {
      throw fm.ErrorAt("kill_controller", "the manually moved leader has no controller to kill");
    }
  }
  if (fm.Has("motors_off")) f.motors_off = ParseVehicleFault(fm.Map("motors_off"), s);
  if (fm.Has("sensor_dropouts")) {
    for (YamlMap& dm : fm.MapList("sensor_dropouts")) {
      SensorDropoutWindow w;
      w.index = VehicleIndex(dm, "vehicle", s, &w.vehicle);
      const std::string sensor = dm.String("sensor");
      bool known = false;
      for (int k = 0; k < kNumSensorKinds; ++k) {
        if (ToString(static_cast<SensorKind>(k)) == sensor) {
          w.sensor = static_cast<SensorKind>(k);
          known = true;
        }
      }
      if (!known) {
        throw dm.ErrorAt(
            "sensor",
            "must be mocap, imu, optical_flow, compass, battery or relative, got '" + sensor + "'");
      }
      w.from = RunTime(dm, "from", s);
      w.to = dm.Double("to");
      if (!(w.to > w.from) || !std::isfinite(w.to))
        throw dm.ErrorAt("to", "must be finite and after 'from', got " + std::to_string(w.to));
      dm.Finish();
      f.sensor_dropouts.push_back(w);
    }
  }
  if (fm.Has("outliers")) {
    YamlMap om = fm.Map("outliers");
    f.outlier_rate = Share(om, "rate");
    f.outlier_size = om.Double("size");
    if (!(f.outlier_size > 0.0) || !std::isfinite(f.outlier_size))
      throw om.ErrorAt("size", "must be > 0 and finite, got " + std::to_string(f.outlier_size));
    om.Finish();
  }
  if (fm.Has("solver_failures")) {
    YamlMap sm = fm.Map("solver_failures");
    f.solver_failure_rate = Share(sm, "rate");
    sm.Finish();
  }
  fm.Finish();
  return f;
}

}  // namespace

ScenarioConfig ParseScenario(YamlMap map) {
  ScenarioConfig s;
  s.file = map.file();
  s.name = map.String("name");
  if (s.name.empty()) throw map.ErrorAt("name", "must not be empty");
  s.description = map.String("description", "");
  s.duration = Positive(map, "duration", s.duration);
  {
    const int seed = map.Int("seed", 1);
    if (seed < 0) throw map.ErrorAt("seed", "must be >= 0");
    s.seed = static_cast<std::uint64_t>(seed);
  }
  s.downwash = map.Bool("downwash", s.downwash);
  s.battery_sag = map.Bool("battery_sag", s.battery_sag);
  const std::string vehicle_file = Resolve(map, map.String("vehicle_file"));
  const std::string sensors_file = Resolve(map, map.String("sensors_file", ""));
  const model::VehicleParams default_params = LoadVehicleFile(vehicle_file);
  const SensorsConfig default_sensors =
      sensors_file.empty() ? SensorsConfig{} : LoadSensorsFile(sensors_file);

  // ---- Vehicles.
  std::vector<YamlMap> vmaps = map.MapList("vehicles");
  if (vmaps.size() < 2)
    throw map.ErrorAt("vehicles", "need at least two vehicles (a leader and a follower)");
  std::map<std::string, int> index;
  std::vector<std::vector<std::pair<YamlMap, std::string>>> pending(vmaps.size());
  for (std::size_t i = 0; i < vmaps.size(); ++i) {
    YamlMap& vm = vmaps[i];
    ScenarioVehicle v;
    v.name = vm.String("name");
    if (v.name.empty() || index.count(v.name) > 0)
      throw vm.ErrorAt("name", "must be unique and non-empty");
    index[v.name] = static_cast<int>(i);
    const std::string role = vm.String("role");
    if (role != "leader" && role != "follower") {
      throw vm.ErrorAt("role", "must be 'leader' or 'follower', got '" + role + "'");
    }
    v.leader = role == "leader";
    const std::vector<double> start = vm.Doubles("start", 2);
    v.start = Vec3(start[0], start[1], 0.0);
    v.yaw = vm.Double("yaw", 0.0);
    if (vm.Has("landing_time")) v.landing_time = Positive(vm, "landing_time", 1.0);
    if (vm.Has("takeoff_height")) {
      v.takeoff_height = Positive(vm, "takeoff_height", 1.0);
      if (v.takeoff_height < 0.3) throw vm.ErrorAt("takeoff_height", "must be >= 0.3 m");
    }
    v.params = vm.Has("vehicle_file") ? LoadVehicleFile(Resolve(vm, vm.String("vehicle_file")))
                                      : default_params;
    v.sensors = vm.Has("sensors_file") ? LoadSensorsFile(Resolve(vm, vm.String("sensors_file")))
                                       : default_sensors;
    if (v.leader) {
      if (s.leader >= 0) throw vm.ErrorAt("role", "only one leader is allowed");
      s.leader = static_cast<int>(i);
      if (vm.Has("neighbours")) throw vm.ErrorAt("neighbours", "the leader has no neighbours");
    } else {
      const std::string frame = vm.String("frame", "m");
      if (frame != "m" && frame != "c")
        throw vm.ErrorAt("frame", "must be 'm' or 'c', got '" + frame + "'");
      v.frame_control = frame == "c";
      v.relative_position_bound =
          Positive3(vm, "relative_position_bound", v.relative_position_bound);
      std::vector<YamlMap> nmaps = vm.MapList("neighbours");
      if (nmaps.empty() || nmaps.size() > 2) {
        throw vm.ErrorAt("neighbours",
                         "a follower needs 1 or 2 neighbours, got " + std::to_string(nmaps.size()));
      }
      for (YamlMap& nm : nmaps) {
        ScenarioNeighbour n;
        n.vehicle = nm.String("vehicle");
        n.desired = nm.Vector3("desired");
        if (!n.desired.allFinite()) throw nm.ErrorAt("desired", "must be finite");
        v.neighbours.push_back(n);
        pending[i].emplace_back(nm, n.vehicle);
      }
    }
    s.vehicles.push_back(v);
  }
  if (s.leader < 0) throw map.ErrorAt("vehicles", "exactly one vehicle must have role: leader");
  for (std::size_t i = 0; i < vmaps.size(); ++i) {
    for (std::size_t j = 0; j < pending[i].size(); ++j) {
      auto& [nm, name] = pending[i][j];
      const auto it = index.find(name);
      if (it == index.end()) throw nm.ErrorAt("vehicle", "unknown vehicle '" + name + "'");
      if (it->second == static_cast<int>(i))
        throw nm.ErrorAt("vehicle", "a vehicle cannot be its own neighbour");
      s.vehicles[i].neighbours[j].index = it->second;
      nm.Finish();
    }
    vmaps[i].Finish();
  }
  for (std::size_t i = 0; i < s.vehicles.size(); ++i) {
    for (std::size_t j = i + 1; j < s.vehicles.size(); ++j) {
      if ((s.vehicles[i].start - s.vehicles[j].start).norm() < 0.6) {
        throw map.ErrorAt("vehicles", "start positions of '" + s.vehicles[i].name + "' and '" +
                                          s.vehicles[j].name + "' are closer than 0.6 m");
      }
    }
  }

  // ---- Leader motion.
  {
    YamlMap lm = map.Map("leader");
    s.leader_mode = lm.String("mode");
    s.trajectory_start = Positive(lm, "start_time", s.trajectory_start);
    if (s.leader_mode == "waypoints") {
      YAML::Node wp = lm.Node("waypoints");
      if (!wp.IsSequence() || wp.size() < 2)
        throw lm.ErrorAt("waypoints", "need a list of at least two [x, y, z]");
      for (const auto& p : wp) {
        if (!p.IsSequence() || p.size() != 3)
          throw lm.ErrorAt("waypoints", "each waypoint is [x, y, z] in m");
        try {
          s.waypoints.emplace_back(p[0].as<double>(), p[1].as<double>(), p[2].as<double>());
        } catch (const YAML::Exception&) {
          throw lm.ErrorAt("waypoints", "waypoint entries must be numbers");
        }
      }
      s.leg_duration = Positive(lm, "leg_duration", s.leg_duration);
      s.hold_duration = NonNegative(lm, "hold_duration", s.hold_duration);
    } else if (s.leader_mode == "manual") {
      s.manual_start = lm.Vector3("position", s.manual_start);
      s.walk_box = Positive3(lm, "box", s.walk_box);
      s.walk_moves = lm.Int("moves", s.walk_moves);
      if (s.walk_moves < 1) throw lm.ErrorAt("moves", "must be >= 1");
      std::tie(s.walk_min_leg, s.walk_max_leg) =
          Range(lm, "move_duration", s.walk_min_leg, s.walk_max_leg);
      if (!(s.walk_min_leg > 0.0)) throw lm.ErrorAt("move_duration", "minimum must be > 0");
      std::tie(s.walk_min_hold, s.walk_max_hold) =
          Range(lm, "pause_duration", s.walk_min_hold, s.walk_max_hold);
    } else {
      throw lm.ErrorAt("mode", "must be 'waypoints' or 'manual', got '" + s.leader_mode + "'");
    }
    lm.Finish();
  }

  // ---- Controller.
  if (map.Has("controller")) {
    YamlMap cm = map.Map("controller");
    s.sample_time = Positive(cm, "sample_time", s.sample_time);
    s.horizon = cm.Int("horizon", s.horizon);
    if (s.horizon < 1 || s.horizon > 100) throw cm.ErrorAt("horizon", "must be in [1, 100]");
    s.integrator_steps = cm.Int("integrator_steps", s.integrator_steps);
    if (s.integrator_steps < 1) throw cm.ErrorAt("integrator_steps", "must be >= 1");
    s.max_iterations = cm.Int("max_iterations", s.max_iterations);
    if (s.max_iterations < 1) throw cm.ErrorAt("max_iterations", "must be >= 1");
    s.max_initial_iterations = cm.Int("max_initial_iterations", s.max_initial_iterations);
    if (s.max_initial_iterations < 1) throw cm.ErrorAt("max_initial_iterations", "must be >= 1");
    s.kkt_threshold = Positive(cm, "kkt_threshold", s.kkt_threshold);
    s.cpu_budget = Positive(cm, "cpu_budget", s.sample_time);
    s.use_throttle = cm.Bool("use_throttle", s.use_throttle);
    if (cm.Has("bounds")) {
      YamlMap bm = cm.Map("bounds");
      if (bm.Has("thrust")) {
        const std::vector<double> t = bm.Doubles("thrust", 2);
        if (!(t[0] >= 0.0 && t[1] > t[0]))
          throw bm.ErrorAt("thrust", "must be [min, max] with 0 <= min < max");
        s.thrust_min = t[0];
        s.thrust_max = t[1];
      }
      s.max_attitude_ref = Positive(bm, "attitude_ref", s.max_attitude_ref);
      if (s.max_attitude_ref >= 1.2) throw bm.ErrorAt("attitude_ref", "must be < 1.2 rad");
      s.max_speed = Positive(bm, "speed", s.max_speed);
      bm.Finish();
    }
    if (cm.Has("weights")) {
      YamlMap wm = cm.Map("weights");
      if (wm.Has("leader")) s.leader_weights = ParseWeights(wm.Map("leader"));
      if (wm.Has("follower")) s.follower_weights = ParseWeights(wm.Map("follower"));
      wm.Finish();
    }
    cm.Finish();
  }

  // ---- Phases.
  if (map.Has("phases")) {
    YamlMap pm = map.Map("phases");
    s.takeoff_time = NonNegative(pm, "takeoff_time", s.takeoff_time);
    s.takeoff_height = Positive(pm, "takeoff_height", s.takeoff_height);
    if (s.takeoff_height < 0.3) throw pm.ErrorAt("takeoff_height", "must be >= 0.3 m");
    s.climb_speed = Positive(pm, "climb_speed", s.climb_speed);
    s.hover_before_switch = NonNegative(pm, "hover_before_switch", s.hover_before_switch);
    s.blend_time = NonNegative(pm, "blend_time", s.blend_time);
    s.landing_time = Positive(pm, "landing_time", s.landing_time);
    s.descent_speed = Positive(pm, "descent_speed", s.descent_speed);
    pm.Finish();
  }
  if (!(s.landing_time > s.trajectory_start && s.landing_time < s.duration)) {
    throw map.Error("phases.landing_time must lie between leader.start_time and duration");
  }
  if (!(s.trajectory_start > s.takeoff_time))
    throw map.Error("leader.start_time must be after phases.takeoff_time");
  for (const ScenarioVehicle& v : s.vehicles) {
    if (std::isfinite(v.landing_time) &&
        !(v.landing_time > s.trajectory_start && v.landing_time < s.duration)) {
      throw map.Error("vehicle '" + v.name +
                      "': landing_time must lie between leader.start_time and duration");
    }
  }

  // ---- Safety (formation::SafetyConfig, defaults there).
  if (map.Has("safety")) {
    YamlMap sm = map.Map("safety");
    formation::SafetyConfig& f = s.safety;
    f.min_altitude = NonNegative(sm, "min_altitude", f.min_altitude);
    f.max_altitude = Positive(sm, "max_altitude", f.max_altitude);
    if (!(f.max_altitude > f.min_altitude))
      throw sm.ErrorAt("max_altitude", "must be above min_altitude");
    f.neighbour_timeout = Positive(sm, "neighbour_timeout", f.neighbour_timeout);
    f.neighbour_reacquire_time =
        NonNegative(sm, "neighbour_reacquire_time", f.neighbour_reacquire_time);
    f.collision_radius = NonNegative(sm, "collision_radius", f.collision_radius);
    if (f.collision_radius > 10.0) throw sm.ErrorAt("collision_radius", "must be <= 10 m");
    if (sm.Has("recovery")) {
      YamlMap rm = sm.Map("recovery");
      formation::RecoveryConfig& r = f.recovery;
      r.fallbacks_before_reinit = rm.Int("fallbacks_before_reinit", r.fallbacks_before_reinit);
      if (r.fallbacks_before_reinit < 1 || r.fallbacks_before_reinit > 1000)
        throw rm.ErrorAt("fallbacks_before_reinit", "must be in [1, 1000]");
      r.max_reinitialisations = rm.Int("max_reinitialisations", r.max_reinitialisations);
      if (r.max_reinitialisations < 0 || r.max_reinitialisations > 1000)
        throw rm.ErrorAt("max_reinitialisations", "must be in [0, 1000]");
      r.estimate_timeout = Positive(rm, "estimate_timeout", r.estimate_timeout);
      r.failsafe_hold_time = NonNegative(rm, "failsafe_hold_time", r.failsafe_hold_time);
      r.failsafe_descent_speed = Positive(rm, "failsafe_descent_speed", r.failsafe_descent_speed);
      if (r.failsafe_descent_speed > 1.5)
        throw rm.ErrorAt("failsafe_descent_speed", "must be <= 1.5 m/s");
      rm.Finish();
    }
    sm.Finish();
  }

  // ---- Faults (after the vehicles, the leader mode and the duration they refer to).
  if (map.Has("faults")) s.faults = ParseFaults(map.Map("faults"), s);

  if (map.Has("metrics")) {
    YamlMap mm = map.Map("metrics");
    s.settle_time = NonNegative(mm, "settle_time", s.settle_time);
    s.touchdown_speed_max = Positive(mm, "touchdown_speed_max", s.touchdown_speed_max);
    s.max_tilt_landed = Positive(mm, "max_tilt_landed", s.max_tilt_landed);
    mm.Finish();
  }
  map.Finish();
  return s;
}

double LandingTime(const ScenarioConfig& s, int i) {
  const double t = s.vehicles[static_cast<std::size_t>(i)].landing_time;
  return std::isfinite(t) ? t : s.landing_time;
}

double FormationWindowEnd(const ScenarioConfig& s) {
  double t = s.landing_time;
  for (std::size_t i = 0; i < s.vehicles.size(); ++i)
    t = std::min(t, LandingTime(s, static_cast<int>(i)));
  return t;
}

ScenarioConfig LoadScenarioFile(const std::string& path) {
  return ParseScenario(YamlMap::LoadFile(path));
}

}  // namespace fnmpc::config
