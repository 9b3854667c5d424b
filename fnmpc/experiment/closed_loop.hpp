// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/fault_injector.hpp"
#include "fnmpc/experiment/measurement_feeder.hpp"
#include "fnmpc/experiment/plan_link.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"
#include "fnmpc/experiment/worker_pool.hpp"
#include "fnmpc/formation/trajectory.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/sim/world.hpp"

/// The closed loop of `fnmpc run` in the shape of Drake's Simulator with monitors: a
/// ClosedLoop steps the world (with the scenario's faults) and the vehicles' controllers and
/// calls its observers, which measure and log (run_observers.hpp) and never act on the loop.
namespace fnmpc::experiment {

/// The world with the scenario's faults applied: the motors-off event at its time, the sensor
/// faults (dropout windows, outliers) on every measurement delivered, the controller kill.
class FaultedWorld {
 public:
  FaultedWorld(const sim::WorldConfig& config, const config::ScenarioFaults& faults,
               std::uint64_t seed)
      : world_(config), faults_(faults), injector_(faults, seed) {}

  /// Switches the motors of faults.motors_off off once its time came; true at that step.
  bool SwitchMotorsOffWhenDue(double t) {
    if (!faults_.motors_off.active() || t < faults_.motors_off.time - 1e-9 ||
        world_.GetAutopilotStatus(faults_.motors_off.index).motors_killed) {
      return false;
    }
    world_.KillMotors(faults_.motors_off.index);
    return true;
  }
  /// The next delivered measurement that the sensor faults let through, in delivery order
  /// (the outliers' random stream is shared by all vehicles).
  bool PopMeasurement(Measurement* m) {
    while (world_.PopMeasurement(m)) {
      if (injector_.Filter(m)) return true;
    }
    return false;
  }
  /// Vehicle i's controller is killed (faults.kill_controller) from this time on.
  [[nodiscard]] bool ControllerKilledAt(int i, double t) const {
    return faults_.kill_controller.index == i && t >= faults_.kill_controller.time - 1e-9;
  }
  /// Vehicle i's motors were switched off by the fault.
  [[nodiscard]] bool MotorsOffByFault(int i) const {
    return faults_.motors_off.index == i && world_.GetAutopilotStatus(i).motors_killed;
  }
  [[nodiscard]] sim::World& world() { return world_; }
  [[nodiscard]] const sim::World& world() const { return world_; }
  [[nodiscard]] const FaultInjector& injector() const { return injector_; }
  [[nodiscard]] const config::ScenarioFaults& faults() const { return faults_; }

 private:
  sim::World world_;
  const config::ScenarioFaults& faults_;
  FaultInjector injector_;
};

class ClosedLoop;

/// One control step as the observers see it (valid during the calls).
struct ControlStep {
  double t = 0.0;
  /// The leader's reference position (NaN while unknown) and whether the formation had time
  /// to settle after the leader's last waypoint (metrics.settle_time).
  Vec3 leader_ref = Vec3::Constant(kNaN);
  bool settled = false;
};

/// What watches the closed loop. The calls of one step come in this order: PhysicsStep
/// (every 1 ms step, before its measurements are delivered); at a control step
/// ControlStepBegin (truth sampled, controllers not yet run), CommandsSent (the world has the
/// commands), VehicleStep (once per vehicle, in parallel: touch only vehicle i's data) and
/// ControlStepEnd; Finish once after the last step.
class ClosedLoopObserver {
 public:
  virtual ~ClosedLoopObserver() = default;
  virtual void PhysicsStep(const ClosedLoop& /*loop*/, double /*t*/) {}
  virtual void ControlStepBegin(const ClosedLoop& /*loop*/, const ControlStep& /*step*/) {}
  virtual void CommandsSent(const ClosedLoop& /*loop*/, const ControlStep& /*step*/) {}
  virtual void VehicleStep(const ClosedLoop& /*loop*/, const ControlStep& /*step*/, int /*i*/) {}
  virtual void ControlStepEnd(const ClosedLoop& /*loop*/, const ControlStep& /*step*/) {}
  virtual void Finish(const ClosedLoop& /*loop*/) {}
};

/// Something that happened in the loop, for the progress output ("motors of f1 off (fault)").
using LoopEventSink = std::function<void(double t, const std::string& what)>;

/// The world (1 ms physics, all sensors, the autopilots' command-timeout failsafe on), one
/// controller per flying vehicle every sample time on a pool of options.threads threads, the
/// plans over the simulated link in cooperative mode, the scenario's faults.
class ClosedLoop {
 public:
  /// Throws std::invalid_argument when the duration is outside (0, kMaxScenarioDuration].
  ClosedLoop(const config::ScenarioConfig& scenario, const RunOptions& options);
  ~ClosedLoop();
  ClosedLoop(const ClosedLoop&) = delete;
  ClosedLoop& operator=(const ClosedLoop&) = delete;

  /// Observers are called in the order added; they must outlive Run().
  void AddObserver(ClosedLoopObserver* observer) { observers_.push_back(observer); }
  void SetEventSink(LoopEventSink sink) { events_ = std::move(sink); }
  /// Steps to the end, options.stop or a simulator error (stopped(), sim_error()).
  void Run();

  [[nodiscard]] const config::ScenarioConfig& scenario() const { return sc_; }
  [[nodiscard]] const RunOptions& options() const { return options_; }
  [[nodiscard]] double duration() const { return duration_; }
  [[nodiscard]] int vehicles() const { return nv_; }
  [[nodiscard]] bool manual_leader() const { return manual_; }
  [[nodiscard]] const sim::WorldConfig& world_config() const { return world_config_; }
  [[nodiscard]] const FaultedWorld& world() const { return *world_; }
  /// Vehicle i's controller (nullptr: a hand-moved leader).
  [[nodiscard]] const formation::VehicleController* controller(int i) const {
    return ctrl_[static_cast<std::size_t>(i)].get();
  }
  [[nodiscard]] bool killed(int i) const { return killed_[static_cast<std::size_t>(i)] != 0; }
  /// At the control step: the output each vehicle flies (killed: time only; hand-moved
  /// leader: phase kNmpc), the true states and positions.
  [[nodiscard]] const formation::ControlOutput& output(int i) const {
    return outs_[static_cast<std::size_t>(i)];
  }
  [[nodiscard]] const std::vector<sim::TrueState>& truth() const { return truth_; }
  [[nodiscard]] const std::vector<Vec3>& positions() const { return positions_; }
  [[nodiscard]] const PlanLink* link() const { return link_.get(); }
  [[nodiscard]] const std::string& stopped() const { return stopped_; }
  [[nodiscard]] const std::string& sim_error() const { return sim_error_; }
  void Event(double t, const std::string& what) const {
    if (events_) events_(t, what);
  }

 private:
  void ControlStepOf(double t);
  void Feed(int i);

  const config::ScenarioConfig& sc_;
  RunOptions options_;
  double duration_ = 0.0;
  int nv_ = 0;
  bool manual_ = false;
  formation::WaypointTrajectory trajectory_;
  sim::WorldConfig world_config_;
  std::unique_ptr<FaultedWorld> world_;
  std::vector<std::unique_ptr<formation::VehicleController>> ctrl_;
  std::unique_ptr<PlanLink> link_;
  formation::PlanMessage plan_;
  // Each vehicle's measurements since its last control step, in delivery order: its own
  // thread feeds them to its controller just before the step (the same calls in the same
  // order as feeding them at delivery: nothing else reaches a controller in between).
  std::vector<std::vector<Measurement>> inbox_;
  std::unique_ptr<WorkerPool> pool_;
  std::optional<MeasurementFeeder> feeder_;
  std::vector<char> killed_, killed_now_;
  std::vector<formation::ControlOutput> outs_;
  std::vector<sim::TrueState> truth_;
  std::vector<Vec3> positions_;
  std::vector<ClosedLoopObserver*> observers_;
  LoopEventSink events_;
  std::string stopped_, sim_error_;
};

}  // namespace fnmpc::experiment
