// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/scenario_yaml.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>

#include "fnmpc/config/sensors_yaml.hpp"
#include "fnmpc/config/settings_yaml.hpp"
#include "fnmpc/config/text_file.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/formation/formation_shape.hpp"

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

/// A desired offset outside the follower's own soft bound on that neighbour's relative
/// position: the NMPC is pulled between the two and holds neither (a generated circle with
/// 8 ties flew 2.8 m off, docs/scenarios.md "formation"). "" when it fits.
std::string BoundConflict(const ScenarioVehicle& v, const ScenarioNeighbour& n) {
  if ((n.desired.cwiseAbs().array() <= v.relative_position_bound.array()).all()) return "";
  std::ostringstream os;
  os << "the desired offset (" << n.desired.x() << ", " << n.desired.y() << ", " << n.desired.z()
     << ") m of '" << v.name << "' to neighbour '" << n.vehicle
     << "' lies outside its relative_position_bound (" << v.relative_position_bound.x() << ", "
     << v.relative_position_bound.y() << ", " << v.relative_position_bound.z()
     << ") m: the soft bound pulls the follower off its place";
  return os.str();
}

std::pair<double, double> Range(YamlMap& m, const std::string& key, double lo, double hi) {
  if (!m.Has(key)) return {lo, hi};
  const std::vector<double> v = m.Doubles(key, 2);
  if (!(v[0] >= 0.0 && v[1] >= v[0]))
    throw m.ErrorAt(key, "must be [min, max] with 0 <= min <= max");
  return {v[0], v[1]};
}

/// Loads a file the scenario refers to by `key`; its errors (which carry the referenced file's
/// own place) are prefixed with the place of the reference.
template <typename Load>
auto Referenced(YamlMap& m, const std::string& key, const Load& load) {
  try {
    return load();
  } catch (const ConfigError& e) {
    throw m.ErrorAt(key, e.what());
  }
}

/// A name that becomes part of a file or folder name: an identifier (IsIdentifier).
std::string Identifier(YamlMap& m, const std::string& key) {
  const std::string name = m.String(key);
  if (!IsIdentifier(name)) {
    throw m.ErrorAt(
        key, "must be 1 to 64 letters, digits, '-' or '_' (it names files), got '" + name + "'");
  }
  return name;
}

/// An integer in [lo, hi].
int IntIn(YamlMap& m, const std::string& key, int fallback, int lo, int hi) {
  const int v = m.Int(key, fallback);
  if (v < lo || v > hi) {
    throw m.ErrorAt(key, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                             "], got " + std::to_string(v));
  }
  return v;
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

/// What the `reality:` block's Serialize cannot say alone: the turbulence block's two forms,
/// its airspeed without a mean wind and the gust times inside the run.
void CheckReality(SettingsReader& reader, const ScenarioConfig& s) {
  const ScenarioReality& r = s.reality;
  if (YamlMap* t = reader.At("reality.wind.turbulence")) {
    if (t->Has("w20")) {
      if (t->Has("sigma") || t->Has("length_scale"))
        throw t->ErrorAt("w20", "give either w20 and height or sigma and length_scale");
      if (!t->Has("height")) throw t->ErrorAt("height", "missing required key (with w20)");
    } else {
      if (t->Has("height")) throw t->ErrorAt("height", "only with w20");
      if (!t->Has("sigma")) throw t->ErrorAt("sigma", "missing required key (or w20 and height)");
    }
    if (!std::isfinite(r.turbulence.airspeed) && !(r.wind.velocity.norm() > 0.0))
      throw t->Error("turbulence without a mean wind needs 'airspeed' (m/s) for the spectra");
  }
  // The plant draw of every vehicle without a plant file, for the scenario's seed: a spread
  // that cannot give a physical body (model::PlantDrawError) is refused here, at its line.
  for (std::size_t i = 0; i < s.vehicles.size(); ++i) {
    const ScenarioVehicle& v = s.vehicles[i];
    if (v.has_plant) continue;
    try {
      model::DrawTruePlant(v.params, model::TruePlant().motor_time_constant, r.plant, s.seed,
                           static_cast<int>(i));
    } catch (const model::PlantDrawError& e) {
      const std::string what =
          "vehicle '" + v.name + "' (seed " + std::to_string(s.seed) + "): " + e.what();
      if (YamlMap* plant = reader.At("reality.plant")) throw plant->ErrorAt(e.key(), what);
      throw reader.Required("reality").ErrorAt(
          "plant", "the default reality.plant." + e.key() + ": " + what);
    }
  }
  for (std::size_t i = 0; i < r.wind.discrete_gusts.size(); ++i) {
    const double time = r.wind.discrete_gusts[i].start;
    if (!(time < s.duration)) {
      throw reader.Required("reality.wind.discrete_gusts[" + std::to_string(i) + "]")
          .ErrorAt("time", "must be in [0, duration) s, got " + std::to_string(time));
    }
  }
}

// `vehicles:`, one by one; neighbours by name.
void ListedVehicles(YamlMap& map, const model::VehicleParams& default_params,
                    const SensorsConfig& default_sensors, ScenarioConfig* scenario) {
  ScenarioConfig& s = *scenario;
  std::vector<YamlMap> vmaps = map.MapList("vehicles");
  if (vmaps.empty()) throw map.ErrorAt("vehicles", "need at least one vehicle (the leader)");
  if (vmaps.size() > static_cast<std::size_t>(kMaxVehicles))
    throw map.ErrorAt("vehicles", "at most " + std::to_string(kMaxVehicles) + " vehicles");
  std::map<std::string, int> index;
  std::vector<std::vector<std::pair<YamlMap, std::string>>> pending(vmaps.size());
  for (std::size_t i = 0; i < vmaps.size(); ++i) {
    YamlMap& vm = vmaps[i];
    ScenarioVehicle v;
    v.name = Identifier(vm, "name");
    if (index.count(v.name) > 0)
      throw vm.ErrorAt("name", "must be unique, '" + v.name + "' is not");
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
    v.params =
        vm.Has("vehicle_file")
            ? Referenced(vm, "vehicle_file",
                         [&] { return LoadVehicleFile(Resolve(vm, vm.String("vehicle_file"))); })
            : default_params;
    v.sensors =
        vm.Has("sensors_file")
            ? Referenced(vm, "sensors_file",
                         [&] { return LoadSensorsFile(Resolve(vm, vm.String("sensors_file"))); })
            : default_sensors;
    if (vm.Has("plant_file")) {
      v.plant = Referenced(vm, "plant_file",
                           [&] { return LoadVehicleFile(Resolve(vm, vm.String("plant_file"))); });
      v.has_plant = true;
    }
    if (vm.Has("plant_motor_time_constant"))
      v.plant_motor_time_constant = Positive(vm, "plant_motor_time_constant", 0.02);
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
      if (nmaps.empty() || nmaps.size() > static_cast<std::size_t>(formation::kMaxNeighbours)) {
        throw vm.ErrorAt("neighbours", "a follower needs 1 to " +
                                           std::to_string(formation::kMaxNeighbours) +
                                           " neighbours, got " + std::to_string(nmaps.size()));
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
      for (std::size_t k = 0; k < j; ++k) {
        if (s.vehicles[i].neighbours[k].index == it->second)
          throw nm.ErrorAt("vehicle", "neighbour '" + name + "' is listed twice");
      }
      const ScenarioVehicle& self = s.vehicles[i];
      const ScenarioVehicle& other = s.vehicles[static_cast<std::size_t>(it->second)];
      const double gap = (other.start - self.start).norm();
      if (!self.sensors.relative.enabled) {
        s.warnings.push_back(std::string(nm.ErrorAt("vehicle", "").what()) +
                             "the relative sensor of '" + self.name +
                             "' is disabled: it never observes neighbour '" + name + "'");
      } else if (gap > self.sensors.relative.max_range) {
        s.warnings.push_back(
            std::string(nm.ErrorAt("vehicle", "").what()) + "neighbour '" + name + "' starts " +
            std::to_string(gap) + " m away, beyond the relative sensor's max_range " +
            std::to_string(self.sensors.relative.max_range) + " m of '" + self.name + "'");
      }
      s.vehicles[i].neighbours[j].index = it->second;
      const std::string conflict = BoundConflict(self, self.neighbours[j]);
      if (!conflict.empty()) {
        s.warnings.push_back(std::string(nm.ErrorAt("desired", "").what()) + conflict);
      }
      nm.Finish();
    }
    vmaps[i].Finish();
  }
}

// `formation:`, expanded by formation::GenerateFormation: the leader is named `leader`,
// the followers <prefix>1, <prefix>2, ... front to back.
std::vector<ScenarioVehicle> GeneratedVehicles(YamlMap& fm,
                                               const model::VehicleParams& default_params,
                                               const SensorsConfig& default_sensors,
                                               std::vector<std::string>* warnings) {
  formation::FormationSpec spec;
  const std::string shape = fm.String("shape");
  if (!formation::ParseFormationShape(shape, &spec.shape))
    throw fm.ErrorAt("shape", "must be wedge, line, grid or circle, got '" + shape + "'");
  spec.count = fm.Int("count");
  if (spec.count < 2 || spec.count > kMaxVehicles)
    throw fm.ErrorAt("count", "must be 2 to " + std::to_string(kMaxVehicles) + ", got " +
                                  std::to_string(spec.count));
  spec.spacing = Positive(fm, "spacing", spec.spacing);
  if (spec.spacing < 1.0) throw fm.ErrorAt("spacing", "must be >= 1 m");
  spec.ties = fm.Int("ties", spec.ties);
  if (spec.ties < 1 || spec.ties > formation::kMaxNeighbours)
    throw fm.ErrorAt("ties", "must be 1 to " + std::to_string(formation::kMaxNeighbours) +
                                 ", got " + std::to_string(spec.ties));
  spec.columns = fm.Int("columns", 0);
  if (spec.columns < 0 || spec.columns > spec.count)
    throw fm.ErrorAt("columns", "must be 0 (automatic) to count");
  if (fm.Has("columns") && spec.shape != formation::FormationShape::kGrid)
    throw fm.ErrorAt("columns", "only for shape: grid");
  if (fm.Has("origin")) {
    const std::vector<double> origin = fm.Doubles("origin", 2);
    spec.origin = Vec3(origin[0], origin[1], 0.0);
  }
  if (!spec.origin.allFinite()) throw fm.ErrorAt("origin", "must be finite");
  const std::string prefix = fm.Has("prefix") ? Identifier(fm, "prefix") : std::string("f");
  const std::string frame = fm.String("frame", "m");
  if (frame != "m" && frame != "c")
    throw fm.ErrorAt("frame", "must be 'm' or 'c', got '" + frame + "'");
  const Vec3 bound =
      Positive3(fm, "relative_position_bound", ScenarioVehicle{}.relative_position_bound);

  const std::vector<formation::FormationSlot> slots = formation::GenerateFormation(spec);
  std::vector<ScenarioVehicle> vehicles(slots.size());
  for (std::size_t i = 0; i < slots.size(); ++i) {
    ScenarioVehicle& v = vehicles[i];
    v.name = i == 0 ? std::string("leader") : prefix + std::to_string(i);
    v.leader = i == 0;
    v.start = slots[i].start;
    v.params = default_params;
    v.sensors = default_sensors;
    if (v.leader) continue;
    v.frame_control = frame == "c";
    v.relative_position_bound = bound;
    for (const formation::FormationTie& t : slots[i].ties) {
      ScenarioNeighbour n;
      n.index = t.neighbour;
      n.desired = t.desired;
      v.neighbours.push_back(n);
    }
  }
  for (ScenarioVehicle& v : vehicles) {
    for (ScenarioNeighbour& n : v.neighbours) {
      n.vehicle = vehicles[static_cast<std::size_t>(n.index)].name;
      const double gap = n.desired.norm();
      if (!v.sensors.relative.enabled || gap > v.sensors.relative.max_range) {
        warnings->push_back(std::string(fm.ErrorAt("spacing", "").what()) + "neighbour '" +
                            n.vehicle + "' of '" + v.name + "' is " + std::to_string(gap) +
                            " m away, beyond the relative sensor's range");
      }
      const std::string conflict = BoundConflict(v, n);
      if (!conflict.empty()) {
        warnings->push_back(std::string(fm.ErrorAt("ties", "").what()) + conflict);
      }
    }
  }
  return vehicles;
}

}  // namespace

ScenarioConfig ParseScenario(YamlMap map) {
  ScenarioConfig s;
  // The settings structs' keys (ScenarioConfig::Serialize); the blocks they share with
  // hand-parsed keys (leader) are opened through the reader.
  SettingsReader reader(&map);
  s.file = map.file();
  s.name = Identifier(map, "name");
  s.description = map.String("description", "");
  s.duration = Positive(map, "duration", s.duration);
  if (s.duration > kMaxScenarioDuration) {
    throw map.ErrorAt("duration", "must be <= " + std::to_string(kMaxScenarioDuration) +
                                      " s, got " + std::to_string(s.duration));
  }
  {
    const int seed = map.Int("seed", 1);
    if (seed < 0) throw map.ErrorAt("seed", "must be >= 0");
    s.seed = static_cast<std::uint64_t>(seed);
  }
  s.downwash = map.Bool("downwash", s.downwash);
  s.battery_sag = map.Bool("battery_sag", s.battery_sag);
  const std::string vehicle_file = Resolve(map, map.String("vehicle_file"));
  const std::string sensors_file = Resolve(map, map.String("sensors_file", ""));
  const model::VehicleParams default_params =
      Referenced(map, "vehicle_file", [&] { return LoadVehicleFile(vehicle_file); });
  const SensorsConfig default_sensors =
      sensors_file.empty()
          ? SensorsConfig{}
          : Referenced(map, "sensors_file", [&] { return LoadSensorsFile(sensors_file); });

  // ---- Vehicles: generated from `formation:` or listed one by one in `vehicles:`.
  if (map.Has("formation")) {
    if (map.Has("vehicles"))
      throw map.ErrorAt("formation", "give either formation: or vehicles:, not both");
    YamlMap fm = map.Map("formation");
    s.vehicles = GeneratedVehicles(fm, default_params, default_sensors, &s.warnings);
    s.leader = 0;
    fm.Finish();
  } else {
    ListedVehicles(map, default_params, default_sensors, &s);
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
    YamlMap& lm = reader.Required("leader");
    s.leader_mode = lm.String("mode");
    if (s.leader_mode == "waypoints") {
      YAML::Node wp = lm.Node("waypoints");
      if (!wp.IsSequence() || wp.size() < 2)
        throw lm.ErrorAt("waypoints", "need a list of at least two [x, y, z]");
      if (wp.size() > static_cast<std::size_t>(kMaxWaypoints))
        throw lm.ErrorAt("waypoints", "at most " + std::to_string(kMaxWaypoints) + " waypoints");
      for (std::size_t k = 0; k < wp.size(); ++k) {
        const YAML::Node p = wp[k];
        const std::string at = lm.file() + ":" + std::to_string(p.Mark().line + 1) + ":" +
                               std::to_string(p.Mark().column + 1) + ": key 'leader.waypoints[" +
                               std::to_string(k) + "]': ";
        if (!p.IsSequence() || p.size() != 3)
          throw ConfigError(at + "each waypoint is [x, y, z] in m");
        Vec3 q;
        for (int a = 0; a < 3; ++a) {
          double x = kNaN;
          try {
            x = p[a].as<double>();
          } catch (const YAML::Exception&) {
          }
          if (!std::isfinite(x)) throw ConfigError(at + "waypoint entries must be finite numbers");
          q[a] = x;
        }
        s.waypoints.push_back(q);
      }
      s.leg_duration = Positive(lm, "leg_duration", s.leg_duration);
      s.hold_duration = NonNegative(lm, "hold_duration", s.hold_duration);
    } else if (s.leader_mode == "manual") {
      s.manual_start = lm.Vector3("position", s.manual_start);
      // The world needs the held leader at or above its resting CoM height (0.1 m,
      // sim::World::kRestHeight); checked here so the error names the key.
      if (!(s.manual_start.z() >= 0.1))
        throw lm.ErrorAt("position", "z must be >= 0.1 m (the resting height of the CoM)");
      s.walk_box = Positive3(lm, "box", s.walk_box);
      s.walk_moves = IntIn(lm, "moves", s.walk_moves, 1, kMaxLeaderMoves);
      std::tie(s.walk_min_leg, s.walk_max_leg) =
          Range(lm, "move_duration", s.walk_min_leg, s.walk_max_leg);
      if (!(s.walk_min_leg > 0.0)) throw lm.ErrorAt("move_duration", "minimum must be > 0");
      std::tie(s.walk_min_hold, s.walk_max_hold) =
          Range(lm, "pause_duration", s.walk_min_hold, s.walk_max_hold);
    } else {
      throw lm.ErrorAt("mode", "must be 'waypoints' or 'manual', got '" + s.leader_mode + "'");
    }
  }

  // ---- Controller, phases, safety, weights, metrics, envelope: the settings structs.
  reader.Read(&s);
  formation::ControllerSettings& c = s;
  if (YamlMap* cm = reader.At("controller")) {
    // The controller runs every round(sample_time / physics step) physics steps, so any
    // other value would silently fly a different sample time than the model's.
    const double ratio = c.rti.sample_time / kPhysicsStep;
    if (std::abs(ratio - std::round(ratio)) > 1e-6 || c.rti.sample_time > 1.0) {
      throw cm->ErrorAt("sample_time",
                        "must be a multiple of the 0.001 s physics step in "
                        "[0.001, 1] s, got " +
                            std::to_string(c.rti.sample_time));
    }
  }
  // Algorithm 1's budget is one sample time unless given.
  if (YamlMap* cm = reader.At("controller"); cm == nullptr || !cm->Has("cpu_budget"))
    c.rti.cpu_budget = c.rti.sample_time;
  if (YamlMap* bm = reader.At("controller.bounds"); bm != nullptr && bm->Has("thrust")) {
    // The collective thrust bounds [N] must bracket every vehicle's weight with margin, or
    // the vehicles cannot take off (or cannot descend).
    for (const ScenarioVehicle& v : s.vehicles) {
      const double weight = v.params.mass * kPlausibleGravity;
      if (!(c.thrust_max >= kThrustMargin * weight && c.thrust_min < weight)) {
        throw bm->ErrorAt("thrust", "[min, max] = [" + std::to_string(c.thrust_min) + ", " +
                                        std::to_string(c.thrust_max) +
                                        "] N must satisfy min < m g and "
                                        "max >= " +
                                        std::to_string(kThrustMargin) + " m g for vehicle '" +
                                        v.name + "' (m g = " + std::to_string(weight) + " N)");
      }
    }
  }
  if (YamlMap* sm = reader.At("safety");
      sm != nullptr && !(c.safety.max_altitude > c.safety.min_altitude))
    throw sm->ErrorAt("max_altitude", "must be above min_altitude");

  if (!(s.landing_time > s.trajectory_start && s.landing_time < s.duration)) {
    throw map.ErrorAt(map.Has("phases") ? "phases" : "duration",
                      "phases.landing_time must lie between leader.start_time and duration");
  }
  if (!(s.trajectory_start > s.takeoff_time))
    throw map.ErrorAt("leader", "leader.start_time must be after phases.takeoff_time");
  for (const ScenarioVehicle& v : s.vehicles) {
    if (std::isfinite(v.landing_time) &&
        !(v.landing_time > s.trajectory_start && v.landing_time < s.duration)) {
      throw map.ErrorAt("vehicles", "vehicle '" + v.name +
                                        "': landing_time must lie between leader.start_time "
                                        "and duration");
    }
  }

  // ---- Reality (after the duration its gust times refer to): a block without `enabled` is on.
  if (map.Has("reality")) {
    s.reality.enabled = true;
    reader.Required("reality");
    reader.Nested("reality", &s.reality);
    CheckReality(reader, s);
  }

  // ---- Faults (after the vehicles, the leader mode and the duration they refer to).
  if (map.Has("faults")) s.faults = ParseFaults(map.Map("faults"), s);

  {
    // The leader flies its NMPC on its own absolute position: without motion capture it can
    // only dead-reckon (a test of that may be meant, so this is a warning).
    const ScenarioVehicle& leader = s.vehicles[static_cast<std::size_t>(s.leader)];
    if (s.leader_mode == "waypoints" && !leader.sensors.mocap.enabled) {
      s.warnings.push_back(std::string(map.ErrorAt("vehicles", "").what()) + "the leader '" +
                           leader.name +
                           "' has no absolute position sensing (mocap disabled): its position "
                           "is dead-reckoned and drifts");
    }
  }

  reader.Finish();
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

void CheckDurationFlag(const ScenarioConfig& s, double duration) {
  if (!std::isfinite(duration) || !(duration > 0.0) || duration > s.duration) {
    throw ConfigError("--duration: must be finite, > 0 and at most the scenario's duration (" +
                      std::to_string(s.duration) + " s of " + s.file + "), got " +
                      std::to_string(duration));
  }
}

std::vector<SettingDoc> RealitySettingsDocs() {
  ScenarioReality defaults;
  SettingsDocWriter writer;
  writer.Nested("reality", &defaults);
  return writer.fields();
}

std::vector<SettingDoc> ScenarioSettingsDocs() {
  ScenarioConfig defaults;
  SettingsDocWriter writer;
  writer.Read(&defaults);
  return writer.fields();
}

ScenarioConfig LoadScenarioFile(const std::string& path) {
  return ParseScenario(YamlMap::LoadFile(path));
}

}  // namespace fnmpc::config
