// SPDX-License-Identifier: BSD-3-Clause
// Real-time factor of the MuJoCo world: counter "rtf" = simulated seconds per wall second.
// BM_MujocoLayout: MuJoCo alone, the world's MJCF of N vehicles as one model against N models
// of one vehicle each (the layout that would let the vehicles be stepped in parallel).
#include <benchmark/benchmark.h>
#include <mujoco/mujoco.h>

#include <memory>
#include <string>
#include <vector>

#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/sim/mjcf_model.hpp"
#include "fnmpc/sim/world.hpp"

namespace {

using fnmpc::sim::World;
using fnmpc::sim::WorldConfig;

enum Scenario : int {
  kHoverNoSensors = 0,   ///< in the air at the hover throttle, no controllers, no sensors
  kGroundNoSensors = 1,  ///< resting on the ground (contacts), no controllers, no sensors
  kHoverFull = 2,        ///< in the air, autopilot, all sensors, downwash, wind and gusts
  kHoverLean = 3,        ///< as kHoverNoSensors without the visual-only MJCF geometry
  kGroundLean = 4,       ///< as kGroundNoSensors without the visual-only MJCF geometry
};

WorldConfig Make(int n, Scenario scenario) {
  WorldConfig c;
  const auto p = fnmpc::config::LoadVehicleFile(std::string(FNMPC_SOURCE_DIR) +
                                                "/config/vehicles/storm-drone-4.yaml");
  c.battery.fixed_voltage = true;
  const bool ground = scenario == kGroundNoSensors || scenario == kGroundLean;
  c.visual_geometry = scenario != kHoverLean && scenario != kGroundLean;
  for (int i = 0; i < n; ++i) {
    fnmpc::sim::VehicleSpec v;
    v.params = p;
    v.position = {1.5 * i, 0.0, ground ? World::kRestHeight : 2.0 + i};
    if (!ground) {
      v.initial_throttle = p.throttle.Throttle(p.mass * fnmpc::kGravity / 4.0, 16.8);
    }
    if (scenario != kHoverFull) {
      for (auto* s : {&v.sensors.mocap, &v.sensors.imu, &v.sensors.optical_flow, &v.sensors.compass,
                      &v.sensors.battery, &v.sensors.relative}) {
        s->enabled = false;
      }
    }
    c.vehicles.push_back(v);
  }
  if (scenario == kHoverFull) {
    c.downwash.enabled = true;
    c.wind.enabled = true;
    c.wind.gust_std = 0.5;
  }
  return c;
}

void BM_World(benchmark::State& state) {
  const auto scenario = static_cast<Scenario>(state.range(1));
  const WorldConfig c = Make(static_cast<int>(state.range(0)), scenario);
  World world(c);
  if (scenario == kHoverFull) {
    for (int v = 0; v < world.num_vehicles(); ++v) {
      world.SetCommand(v, {1.37 * fnmpc::kGravity, 0.0, 0.0, 0.0});
    }
  }
  constexpr int kSteps = 1000;  // 1 s of simulated time per iteration
  fnmpc::Measurement m;
  for (auto _ : state) {
    for (int k = 0; k < kSteps; ++k) {
      world.StepOnce();
      while (world.PopMeasurement(&m)) benchmark::DoNotOptimize(m);
    }
    if (world.time() > 50.0) {  // stay near the start: re-place the vehicles
      state.PauseTiming();
      for (int v = 0; v < world.num_vehicles(); ++v) {
        world.SetPose(v, c.vehicles[v].position, fnmpc::Vec3::Zero());
      }
      state.ResumeTiming();
    }
  }
  state.counters["rtf"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["us_per_step"] =
      benchmark::Counter(static_cast<double>(state.iterations() * kSteps),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_World)
    ->ArgNames({"vehicles", "scenario"})
    ->Args({3, kHoverNoSensors})
    ->Args({3, kGroundNoSensors})
    ->Args({3, kHoverFull})
    ->Args({3, kHoverLean})
    ->Args({3, kGroundLean})
    ->Args({1, kHoverNoSensors})
    ->Args({10, kHoverNoSensors})
    ->Unit(benchmark::kMillisecond);

enum Layout : int { kOneModel = 0, kModelPerVehicle = 1 };

/// A MuJoCo model compiled from MJCF text and its data.
struct MujocoPair {
  mjModel* m = nullptr;
  mjData* d = nullptr;
  explicit MujocoPair(const std::string& xml)
      : m(fnmpc::sim::CompileMjcf(xml, "[sim_bench]")), d(mj_makeData(m)) {}
  MujocoPair(const MujocoPair&) = delete;
  MujocoPair& operator=(const MujocoPair&) = delete;
  ~MujocoPair() {
    mj_deleteData(d);
    mj_deleteModel(m);
  }
};

/// The world's MJCF (World::BuildMjcf) for the vehicles of `c`, as one model or one per vehicle.
std::vector<std::unique_ptr<MujocoPair>> BuildLayout(const WorldConfig& c, Layout layout) {
  std::vector<std::unique_ptr<MujocoPair>> models;
  if (layout == kOneModel) {
    models.push_back(std::make_unique<MujocoPair>(World::BuildMjcf(c)));
    return models;
  }
  for (const auto& v : c.vehicles) {
    WorldConfig one = c;
    one.vehicles = {v};
    models.push_back(std::make_unique<MujocoPair>(World::BuildMjcf(one)));
  }
  return models;
}

/// mj_step of every model, the vehicles held up by a vertical force m g in the air (args:
/// vehicles, layout, on the ground 0/1). Counter us_per_step: one physics step of all vehicles.
void BM_MujocoLayoutStep(benchmark::State& state) {
  const bool ground = state.range(2) != 0;
  const WorldConfig c = Make(static_cast<int>(state.range(0)), ground ? kGroundLean : kHoverLean);
  const auto models = BuildLayout(c, static_cast<Layout>(state.range(1)));
  const double weight = c.vehicles[0].params.mass * c.gravity;
  constexpr int kSteps = 1000;
  for (auto _ : state) {
    for (int k = 0; k < kSteps; ++k) {
      for (const auto& p : models) {
        for (int j = 0; j < p->m->njnt; ++j) {
          p->d->qfrc_applied[p->m->jnt_dofadr[j] + 2] = ground ? 0.0 : weight;
        }
        mj_step(p->m, p->d);
      }
    }
    state.PauseTiming();
    for (const auto& p : models) mj_resetData(p->m, p->d);  // back to the start
    state.ResumeTiming();
  }
  state.counters["us_per_step"] =
      benchmark::Counter(static_cast<double>(state.iterations() * kSteps),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_MujocoLayoutStep)
    ->ArgNames({"vehicles", "per_vehicle", "ground"})
    ->ArgsProduct({{25, 100}, {kOneModel, kModelPerVehicle}, {0, 1}})
    ->Unit(benchmark::kMillisecond);

/// Compiling the MJCF and making the data (args: vehicles, layout).
void BM_MujocoLayoutBuild(benchmark::State& state) {
  const WorldConfig c = Make(static_cast<int>(state.range(0)), kHoverLean);
  for (auto _ : state) {
    benchmark::DoNotOptimize(BuildLayout(c, static_cast<Layout>(state.range(1))));
  }
}
BENCHMARK(BM_MujocoLayoutBuild)
    ->ArgNames({"vehicles", "per_vehicle"})
    ->ArgsProduct({{25, 100}, {kOneModel, kModelPerVehicle}})
    ->Unit(benchmark::kMillisecond);

}  // namespace
