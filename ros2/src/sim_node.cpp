// SPDX-License-Identifier: BSD-3-Clause
// fnmpc_ros2_sim: the MuJoCo world of a scenario (experiment::WorldConfigFor, as `fnmpc run`)
// on ROS 2 topics (docs/ros2.md), the ROS 1 sim_node's roles: every vehicle's sensor topics in
// /<vehicle>/..., its ground truth, /clock (rosgraph_msgs/Clock, simulated time), the
// setpoints applied to the emulated autopilots. Lockstep: simulated time advances one control
// period only when every live vehicle node answered the period's SimSync; a vehicle silent for
// vehicle_timeout wall seconds is declared dead and its autopilot flies the failsafe (level
// attitude, slow descent, motors off on the ground). Parameter truth_csv: the true state and
// formation error of every vehicle at each control instant.
#include <chrono>
#include <cmath>
#include <fstream>
#include <memory>
#include <thread>
#include <vector>

#include "conversions.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"
#include "fnmpc/onboard/controller_setup.hpp"
#include "fnmpc/sim/world.hpp"
#include "node_common.hpp"
#include "parameters.hpp"

namespace fnmpc::ros2 {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

struct VehicleIo {
  VehicleIo(const Participant& p, const NodeOptions& o, const std::string& name, bool lockstep)
      : name(name),
        body_frame(name + "/base_link"),
        pose(p, o.Topic("/" + name + "/" + topics::kMocapPose), SensorQos(lockstep)),
        imu(p, o.Topic("/" + name + "/" + topics::kImu), SensorQos(lockstep)),
        flow(p, o.Topic("/" + name + "/" + topics::kOpticalFlow), SensorQos(lockstep)),
        compass(p, o.Topic("/" + name + "/" + topics::kCompass), SensorQos(lockstep)),
        battery(p, o.Topic("/" + name + "/" + topics::kBattery), SensorQos(lockstep)),
        relative(p, o.Topic("/" + name + "/" + topics::kRelative), SensorQos(lockstep)),
        sync(p, o.Topic("/" + name + "/" + topics::kSync), QosProfile::Default()),
        truth(p, o.Topic("/" + name + "/" + topics::kGroundTruth), StreamQos(lockstep)),
        setpoint(p, o.Topic("/" + name + "/" + topics::kSetpoint), StreamQos(lockstep)) {}
  std::string name, body_frame;
  Writer<geometry_msgs_msg_dds__PoseStamped_> pose;
  Writer<sensor_msgs_msg_dds__Imu_> imu;
  Writer<fnmpc_msgs_msg_dds__OpticalFlow_> flow;
  Writer<fnmpc_msgs_msg_dds__Heading_> compass;
  Writer<sensor_msgs_msg_dds__BatteryState_> battery;
  Writer<fnmpc_msgs_msg_dds__RelativeObservation_> relative;
  Writer<fnmpc_msgs_msg_dds__SimSync_> sync;
  Writer<nav_msgs_msg_dds__Odometry_> truth;
  Reader<fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_> setpoint;
  std::uint64_t seq = 0;            // measurements published so far
  std::vector<std::uint8_t> order;  // kinds published since the last control period
  std::vector<std::uint8_t> sync_order;
  std::uint64_t sync_measurements = 0, sync_first = 0;
  bool live = true, answered = false, ever_answered = false;
  sim::AttitudeCommand command;
};

class SimNode {
 public:
  explicit SimNode(const NodeOptions& o)
      : o_(o), scenario_(config::LoadScenarioFile(o.RequiredString("scenario"))) {
    int seed = o.Int("seed", -1);
    if (seed < 0) seed = static_cast<int>(scenario_.seed);
    duration_ = o.Double("duration", -1.0);
    if (duration_ <= 0.0) duration_ = scenario_.duration;
    lockstep_ = o.Bool("lockstep", true);
    vehicle_timeout_ = o.Double("vehicle_timeout", 2.0);
    startup_timeout_ = o.Double("startup_timeout", 60.0);
    failsafe_descent_speed_ = o.Double("failsafe_descent_speed", 0.3);
    // Observers that must not miss the start (the recorder, a test) are waited for.
    truth_subscribers_ = o.Int("ground_truth_subscribers", 0);
    for (const auto& [name, v] : {std::pair{"vehicle_timeout", vehicle_timeout_},
                                  {"startup_timeout", startup_timeout_},
                                  {"failsafe_descent_speed", failsafe_descent_speed_},
                                  {"duration", duration_}}) {
      if (!(v > 0.0)) {
        throw std::invalid_argument(fmt::format("parameter {} of {} must be > 0, got {}", name,
                                                o.fully_qualified_name(), v));
      }
    }
    if (scenario_.leader_mode == "manual") {
      throw std::invalid_argument(
          "the ROS 2 simulator node does not move a manual leader (not ported yet)");
    }
    world_ = std::make_unique<sim::World>(
        experiment::WorldConfigFor(scenario_, static_cast<std::uint64_t>(seed)));
    clock_pub_ = std::make_unique<Writer<rosgraph_msgs_msg_dds__Clock_>>(
        participant_, o.Topic("/clock"), StreamQos(lockstep_));
    for (const auto& v : scenario_.vehicles)
      io_.push_back(std::make_unique<VehicleIo>(participant_, o, v.name, lockstep_));
    const std::string csv = o.String("truth_csv", "");
    if (!csv.empty()) {
      truth_csv_.open(csv);
      if (!truth_csv_)
        throw std::invalid_argument(fmt::format("parameter truth_csv: cannot write {}", csv));
      truth_csv_ << "t,vehicle,live,x,y,z,yaw,formation_error\n";
    }
    Log(o.fully_qualified_name(), "{} vehicles, seed {}, {:.1f} s, {}", io_.size(), seed, duration_,
        lockstep_ ? fmt::format("lockstep period {:.3f} s", scenario_.rti.sample_time)
                  : "free-running");
  }

  // Runs the scenario to its end; false when stopped first.
  bool Run() {
    // The vehicle nodes' sensor readers must be there before the first measurement (DDS
    // topics are volatile): wait for every sensor writer to be matched.
    const auto start = Clock::now();
    while (lockstep_) {
      if (StopRequested()) return false;
      bool all = true;
      for (const auto& io : io_) {
        all = all && io->pose.Subscriptions() > 0 && io->imu.Subscriptions() > 0 &&
              io->flow.Subscriptions() > 0 && io->compass.Subscriptions() > 0 &&
              io->battery.Subscriptions() > 0 && io->relative.Subscriptions() > 0 &&
              io->sync.Subscriptions() > 0;
      }
      for (const auto& io : io_)
        all = all && static_cast<int>(io->truth.Subscriptions()) >= truth_subscribers_;
      if (all) break;
      if (Since(start) > startup_timeout_) {
        throw std::runtime_error(
            "the vehicle nodes' sensor subscriptions did not appear within startup_timeout");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    const double dt = world_->physics_dt();
    const int steps = static_cast<int>(std::lround(duration_ / dt));
    const int every = std::max(1, static_cast<int>(std::lround(scenario_.rti.sample_time / dt)));
    const auto wall_start = Clock::now();
    for (int step = 0; step <= steps; ++step) {
      if (StopRequested()) return false;
      const double t = world_->time();
      PublishMeasurements();
      if (step % every == 0 && !ControlPeriod(t, step == 0)) return false;
      if (!lockstep_) {  // free-running: simulated time follows the wall clock
        const double ahead = t - Since(wall_start);
        if (ahead > 0) std::this_thread::sleep_for(std::chrono::duration<double>(ahead));
        ReadSetpoints(t, false);
      }
      if (step < steps) world_->StepOnce();
    }
    return true;
  }

  double time() const { return world_->time(); }
  int dead() const {
    int n = 0;
    for (const auto& io : io_) n += io->live ? 0 : 1;
    return n;
  }

 private:
  void PublishMeasurements() {
    Measurement m;
    while (world_->PopMeasurement(&m)) {
      VehicleIo& io = *io_.at(static_cast<std::size_t>(m.vehicle));
      ++io.seq;
      io.order.push_back(static_cast<std::uint8_t>(m.kind));
      switch (m.kind) {
        case SensorKind::kMocapPose:
          io.pose.Write(ToPose(m));
          break;
        case SensorKind::kImu:
          io.imu.Write(ToImu(m, io.body_frame.c_str()));
          break;
        case SensorKind::kOpticalFlow:
          io.flow.Write(ToOpticalFlow(m));
          break;
        case SensorKind::kCompass:
          io.compass.Write(ToHeading(m));
          break;
        case SensorKind::kBattery:
          io.battery.Write(ToBattery(m));
          break;
        case SensorKind::kRelative:
          io.relative.Write(ToRelative(m, io.body_frame.c_str()));
          break;
      }
    }
  }

  void SendSyncs(double t) {
    for (auto& io : io_) {
      fnmpc_msgs_msg_dds__SimSync_ s{};
      s.header.stamp = ToRosTime(t);
      s.header.frame_id = const_cast<char*>("");
      s.measurements = io->sync_measurements;
      s.first = io->sync_first;
      s.order = {static_cast<std::uint32_t>(io->sync_order.size()),
                 static_cast<std::uint32_t>(io->sync_order.size()), io->sync_order.data(), false};
      io->sync.Write(s);
    }
  }

  // Takes the setpoints; only answers stamped `t` count in lockstep.
  void ReadSetpoints(double t, bool lockstep) {
    for (std::size_t i = 0; i < io_.size(); ++i) {
      VehicleIo& io = *io_[i];
      io.setpoint.TakeAll([&](const fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_& s) {
        if (lockstep && FromRosTime(s.header.stamp) != FromRosTime(ToRosTime(t))) return;
        io.command.thrust = s.thrust;
        io.command.throttle = s.throttle;
        io.command.roll = s.roll;
        io.command.pitch = s.pitch;
        io.command.yaw = s.yaw;
        io.answered = true;
        if (!io.live && io.ever_answered)
          Log(o_.fully_qualified_name(), "vehicle {} answered again: back in control", io.name);
        io.live = true;
        io.ever_answered = true;
        if (!lockstep) world_->SetCommand(static_cast<int>(i), io.command);
      });
    }
  }

  bool ControlPeriod(double t, bool first) {
    rosgraph_msgs_msg_dds__Clock_ clock{};
    clock.clock = ToRosTime(t);
    clock_pub_->Write(clock);
    std::vector<Vec3> positions;
    for (std::size_t i = 0; i < io_.size(); ++i) {
      const sim::TrueState x = world_->GetTrueState(static_cast<int>(i));
      positions.push_back(x.position);
      io_[i]->truth.Write(ToOdometry(t, kWorldFrame, io_[i]->body_frame.c_str(), x.position,
                                     x.velocity, x.euler, x.body_rates));
      io_[i]->answered = false;
    }
    if (truth_csv_.is_open()) {
      for (std::size_t i = 0; i < io_.size(); ++i) {
        const sim::TrueState x = world_->GetTrueState(static_cast<int>(i));
        const double e =
            onboard::FormationError(scenario_, static_cast<int>(i), positions, x.euler.z());
        truth_csv_ << fmt::format("{:.3f},{},{},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f}\n", t,
                                  io_[i]->name, io_[i]->live ? 1 : 0, x.position.x(),
                                  x.position.y(), x.position.z(), x.euler.z(), e);
      }
      truth_csv_.flush();  // a watcher (the kill test, a plot) sees each control instant
    }
    if (!lockstep_) return true;
    for (auto& io : io_) {
      io->sync_measurements = io->seq;
      io->sync_first = io->seq - io->order.size();
      io->sync_order.swap(io->order);
      io->order.clear();
    }
    SendSyncs(t);
    const auto start = Clock::now();
    auto last_sync = start;
    while (true) {
      if (StopRequested()) return false;
      ReadSetpoints(t, true);
      bool waiting = false;
      const double waited = Since(start);
      for (auto& io : io_) {
        if (!io->live || io->answered) continue;
        const double limit = io->ever_answered ? vehicle_timeout_ : startup_timeout_;
        if (waited > limit) {
          io->live = false;
          Log(o_.fully_qualified_name(),
              "vehicle {} silent for {:.1f} s (wall) at t = {:.2f} s: declared dead, its autopilot "
              "flies the failsafe descent",
              io->name, waited, t);
        } else {
          waiting = true;
        }
      }
      if (!waiting) break;
      if (Since(last_sync) > 0.2 && (first || AnyUnstarted())) {
        SendSyncs(t);
        last_sync = Clock::now();
      }
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    for (std::size_t i = 0; i < io_.size(); ++i) {
      VehicleIo& io = *io_[i];
      if (!io.answered) io.command = Failsafe(static_cast<int>(i), io.command);
      world_->SetCommand(static_cast<int>(i), io.command);
    }
    return true;
  }

  bool AnyUnstarted() const {
    for (const auto& io : io_) {
      if (io->live && !io->ever_answered) return true;
    }
    return false;
  }

  // The ROS 1 sim_node's failsafe of the emulated autopilot.
  sim::AttitudeCommand Failsafe(int i, const sim::AttitudeCommand& last) const {
    const sim::TrueState x = world_->GetTrueState(i);
    sim::AttitudeCommand c;
    c.yaw = last.yaw;
    c.roll = c.pitch = 0.0;
    c.throttle = kNaN;
    const bool on_ground = x.position.z() < sim::World::kRestHeight + 0.03;
    const bool was_off = last.thrust == 0.0 && std::isnan(last.throttle);
    if (on_ground || was_off) {
      c.thrust = 0.0;
      return c;
    }
    const double mass = scenario_.vehicles[i].params.mass;
    const double gain = 2.0;  // [1/s] vertical-speed loop of the emulated autopilot
    const double tilt = std::max(0.5, std::cos(x.euler.x()) * std::cos(x.euler.y()));
    c.thrust = mass * (kGravity + gain * (-failsafe_descent_speed_ - x.velocity.z())) / tilt;
    return c;
  }

  const NodeOptions& o_;
  config::ScenarioConfig scenario_;
  double duration_ = 0.0, vehicle_timeout_ = 2.0, startup_timeout_ = 60.0,
         failsafe_descent_speed_ = 0.3;
  bool lockstep_ = true;
  int truth_subscribers_ = 0;
  std::unique_ptr<sim::World> world_;
  Participant participant_;
  std::unique_ptr<Writer<rosgraph_msgs_msg_dds__Clock_>> clock_pub_;
  std::vector<std::unique_ptr<VehicleIo>> io_;
  std::ofstream truth_csv_;
};

}  // namespace
}  // namespace fnmpc::ros2

int main(int argc, char** argv) {
  using namespace fnmpc::ros2;
  return RunNodeMain(argc, argv, "sim", [](const NodeOptions& options) {
    SimNode node(options);
    const bool finished = node.Run();
    Log(options.fully_qualified_name(), "{} at t = {:.2f} s, {} vehicle(s) declared dead",
        finished ? "scenario finished" : "stopped", node.time(), node.dead());
    return 0;
  });
}
