// SPDX-License-Identifier: BSD-3-Clause
// vehicle_node: one vehicle's estimator + NMPC (formation::VehicleController, leader or
// follower as its scenario entry says). Subscribes only to its own sensor topics (mocap, IMU,
// optical flow, compass, battery, relative measurements), publishes the attitude/thrust
// setpoint, the estimate, the predicted path and solver diagnostics. Plumbing only: the
// controller is built by app::ControllerConfigFor exactly as `fnmpc run` builds it.
//
// Two timing modes (docs/ros.md):
//  * lockstep (simulation): measurements are buffered; on each SimSync from sim_node the
//    node waits until it has received every measurement the sync counts, feeds them in the
//    simulator's delivery order (header.seq), runs Control(t_sync) and answers with a
//    setpoint stamped t_sync. Deterministic, the same order as the CLI's closed loop.
//  * free-running (flight): each measurement goes to the estimators on arrival; a timer on
//    ROS time (wall or /clock) runs Control every sample_time.
#include <nav_msgs/Path.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <algorithm>
#include <memory>
#include <vector>

#include "apps/fnmpc/scenario_runner.hpp"
#include "conversions.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc_ros/SimSync.h"

namespace fnmpc::ros_bridge {
namespace {

class VehicleNode {
 public:
  VehicleNode(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh) {
    const std::string scenario_file = RequiredParam(pnh, "scenario");
    scenario_ = config::LoadScenarioFile(scenario_file);
    name_ = RequiredParam(pnh, "vehicle");
    for (std::size_t i = 0; i < scenario_.vehicles.size(); ++i) {
      if (scenario_.vehicles[i].name == name_) index_ = static_cast<int>(i);
    }
    if (index_ < 0) {
      throw std::runtime_error("parameter " + pnh.resolveName("vehicle") + " = '" + name_ +
                               "' names no vehicle of " + scenario_file);
    }
    const auto& v = scenario_.vehicles[index_];
    std::string role;
    if (pnh.getParam("role", role) && role != (v.leader ? "leader" : "follower")) {
      throw std::runtime_error("parameter " + pnh.resolveName("role") + " = '" + role +
                               "' contradicts " + scenario_file + " (vehicle " + name_ + " is a " +
                               (v.leader ? "leader" : "follower") + ")");
    }
    if (scenario_.leader_mode == "manual" && v.leader) {
      throw std::runtime_error(scenario_file +
                               ": the manual leader has no controller, start no "
                               "vehicle_node for '" +
                               name_ + "'");
    }
    int seed = -1;  // < 0: the scenario's
    pnh.param("seed", seed, seed);
    if (seed < 0) seed = static_cast<int>(scenario_.seed);
    pnh.param("lockstep", lockstep_, false);
    const auto trajectory = app::LeaderTrajectory(scenario_, static_cast<std::uint64_t>(seed));
    controller_ = std::make_unique<formation::VehicleController>(
        app::ControllerConfigFor(scenario_, index_, trajectory));
    frame_ = v.leader ? std::string(kWorldFrame) : MpcFrame(name_);

    setpoint_pub_ = nh_.advertise<fnmpc_ros::AttitudeThrustSetpoint>(topics::kSetpoint, 10);
    estimate_pub_ = nh_.advertise<nav_msgs::Odometry>(topics::kEstimate, 10);
    path_pub_ = nh_.advertise<nav_msgs::Path>(topics::kPredictedPath, 2);
    diag_pub_ = nh_.advertise<fnmpc_ros::SolverDiagnostics>(topics::kDiagnostics, 10);

    // Large queues: in lockstep a whole control period of IMU samples arrives at once.
    const int q = 1000;
    auto hints = ros::TransportHints().tcpNoDelay();
    subs_.push_back(nh_.subscribe<geometry_msgs::PoseStamped>(
        topics::kMocapPose, q,
        [this](const auto& m) { Receive(FromPose(*m, index_), m->header.seq); }, {}, hints));
    subs_.push_back(nh_.subscribe<sensor_msgs::Imu>(
        topics::kImu, q, [this](const auto& m) { Receive(FromImu(*m, index_), m->header.seq); }, {},
        hints));
    subs_.push_back(nh_.subscribe<fnmpc_ros::OpticalFlow>(
        topics::kOpticalFlow, q,
        [this](const auto& m) { Receive(FromOpticalFlow(*m, index_), m->header.seq); }, {}, hints));
    subs_.push_back(nh_.subscribe<fnmpc_ros::Heading>(
        topics::kCompass, q,
        [this](const auto& m) { Receive(FromHeading(*m, index_), m->header.seq); }, {}, hints));
    subs_.push_back(nh_.subscribe<sensor_msgs::BatteryState>(
        topics::kBattery, q,
        [this](const auto& m) { Receive(FromBattery(*m, index_), m->header.seq); }, {}, hints));
    subs_.push_back(nh_.subscribe<fnmpc_ros::RelativeMeasurement>(
        topics::kRelative, q,
        [this](const auto& m) { Receive(FromRelative(*m, index_), m->header.seq); }, {}, hints));
    if (lockstep_) {
      sync_sub_ = nh_.subscribe<fnmpc_ros::SimSync>(
          topics::kSync, 10,
          [this](const auto& m) {
            pending_sync_ = *m;
            has_sync_ = true;
          },
          {}, hints);
    } else {
      timer_ = nh_.createTimer(ros::Duration(scenario_.sample_time),
                               [this](const ros::TimerEvent&) { Step(ros::Time::now().toSec()); });
    }
    ROS_INFO("vehicle_node %s (%s, vehicle %d of %s): %s", name_.c_str(),
             v.leader ? "leader" : "follower", index_, scenario_file.c_str(),
             lockstep_ ? "lockstep with sim_node" : "free-running on ROS time");
  }

  /// Lockstep: answers a pending sync once its measurements are all here.
  void Poll() {
    if (!lockstep_ || !has_sync_) return;
    const double t = ToSec(pending_sync_.header.stamp);
    if (t == last_answered_) {  // a repeated sync (start-up handshake): repeat the answer
      has_sync_ = false;
      setpoint_pub_.publish(last_setpoint_);
      return;
    }
    if (received_ < pending_sync_.measurements) return;  // still in flight
    // Do not answer before every sensor subscription is connected, or measurements
    // published before the connection would be lost (sim_node repeats the first sync).
    for (const auto& s : subs_) {
      if (s.getNumPublishers() == 0) return;
    }
    has_sync_ = false;
    std::sort(buffer_.begin(), buffer_.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (auto& [seq, m] : buffer_) {
      m.arrival = t;
      controller_->Process(m);
    }
    buffer_.clear();
    Step(t);
  }

 private:
  void Receive(Measurement m, std::uint32_t seq) {
    if (lockstep_) {
      buffer_.emplace_back(seq, m);
      ++received_;
    } else {
      m.arrival = ros::Time::now().toSec();
      controller_->Process(m);
    }
  }

  void Step(double t) {
    formation::ControlOutput out = controller_->Control(t);
    last_setpoint_ = ToSetpoint(out);
    setpoint_pub_.publish(last_setpoint_);
    controller_->Diagnose(&out);  // KKT value and cost after the command went out
    last_answered_ = t;
    diag_pub_.publish(ToDiagnostics(out, *controller_));
    const auto& e = controller_->estimates().own;
    if (e.valid) {
      estimate_pub_.publish(
          ToOdometry(t, frame_, name_, e.position, e.velocity, e.euler, Vec3::Constant(kNaN)));
    }
    if (out.nmpc && path_pub_.getNumSubscribers() > 0) {
      nav_msgs::Path path;
      path.header.stamp = ToRosTime(t);
      path.header.frame_id = frame_;
      const auto points = controller_->PredictedPositions();
      for (std::size_t k = 0; k < points.size(); ++k) {
        geometry_msgs::PoseStamped p;
        p.header.stamp = ToRosTime(t + static_cast<double>(k) * scenario_.sample_time);
        p.header.frame_id = frame_;
        p.pose.position.x = points[k].x();
        p.pose.position.y = points[k].y();
        p.pose.position.z = points[k].z();
        p.pose.orientation.w = 1.0;
        path.poses.push_back(p);
      }
      path_pub_.publish(path);
    }
  }

  ros::NodeHandle nh_;
  config::ScenarioConfig scenario_;
  std::string name_;
  std::string frame_;
  int index_ = -1;
  bool lockstep_ = false;
  std::unique_ptr<formation::VehicleController> controller_;
  ros::Publisher setpoint_pub_, estimate_pub_, path_pub_, diag_pub_;
  std::vector<ros::Subscriber> subs_;
  ros::Subscriber sync_sub_;
  ros::Timer timer_;
  // Lockstep state.
  std::vector<std::pair<std::uint32_t, Measurement>> buffer_;
  std::uint64_t received_ = 0;
  fnmpc_ros::SimSync pending_sync_;
  bool has_sync_ = false;
  double last_answered_ = kNaN;
  fnmpc_ros::AttitudeThrustSetpoint last_setpoint_;
};

}  // namespace
}  // namespace fnmpc::ros_bridge

int main(int argc, char** argv) {
  ros::init(argc, argv, "vehicle_node");
  try {
    fnmpc::ros_bridge::VehicleNode node(ros::NodeHandle(), ros::NodeHandle("~"));
    while (ros::ok()) {
      ros::getGlobalCallbackQueue()->callAvailable(ros::WallDuration(0.001));
      node.Poll();
    }
  } catch (const std::exception& e) {
    ROS_FATAL("vehicle_node: %s", e.what());
    return 1;
  }
  return 0;
}
