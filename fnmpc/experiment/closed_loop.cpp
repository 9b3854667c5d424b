// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/closed_loop.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>

#include "fnmpc/onboard/controller_setup.hpp"

namespace fnmpc::experiment {

namespace {
// From this many vehicles the world's per-step work is shared with the pool's threads (each
// share costs a wake-up of the workers, 2 per millisecond step).
constexpr int kWorldParallelMinVehicles = 16;
}  // namespace

ClosedLoop::ClosedLoop(const config::ScenarioConfig& scenario, const RunOptions& options)
    : sc_(scenario),
      options_(options),
      duration_(options.duration > 0.0 ? options.duration : scenario.duration),
      nv_(static_cast<int>(scenario.vehicles.size())),
      manual_(scenario.leader_mode == "manual"),
      trajectory_(onboard::LeaderTrajectory(scenario, options.seed)),
      world_config_(WorldConfigFor(scenario, options.seed)) {
  // The autopilots' command-timeout failsafe is on: a vehicle whose controller stops (fault
  // kill_controller) is landed by its autopilot, as a real one would.
  world_config_.command_timeout.enabled = true;
  world_ = std::make_unique<FaultedWorld>(world_config_, sc_.faults, options.seed);
  const auto n = static_cast<std::size_t>(nv_);
  killed_.assign(n, 0);
  killed_now_.assign(n, 0);

  // Controllers (a manually moved leader has none).
  ctrl_.resize(n);
  for (int i = 0; i < nv_; ++i) {
    if (manual_ && i == sc_.leader) continue;
    formation::ControllerConfig cc = onboard::ControllerConfigFor(sc_, i, trajectory_);
    cc.safety.injected_failure_rate = sc_.faults.solver_failure_rate;  // 0: off
    cc.safety.injected_failure_seed = options.seed;
    ctrl_[i] = std::make_unique<formation::VehicleController>(cc);
  }

  // Cooperative mode: the plans go over the simulated link to the vehicles that have their
  // publisher as a formation neighbour.
  if (sc_.compensation >= formation::Compensation::kCooperative) {
    std::vector<std::vector<int>> receivers(n);
    for (int r = 0; r < nv_; ++r) {
      if (!ctrl_[r]) continue;
      for (const formation::NeighbourTarget& nb : ctrl_[r]->config().neighbours) {
        receivers[static_cast<std::size_t>(nb.vehicle)].push_back(r);
      }
    }
    link_ =
        std::make_unique<PlanLink>(sc_.link, std::move(receivers), sc_.plan_timeout, options.seed);
  }
  if (!(std::isfinite(duration_) && duration_ > 0.0 && duration_ <= config::kMaxScenarioDuration)) {
    throw std::invalid_argument("[RunScenario] duration must be in (0, " +
                                std::to_string(config::kMaxScenarioDuration) + "] s, got " +
                                std::to_string(duration_));
  }
  inbox_.resize(n);
  // The vehicles' estimators and controllers of one control step run on these threads; each
  // task touches only its own vehicle's controller, inbox and output.
  pool_ = std::make_unique<WorkerPool>(std::max(1, std::min(options.threads, nv_)));
  // With more than one thread, a thread of its own feeds the measurements to the controllers
  // while the world takes its next steps (in delivery order, so each controller gets the same
  // calls as from the inboxes); at a control step the ones it has not reached go to the
  // inboxes, which the vehicles' tasks empty in parallel.
  if (pool_->threads() > 1) {
    feeder_.emplace([this](const Measurement& x) { ctrl_[x.vehicle]->Process(x); });
  }
  // The world's per-vehicle work of each physics step (sensors, the aerodynamic pass) on the
  // same threads while the controllers wait (bit-identical to one thread, sim::World::
  // SetParallelFor); below kWorldParallelMinVehicles a step's work is too small to share.
  if (pool_->threads() > 1 && nv_ >= kWorldParallelMinVehicles) {
    world_->world().SetParallelFor(
        [pool = pool_.get()](int n, const std::function<void(int)>& f) { pool->ForEach(n, f); });
  }
  outs_.resize(n);
  truth_.resize(n);
  positions_.resize(n);
}

ClosedLoop::~ClosedLoop() = default;

void ClosedLoop::Feed(int i) {
  if (ctrl_[i] && !killed_[i]) {
    for (const Measurement& x : inbox_[i]) ctrl_[i]->Process(x);
  }
  inbox_[i].clear();
}

void ClosedLoop::Run() {
  sim::World& world = world_->world();
  const double dt = world.physics_dt();
  const int steps = static_cast<int>(std::lround(duration_ / dt));
  const int every = std::max(1, static_cast<int>(std::lround(sc_.rti.sample_time / dt)));
  Measurement m;
  for (int step = 0; step <= steps; ++step) {
    if (options_.stop != nullptr && *options_.stop != 0) {
      stopped_ = "interrupted";
      break;
    }
    const double t = world.time();
    if (manual_) {
      Vec3 p, v;
      trajectory_.Sample(t - sc_.trajectory_start, &p, &v);
      world.SetState(sc_.leader, sc_.manual_start + p, Vec3(0, 0, sc_.vehicles[sc_.leader].yaw), v,
                     Vec3::Zero());
    }
    if (world_->SwitchMotorsOffWhenDue(t)) {
      Event(t, "motors of " + sc_.vehicles[sc_.faults.motors_off.index].name + " off (fault)");
    }
    for (ClosedLoopObserver* o : observers_) o->PhysicsStep(*this, t);
    while (world_->PopMeasurement(&m)) {
      // Only the carrying vehicle's controller uses a measurement.
      if (m.vehicle >= 0 && m.vehicle < nv_ && ctrl_[m.vehicle] && !killed_[m.vehicle]) {
        if (feeder_) {
          feeder_->Push(m);
        } else {
          inbox_[m.vehicle].push_back(m);
        }
      }
    }
    if (step % every == 0) ControlStepOf(t);
    if (step < steps) {
      try {
        world.StepOnce();
      } catch (const sim::SimulationError& e) {
        sim_error_ = e.what();
        break;
      }
    }
  }
  // Measurements delivered after the last control step still count in the estimators'
  // rejection totals.
  if (feeder_) feeder_->TakeRest([&](const Measurement& x) { inbox_[x.vehicle].push_back(x); });
  pool_->ForEach(nv_, [this](int i) { Feed(i); });
  for (ClosedLoopObserver* o : observers_) o->Finish(*this);
}

void ClosedLoop::ControlStepOf(double t) {
  sim::World& world = world_->world();
  for (int i = 0; i < nv_; ++i) {
    truth_[i] = world.GetTrueState(i);
    positions_[i] = truth_[i].position;
  }
  // Leader reference and steady-state flag (formation window: trajectory start to landing),
  // from the leader's anchor before its control step.
  ControlStep step;
  step.t = t;
  Vec3 ref_off, ref_v;
  trajectory_.Sample(t - sc_.trajectory_start, &ref_off, &ref_v);
  step.settled = trajectory_.TimeSinceStop(t - sc_.trajectory_start) >= sc_.metrics.settle_time;
  if (manual_) {
    step.leader_ref = sc_.manual_start + ref_off;
  } else if (ctrl_[sc_.leader] && ctrl_[sc_.leader]->anchor().allFinite()) {
    step.leader_ref = ctrl_[sc_.leader]->anchor() + ref_off;
  }
  for (ClosedLoopObserver* o : observers_) o->ControlStepBegin(*this, step);

  if (feeder_) feeder_->TakeRest([&](const Measurement& x) { inbox_[x.vehicle].push_back(x); });
  // Cooperative mode: the plans that have arrived, before the control step.
  if (link_) {
    link_->Deliver(t, [&](int r, const formation::PlanMessage& msg) {
      if (ctrl_[r] && !killed_[r]) ctrl_[r]->ReceivePlan(msg);
    });
  }
  // In parallel, per vehicle: its measurements, the kill fault, its control step and the
  // diagnostics (after the command in a real system; the world only gets the command below,
  // in vehicle order, so the order does not matter here).
  pool_->ForEach(nv_, [&](int i) {
    Feed(i);
    killed_now_[i] = 0;
    if (!killed_[i] && world_->ControllerKilledAt(i, t)) {
      killed_[i] = 1;  // no more Process, Control or SetCommand: the autopilot is alone
      killed_now_[i] = 1;
    }
    outs_[i] = formation::ControlOutput{};
    if (!killed_[i] && ctrl_[i]) {
      outs_[i] = ctrl_[i]->Control(t);
      ctrl_[i]->Diagnose(&outs_[i]);
      if (!options_.timing) outs_[i].solver_time = kNaN;
    }
  });
  if (link_) {  // each plan of this step broadcast, in vehicle order (the loss draws' order)
    for (int i = 0; i < nv_; ++i) {
      if (ctrl_[i] && !killed_[i] && ctrl_[i]->MakePlan(&plan_)) link_->Send(plan_, t);
    }
  }
  for (int i = 0; i < nv_; ++i) {
    formation::ControlOutput& out = outs_[i];
    if (killed_now_[i]) Event(t, "controller of " + sc_.vehicles[i].name + " killed (fault)");
    if (killed_[i]) {
      out = formation::ControlOutput{};
      out.time = t;
    } else if (ctrl_[i]) {
      sim::AttitudeCommand cmd;
      cmd.thrust = out.thrust;
      cmd.throttle = out.throttle;
      cmd.roll = out.roll;
      cmd.pitch = out.pitch;
      cmd.yaw = out.yaw;
      world.SetCommand(i, cmd);
    } else {
      out = formation::ControlOutput{};
      out.phase = formation::FlightPhase::kNmpc;
      out.time = t;
    }
  }
  for (ClosedLoopObserver* o : observers_) o->CommandsSent(*this, step);
  // In parallel, per vehicle: what the observers measure and log of it.
  pool_->ForEach(nv_, [&](int i) {
    for (ClosedLoopObserver* o : observers_) o->VehicleStep(*this, step, i);
  });
  for (ClosedLoopObserver* o : observers_) o->ControlStepEnd(*this, step);
}

}  // namespace fnmpc::experiment
