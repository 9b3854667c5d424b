// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/scenario_runner.hpp"

#include <fmt/core.h>
#include <fmt/ostream.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <stdexcept>

#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/experiment/run_loop.hpp"
#include "fnmpc/experiment/run_metrics.hpp"
#include "fnmpc/formation/trajectory.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/model/true_plant.hpp"
#include "fnmpc/onboard/formation_print.hpp"
#include "fnmpc/sim/world.hpp"

namespace fnmpc::experiment {

using json = nlohmann::json;

static_assert(onboard::kGroundRestHeight == sim::World::kRestHeight,
              "the controllers' ground height is the simulator's resting height");

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
      model::TruePlant t;
      try {
        t = model::DrawTruePlant(v.params, wc->motor_time_constant, r.plant, seed, i);
      } catch (const model::PlantDrawError& e) {
        // The scenario check drew the scenario's seed; another seed can still fail.
        throw std::runtime_error(
            fmt::format("{}: key 'reality.plant.{}': vehicle '{}' (seed {}): {}", sc.file, e.key(),
                        v.name, seed, e.what()));
      }
      spec.params = t.params;
      spec.motor_time_constant = t.motor_time_constant;
    }
  }
  wc->reality.rotor_aerodynamics = r.rotor_aerodynamics;
  wc->reality.wake = r.wake;
  wc->sensor_reality = r.sensor_models;
  wc->sensor_reality.enabled = r.sensors;
  if (r.wake) wc->downwash.enabled = true;
  const config::ScenarioTurbulence& t = r.turbulence;
  const bool turbulence = t.enabled();
  sim::WindSettings& w = wc->wind;
  w = r.wind;
  w.enabled =
      w.velocity.norm() > 0.0 || w.gust_std > 0.0 || turbulence || !w.discrete_gusts.empty();
  w.turbulence = turbulence;
  if (turbulence) {
    const double airspeed = std::isfinite(t.airspeed) ? t.airspeed : w.velocity.norm();
    if (std::isfinite(t.w20)) {
      w.dryden = sim::LowAltitudeDryden(t.w20, t.height, airspeed);
    } else {
      w.dryden.sigma = t.sigma;
      w.dryden.length_scale = t.length_scale;
      w.dryden.airspeed = airspeed;
    }
  }
}

config::ScenarioConfig Shortened(const config::ScenarioConfig& scenario, double duration) {
  config::ScenarioConfig s = scenario;
  // The scenario's own landing allowance (its duration after its landing time) is kept: the
  // landing moves earlier by the time cut, and the leader keeps the legs it finishes by then.
  const double cut = scenario.duration - duration;
  const double allowance = scenario.duration - scenario.landing_time;
  s.duration = duration;
  s.landing_time = scenario.landing_time - cut;
  if (!(s.landing_time > s.trajectory_start)) {
    throw config::ConfigError(fmt::format(
        "--duration {:g}: too short for {}: it keeps the scenario's landing allowance of {:g} s "
        "(duration {:g} s, phases.landing_time {:g} s) after the leader's start at {:g} s "
        "(leader.start_time): more than {:g} s",
        duration, scenario.file, allowance, scenario.duration, scenario.landing_time,
        scenario.trajectory_start, scenario.trajectory_start + allowance));
  }
  // Every vehicle's own landing time moves with the timeline: before the leader starts it
  // stays, inside the scenario's flight (leader start to landing) it keeps its place in
  // proportion, after the scenario's landing it moves by the time cut (its allowance kept).
  const double flight = scenario.landing_time - scenario.trajectory_start;
  const double shortened_flight = s.landing_time - s.trajectory_start;
  for (config::ScenarioVehicle& v : s.vehicles) {
    if (!std::isfinite(v.landing_time) || v.landing_time <= scenario.trajectory_start) continue;
    v.landing_time = v.landing_time >= scenario.landing_time
                         ? v.landing_time - cut
                         : s.trajectory_start + (v.landing_time - scenario.trajectory_start) *
                                                    shortened_flight / flight;
  }
  // The leader's legs that end by the new landing (at least one; never more than it had).
  if (s.leader_mode == "waypoints") {
    const double per_leg = s.leg_duration + s.hold_duration;
    const int legs = std::max(
        1, static_cast<int>(std::floor((shortened_flight - s.leg_duration) / per_leg)) + 1);
    if (static_cast<int>(s.waypoints.size()) > legs) s.waypoints.resize(legs);
  } else {
    const double per_move = s.walk_max_leg + s.walk_max_hold;
    s.walk_moves = std::min(
        scenario.walk_moves,
        std::max(1,
                 static_cast<int>(std::floor((shortened_flight - s.walk_max_leg) / per_move)) + 1));
  }
  return s;
}

json RunScenario(const config::ScenarioConfig& sc, const RunOptions& options,
                 const std::string& dir) {
  const RunRecord record = RecordRun(sc, options, dir);
  std::vector<std::string> fault_lines;
  json s = RunSummary(sc, options, record, &fault_lines);
  for (const std::string& line : fault_lines) {
    std::fprintf(stderr, "%s %s\n", options.label.c_str(), line.c_str());
  }
  config::WriteFileAtomically(config::PathInside(dir, "summary.json"),
                              s.dump(2, ' ', false, json::error_handler_t::replace) + "\n");
  return s;
}

}  // namespace fnmpc::experiment
