// SPDX-License-Identifier: BSD-3-Clause
// ClosedLoop's contract with its observers (closed_loop.hpp): the calls of a step in the
// documented order, one VehicleStep per vehicle, control steps every sample time, Finish once;
// the controller-kill fault stops the killed vehicle's outputs.
#include "fnmpc/experiment/closed_loop.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"

namespace fnmpc::experiment {
namespace {

config::ScenarioConfig Triangle() {
  return config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) +
                                  "/config/scenarios/triangle.yaml");
}

/// Records the calls as letters: P physics step, B control step begin, C commands sent,
/// V the vehicle steps of a control step (they run in parallel: counted, and written once
/// at the step's end when there were any), E control step end, F finish.
class CallRecorder : public ClosedLoopObserver {
 public:
  void PhysicsStep(const ClosedLoop& /*loop*/, double t) override {
    calls += 'P';
    last_physics_t = t;
  }
  void ControlStepBegin(const ClosedLoop& /*loop*/, const ControlStep& step) override {
    calls += 'B';
    control_times.push_back(step.t);
    vehicle_steps = 0;
  }
  void CommandsSent(const ClosedLoop& /*loop*/, const ControlStep& /*step*/) override {
    calls += 'C';
  }
  void VehicleStep(const ClosedLoop& /*loop*/, const ControlStep& /*step*/, int i) override {
    const std::lock_guard<std::mutex> lock(mutex);
    ++vehicle_steps;
    seen.push_back(i);
  }
  void ControlStepEnd(const ClosedLoop& loop, const ControlStep& /*step*/) override {
    vehicle_steps_per_control.push_back(vehicle_steps);
    if (loop.killed(1)) killed_outputs_nmpc += loop.output(1).nmpc ? 1 : 0;
    calls += vehicle_steps > 0 ? "VE" : "E";
  }
  void Finish(const ClosedLoop& /*loop*/) override { calls += 'F'; }

  std::string calls;
  std::vector<double> control_times;
  std::vector<int> vehicle_steps_per_control, seen;
  int vehicle_steps = 0, killed_outputs_nmpc = 0;
  double last_physics_t = -1.0;
  std::mutex mutex;
};

TEST(ClosedLoopTest, CallsObserversInTheDocumentedOrder) {
  const config::ScenarioConfig sc = Triangle();
  RunOptions options;
  options.duration = 1.0;
  options.threads = 2;
  ClosedLoop loop(sc, options);
  CallRecorder rec;
  loop.AddObserver(&rec);
  loop.Run();
  EXPECT_TRUE(loop.stopped().empty());
  EXPECT_TRUE(loop.sim_error().empty());
  // 1 s at 1 ms: 1001 physics steps (t = 0 .. 1 s), a control step every sample time.
  const auto physics = std::count(rec.calls.begin(), rec.calls.end(), 'P');
  EXPECT_EQ(physics, 1001);
  EXPECT_NEAR(rec.last_physics_t, 1.0, 1e-9);
  const int every = static_cast<int>(std::lround(sc.rti.sample_time / 0.001));
  EXPECT_EQ(static_cast<long>(rec.control_times.size()), 1000 / every + 1);
  for (std::size_t k = 1; k < rec.control_times.size(); ++k) {
    EXPECT_NEAR(rec.control_times[k] - rec.control_times[k - 1], sc.rti.sample_time, 1e-9);
  }
  // Every control step: begin, commands, the vehicles, end; after the physics step's call.
  std::string expected;
  for (long p = 0; p < physics; ++p) {
    expected += 'P';
    if (p % every == 0) expected += "BCVE";
  }
  EXPECT_EQ(rec.calls, expected + 'F');
  for (int n : rec.vehicle_steps_per_control) EXPECT_EQ(n, static_cast<int>(sc.vehicles.size()));
  EXPECT_EQ(loop.vehicles(), static_cast<int>(sc.vehicles.size()));
}

TEST(ClosedLoopTest, KilledControllerFliesNoMoreNmpcSteps) {
  config::ScenarioConfig sc = Triangle();
  sc.faults.kill_controller.index = 1;
  sc.faults.kill_controller.time = 6.0;
  RunOptions options;
  options.duration = 8.0;
  ClosedLoop loop(sc, options);
  CallRecorder rec;
  loop.AddObserver(&rec);
  std::vector<std::string> events;
  loop.SetEventSink([&events](double /*t*/, const std::string& what) { events.push_back(what); });
  loop.Run();
  EXPECT_TRUE(loop.killed(1));
  EXPECT_FALSE(loop.killed(0));
  EXPECT_EQ(rec.killed_outputs_nmpc, 0);
  ASSERT_FALSE(events.empty());
  EXPECT_NE(events.front().find("killed (fault)"), std::string::npos) << events.front();
}

TEST(ClosedLoopTest, RefusesADurationOutsideItsRange) {
  const config::ScenarioConfig sc = Triangle();
  RunOptions options;
  options.duration = config::kMaxScenarioDuration * 2.0;
  EXPECT_THROW(ClosedLoop(sc, options), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::experiment
