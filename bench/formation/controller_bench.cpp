// SPDX-License-Identifier: BSD-3-Clause
// One control step of the VehicleController in the NMPC phase (command path only, then the
// diagnostics apart): a follower with 2 neighbours hovering in formation, with and without
// the input-rate and collision terms active, and with the disturbance observer's external
// acceleration in the prediction, and with the neighbours' predicted wakes (issue #17). Goal
// of issues #20/#17: <= 20 us median.
//   ./build/bench/formation/controller_bench
#include <benchmark/benchmark.h>

#include <vector>

#include "fnmpc/formation/vehicle_controller.hpp"
#include "tests/formation/controller_test_support.hpp"

namespace {

using fnmpc::Vec3;
using namespace fnmpc::formation;

// rate: input-rate weights on; close: the second neighbour 0.4 m away (inside r_min = 0.45,
// the collision row active) instead of 3 m. observer: Compensation::kObserver with a constant
// push d on the plant that the estimate reports (hover targets and the acceleration parameter
// in use). wake: Compensation::kWake with neighbour 0 hovering 0.8 m above and 0.25 m beside
// (the follower in its wake: both wake slots in use, one with a push).
void ControlStep(benchmark::State& state, bool rate, bool close, bool observer = false,
                 bool wake = false) {
  ControllerConfig c = testing::BaseConfig(false);
  const Vec3 p0 = wake ? Vec3(0.25, 0.0, 1.9) : Vec3(1.3, -0.8, 1.1);
  const Vec3 p1 = close ? Vec3(0.0, 0.4, 1.1) : Vec3(-1.7, -3.8, 1.1);
  c.neighbours = {{0, p0 - Vec3(0.0, 0.0, 1.1)}, {2, p1 - Vec3(0.0, 0.0, 1.1)}};
  observer = observer || wake;
  if (rate) {
    c.weights.thrust_rate = 2.0;
    c.weights.attitude_ref_rate = 50.0;
  }
  const Vec3 d = observer ? Vec3(0.3, -0.2, -0.6) : Vec3(Vec3::Zero());
  if (observer) c.compensation = wake ? Compensation::kWake : Compensation::kObserver;
  VehicleController ctrl(c);
  testing::Plant plant;
  std::vector<fnmpc::estimation::NeighbourStateVec> nb(2);
  double t = 0.0;
  auto step = [&] {
    fnmpc::estimation::VehicleEstimate e = plant.Estimate(t);
    e.position.z() -= testing::kGround;
    e.disturbance = d;
    nb[0].setZero();
    nb[0].head<3>() = p0 - plant.x.head<3>();
    nb[1].setZero();
    nb[1].head<3>() = p1 - plant.x.head<3>();
    const ControlOutput o = ctrl.ControlWithEstimates(t, e, nb);
    plant.Step(o);
    // The push over the step: exactly its double integral (v' gains d, nothing else).
    plant.x.head<3>() += 0.5 * testing::kTs * testing::kTs * d;
    plant.x.segment<3>(3) += testing::kTs * d;
    t += testing::kTs;
    return o;
  };
  while (ctrl.phase() != FlightPhase::kNmpc || t < 12.0) step();
  long steps = 0;
  for (auto _ : state) {
    const ControlOutput o = step();
    benchmark::DoNotOptimize(o.thrust);
    ++steps;
  }
  state.counters["fallbacks"] = static_cast<double>(ctrl.fallbacks());
}

}  // namespace

BENCHMARK_CAPTURE(ControlStep, follower2_plain, false, false)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate, true, false)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision, true, true)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_observer, false, false, true)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision_observer, true, true, true)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_wake, false, false, true, true)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision_wake, true, true, true, true)
    ->Unit(benchmark::kMicrosecond);
