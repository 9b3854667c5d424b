// SPDX-License-Identifier: BSD-3-Clause
// sim_node: the MuJoCo world of a scenario (experiment::WorldConfigFor, as in `fnmpc run`).
// Publishes every vehicle's sensor topics at their rates (each measurement when it is
// delivered), its ground truth, and /clock; applies the vehicles' setpoints to the emulated
// autopilots. Each period's SimSync carries the kinds of the measurements delivered to the
// vehicle since the previous one, in delivery order (the fusion order of `fnmpc run`).
// Lockstep (docs/ros.md): simulated time advances one control period only when
// every live vehicle node has answered the current period's SimSync; a vehicle silent for
// ~vehicle_timeout wall seconds is declared dead and its autopilot flies the failsafe (level
// attitude, slow descent from the true vertical speed, motors off on the ground).
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

#include <cmath>
#include <map>
#include <vector>

#include "conversions.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"
#include "fnmpc/sim/world.hpp"
#include "fnmpc_ros/SimSync.h"

namespace fnmpc::ros_bridge {
namespace {

struct VehicleIo {
  std::string name;
  ros::Publisher pose, imu, flow, compass, battery, relative, sync, truth, true_battery;
  ros::Subscriber setpoint_sub;
  std::uint32_t seq = 0;            // measurements published so far (SimSync::measurements)
  std::vector<std::uint8_t> order;  // kinds published since the last control period
  fnmpc_ros::SimSync sync_msg;      // this period's sync (repeated during start-up)
  bool live = true;                 // false: declared dead, failsafe
  bool answered = false;            // answered the current period
  bool ever_answered = false;       // the first answer counts as "started"
  sim::AttitudeCommand command;
  double failsafe_since = kNaN;
};

class SimNode {
 public:
  SimNode(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh) {
    const std::string file = RequiredParam(pnh, "scenario");
    scenario_ = config::LoadScenarioFile(file);
    int seed = -1;  // < 0: the scenario's
    pnh.param("seed", seed, seed);
    if (seed < 0) seed = static_cast<int>(scenario_.seed);
    double duration = -1.0;  // <= 0: the scenario's
    pnh.param("duration", duration, duration);
    if (duration <= 0.0) duration = scenario_.duration;
    pnh.param("ground_truth_subscribers", truth_subscribers_, 0);
    pnh.param("vehicle_timeout", vehicle_timeout_, 2.0);
    pnh.param("startup_timeout", startup_timeout_, 60.0);
    pnh.param("failsafe_descent_speed", failsafe_descent_speed_, 0.3);
    auto positive = [&pnh](const char* name, double v) {
      if (!(v > 0.0)) {
        throw std::runtime_error("parameter " + pnh.resolveName(name) + " must be > 0, got " +
                                 std::to_string(v));
      }
    };
    positive("duration", duration);
    positive("vehicle_timeout", vehicle_timeout_);
    positive("startup_timeout", startup_timeout_);
    positive("failsafe_descent_speed", failsafe_descent_speed_);
    duration_ = duration;
    manual_ = scenario_.leader_mode == "manual";
    trajectory_ = onboard::LeaderTrajectory(scenario_, static_cast<std::uint64_t>(seed));
    world_ = std::make_unique<sim::World>(
        experiment::WorldConfigFor(scenario_, static_cast<std::uint64_t>(seed)));

    clock_pub_ = nh_.advertise<rosgraph_msgs::Clock>("/clock", 10);
    const int q = 1000;
    const auto hints = ros::TransportHints().tcpNoDelay();
    for (std::size_t i = 0; i < scenario_.vehicles.size(); ++i) {
      VehicleIo io;
      io.name = scenario_.vehicles[i].name;
      ros::NodeHandle v(nh_, "/" + io.name);
      io.pose = v.advertise<geometry_msgs::PoseStamped>(topics::kMocapPose, q);
      io.imu = v.advertise<sensor_msgs::Imu>(topics::kImu, q);
      io.flow = v.advertise<fnmpc_ros::OpticalFlow>(topics::kOpticalFlow, q);
      io.compass = v.advertise<fnmpc_ros::Heading>(topics::kCompass, q);
      io.battery = v.advertise<sensor_msgs::BatteryState>(topics::kBattery, q);
      io.relative = v.advertise<fnmpc_ros::RelativeMeasurement>(topics::kRelative, q);
      io.sync = v.advertise<fnmpc_ros::SimSync>(topics::kSync, 10);
      io.truth = v.advertise<nav_msgs::Odometry>(topics::kGroundTruth, 10);
      io.true_battery = v.advertise<sensor_msgs::BatteryState>(topics::kTrueBattery, 10);
      const int index = static_cast<int>(i);
      io.setpoint_sub = v.subscribe<fnmpc_ros::AttitudeThrustSetpoint>(
          topics::kSetpoint, 10, [this, index](const auto& m) { OnSetpoint(index, *m); }, {},
          hints);
      // A manually moved leader has no node: nothing to wait for.
      if (manual_ && index == scenario_.leader) io.live = false;
      io_.push_back(std::move(io));
    }
    ROS_INFO("sim_node: %s, %zu vehicles, seed %d, %.1f s, lockstep period %.3f s", file.c_str(),
             io_.size(), seed, duration_, scenario_.rti.sample_time);
  }

  /// Runs the scenario to its end; returns false when ROS shut down first.
  bool Run() {
    // Observers that must not miss the start (the rostest checker, rosbag) are waited for.
    // Meanwhile /clock says 1 ns: ROS treats time 0 as "not yet valid" and rosbag record
    // waits for a valid time before it subscribes. The first control period republishes it.
    const ros::WallTime start = ros::WallTime::now();
    while (truth_subscribers_ > 0 && ros::ok()) {
      rosgraph_msgs::Clock clock;
      clock.clock = ClockTime(0.0);
      clock_pub_.publish(clock);
      bool all = true;
      for (const VehicleIo& io : io_) {
        all = all && static_cast<int>(io.truth.getNumSubscribers()) >= truth_subscribers_;
      }
      if (all) break;
      if ((ros::WallTime::now() - start).toSec() > startup_timeout_) {
        throw std::runtime_error("no ground-truth subscriber after ~startup_timeout (parameter " +
                                 ros::NodeHandle("~").resolveName("ground_truth_subscribers") +
                                 ")");
      }
      ros::WallDuration(0.01).sleep();
    }
    const double dt = world_->physics_dt();
    const int steps = static_cast<int>(std::lround(duration_ / dt));
    const int every = std::max(1, static_cast<int>(std::lround(scenario_.rti.sample_time / dt)));
    for (int step = 0; step <= steps; ++step) {
      if (!ros::ok()) return false;
      const double t = world_->time();
      if (manual_) {
        Vec3 p, v;
        trajectory_.Sample(t - scenario_.trajectory_start, &p, &v);
        world_->SetState(scenario_.leader, scenario_.manual_start + p,
                         Vec3(0, 0, scenario_.vehicles[scenario_.leader].yaw), v, Vec3::Zero());
      }
      PublishMeasurements();
      if (step % every == 0) {
        if (!ControlPeriod(t, step == 0)) return false;
      }
      if (step < steps) world_->StepOnce();
    }
    return true;
  }

  [[nodiscard]] double time() const { return world_->time(); }

 private:
  void OnSetpoint(int i, const fnmpc_ros::AttitudeThrustSetpoint& s) {
    VehicleIo& io = io_[i];
    // Only the answer to the current period counts (late answers of a dead node are dropped).
    if (s.header.stamp != current_stamp_) return;
    io.command.thrust = s.thrust;
    io.command.throttle = s.throttle;
    io.command.roll = s.roll;
    io.command.pitch = s.pitch;
    io.command.yaw = s.yaw;
    io.answered = true;
    if (!io.live && io.ever_answered) {
      ROS_WARN("sim_node: vehicle %s answered again at t = %.2f s: back in control",
               io.name.c_str(), ToSec(s.header.stamp));
    }
    if (!io.live && !(manual_ && i == scenario_.leader)) io.live = true;
    io.ever_answered = true;
  }

  void PublishMeasurements() {
    Measurement m;
    while (world_->PopMeasurement(&m)) {
      VehicleIo& io = io_.at(static_cast<std::size_t>(m.vehicle));
      const std::uint32_t seq = io.seq++;
      io.order.push_back(SyncKind(m.kind));
      switch (m.kind) {
        case SensorKind::kMocapPose:
          io.pose.publish(ToPose(m, seq));
          break;
        case SensorKind::kImu:
          io.imu.publish(ToImu(m, io.name, seq));
          break;
        case SensorKind::kOpticalFlow:
          io.flow.publish(ToOpticalFlow(m, seq));
          break;
        case SensorKind::kCompass:
          io.compass.publish(ToHeading(m, seq));
          break;
        case SensorKind::kBattery:
          io.battery.publish(ToBattery(m, seq));
          break;
        case SensorKind::kRelative:
          io.relative.publish(ToRelative(m, io.name, seq));
          break;
      }
    }
  }

  /// One control period at time t: truth, /clock and syncs out, setpoints in (lockstep).
  bool ControlPeriod(double t, bool first) {
    current_stamp_ = ToRosTime(t);
    rosgraph_msgs::Clock clock;
    clock.clock = ClockTime(t);
    clock_pub_.publish(clock);
    for (std::size_t i = 0; i < io_.size(); ++i) {
      const sim::TrueState x = world_->GetTrueState(static_cast<int>(i));
      io_[i].truth.publish(
          ToOdometry(t, kWorldFrame, io_[i].name, x.position, x.velocity, x.euler, x.body_rates));
      sensor_msgs::BatteryState b;
      b.header.stamp = current_stamp_;
      b.voltage = static_cast<float>(x.voltage);
      b.present = true;
      io_[i].true_battery.publish(b);
      io_[i].answered = false;
    }
    MakeSyncs();
    SendSyncs();
    // Wait for every live vehicle. Before the first answer a vehicle gets startup_timeout
    // (node start, subscriptions), and the sync is repeated because it may have been
    // published before the vehicle subscribed.
    const ros::WallTime start = ros::WallTime::now();
    ros::WallTime last_sync = start;
    while (true) {
      ros::getGlobalCallbackQueue()->callAvailable(ros::WallDuration(0.0005));
      if (!ros::ok()) return false;
      bool waiting = false;
      const double waited = (ros::WallTime::now() - start).toSec();
      for (VehicleIo& io : io_) {
        if (!io.live || io.answered) continue;
        const double limit = io.ever_answered ? vehicle_timeout_ : startup_timeout_;
        if (waited > limit) {
          io.live = false;
          io.failsafe_since = t;
          ROS_ERROR(
              "sim_node: vehicle %s silent for %.1f s (wall) at t = %.2f s: declared dead, "
              "its autopilot flies the failsafe descent",
              io.name.c_str(), waited, t);
        } else {
          waiting = true;
        }
      }
      if (!waiting) break;
      if ((ros::WallTime::now() - last_sync).toSec() > 0.2 && (first || AnyUnstarted())) {
        SendSyncs();
        last_sync = ros::WallTime::now();
      }
    }
    for (std::size_t i = 0; i < io_.size(); ++i) {
      VehicleIo& io = io_[i];
      if (manual_ && static_cast<int>(i) == scenario_.leader) continue;
      if (!io.answered) io.command = Failsafe(static_cast<int>(i), io.command);
      world_->SetCommand(static_cast<int>(i), io.command);
    }
    return true;
  }

  static std::uint8_t SyncKind(SensorKind k) {
    switch (k) {
      case SensorKind::kMocapPose:
        return fnmpc_ros::SimSync::MOCAP_POSE;
      case SensorKind::kImu:
        return fnmpc_ros::SimSync::IMU;
      case SensorKind::kOpticalFlow:
        return fnmpc_ros::SimSync::OPTICAL_FLOW;
      case SensorKind::kCompass:
        return fnmpc_ros::SimSync::COMPASS;
      case SensorKind::kBattery:
        return fnmpc_ros::SimSync::BATTERY;
      case SensorKind::kRelative:
        return fnmpc_ros::SimSync::RELATIVE;
    }
    throw std::logic_error("sim_node: unknown sensor kind");
  }

  static ros::Time ClockTime(double t) {
    ros::Time c = ToRosTime(t);
    if (c.isZero()) c.fromNSec(1);
    return c;
  }

  bool AnyUnstarted() const {
    for (const VehicleIo& io : io_) {
      if (io.live && !io.ever_answered) return true;
    }
    return false;
  }

  /// The syncs of a new control period: the delivery order since the previous one.
  void MakeSyncs() {
    for (VehicleIo& io : io_) {
      fnmpc_ros::SimSync& s = io.sync_msg;
      s.header.stamp = current_stamp_;
      s.measurements = io.seq;
      s.first = io.seq - io.order.size();
      s.order.swap(io.order);
      io.order.clear();
    }
  }

  /// Publishes (or, during start-up, repeats) this period's syncs.
  void SendSyncs() {
    for (VehicleIo& io : io_) io.sync.publish(io.sync_msg);
  }

  /// The emulated autopilot's failsafe for a vehicle whose node went silent: level attitude,
  /// descent at failsafe_descent_speed from its own (true) vertical speed, motors off within
  /// 3 cm of the ground. A vehicle that never flew stays off.
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

  ros::NodeHandle nh_;
  config::ScenarioConfig scenario_;
  bool manual_ = false;
  formation::WaypointTrajectory trajectory_;
  std::unique_ptr<sim::World> world_;
  double duration_ = 0.0;
  int truth_subscribers_ = 0;
  double vehicle_timeout_ = 2.0, startup_timeout_ = 60.0, failsafe_descent_speed_ = 0.3;
  ros::Publisher clock_pub_;
  std::vector<VehicleIo> io_;
  ros::Time current_stamp_;
};

}  // namespace
}  // namespace fnmpc::ros_bridge

int main(int argc, char** argv) {
  ros::init(argc, argv, "sim_node");
  ros::NodeHandle pnh("~");
  try {
    fnmpc::ros_bridge::SimNode node{ros::NodeHandle(), pnh};
    if (!node.Run()) return 0;
    ROS_INFO("sim_node: scenario finished at t = %.2f s; idle until shutdown", node.time());
    bool exit_at_end = false;
    pnh.param("exit_at_end", exit_at_end, false);
    if (!exit_at_end) ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("sim_node: %s", e.what());
    return 1;
  }
  return 0;
}
