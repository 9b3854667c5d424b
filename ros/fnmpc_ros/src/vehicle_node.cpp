// SPDX-License-Identifier: BSD-3-Clause
// vehicle_node: one vehicle's estimator + NMPC (formation::VehicleController, leader or
// follower as its scenario entry says). Subscribes only to its own sensor topics (mocap, IMU,
// optical flow, compass, battery, relative measurements), publishes the attitude/thrust
// setpoint, the estimate, the predicted path and solver diagnostics. Plumbing only: the
// controller is built by onboard::ControllerConfigFor exactly as `fnmpc run` builds it.
//
// Two timing modes (docs/ros.md):
//  * lockstep (simulation): measurements are buffered per topic; on each SimSync from
//    sim_node the node waits until it has received every measurement the sync counts, feeds
//    them in the simulator's delivery order (SimSync::order: the kind of each measurement
//    in delivery order; each topic is FIFO), runs Control(t_sync) and answers with a
//    setpoint stamped t_sync. Deterministic, the same order as the CLI's closed loop.
//  * free-running (flight): each measurement goes to the estimators on arrival; a timer on
//    ROS time (wall or /clock) runs Control every sample_time.
// With ~link (docs/autopilot.md) the setpoints go to the flight controller over MAVLink
// (onboard::OnboardLink, as `fnmpc fly`), whose measurements join the topics'; with
// ~link_clock: autopilot the steps follow the link's ticks (`fnmpc sim-link --lockstep`).
#include <nav_msgs/Path.h>
#include <ros/callback_queue.h>
#include <ros/names.h>
#include <ros/ros.h>

#include <algorithm>
#include <array>
#include <deque>
#include <memory>
#include <vector>

#include "conversions.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"
#include "fnmpc/onboard/onboard_link.hpp"
#include "fnmpc_ros/SimSync.h"

namespace fnmpc::ros_bridge {
namespace {

static_assert(fnmpc_ros::SimSync::MOCAP_POSE == static_cast<int>(SensorKind::kMocapPose));
static_assert(fnmpc_ros::SimSync::IMU == static_cast<int>(SensorKind::kImu));
static_assert(fnmpc_ros::SimSync::OPTICAL_FLOW == static_cast<int>(SensorKind::kOpticalFlow));
static_assert(fnmpc_ros::SimSync::COMPASS == static_cast<int>(SensorKind::kCompass));
static_assert(fnmpc_ros::SimSync::BATTERY == static_cast<int>(SensorKind::kBattery));
static_assert(fnmpc_ros::SimSync::RELATIVE == static_cast<int>(SensorKind::kRelative));

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
    // As `fnmpc run --compensation`: overrides the scenario's controller.compensation.
    std::string compensation;
    pnh.param("compensation", compensation, std::string());
    if (!compensation.empty()) {
      int level = 0;
      const std::string bad = formation::kCompensationChoice.Check(compensation, &level);
      if (!bad.empty()) {
        throw std::runtime_error("parameter " + pnh.resolveName("compensation") + ": " + bad);
      }
      scenario_.compensation = static_cast<formation::Compensation>(level);
    }
    const auto trajectory = onboard::LeaderTrajectory(scenario_, static_cast<std::uint64_t>(seed));
    // ~link: fly through the flight controller over MAVLink (docs/autopilot.md), the same
    // OnboardLink as `fnmpc fly`; the setpoint topic then records what was sent.
    onboard::OnboardLinkOptions link;
    pnh.param("link", link.link, std::string());
    pnh.param("autopilot", link.autopilot, std::string("px4"));
    pnh.param("link_settings", link.settings_file, std::string());
    std::string link_clock;
    pnh.param("link_clock", link_clock, std::string("local"));
    if (link_clock != "local" && link_clock != "autopilot") {
      throw std::runtime_error("parameter " + pnh.resolveName("link_clock") + " = '" + link_clock +
                               "': expected local or autopilot");
    }
    link.autopilot_clock = link_clock == "autopilot";
    const formation::ControllerConfig cc =
        onboard::ControllerConfigFor(scenario_, index_, trajectory);
    if (!link.link.empty()) {
      if (lockstep_) {
        throw std::runtime_error("parameters " + pnh.resolveName("link") + " and " +
                                 pnh.resolveName("lockstep") +
                                 ": the link's lockstep is ~link_clock: autopilot, not sim_node's");
      }
      link_ = std::make_unique<onboard::OnboardLink>(cc, index_, link);
      controller_ = &link_->controller();
      link_lockstep_ = link.autopilot_clock;
    } else {
      own_controller_ = std::make_unique<formation::VehicleController>(cc);
      controller_ = own_controller_.get();
    }
    frame_ = v.leader ? std::string(kWorldFrame) : MpcFrame(name_);

    setpoint_pub_ = nh_.advertise<fnmpc_ros::AttitudeThrustSetpoint>(topics::kSetpoint, 10);
    estimate_pub_ = nh_.advertise<nav_msgs::Odometry>(topics::kEstimate, 10);
    path_pub_ = nh_.advertise<nav_msgs::Path>(topics::kPredictedPath, 2);
    diag_pub_ = nh_.advertise<fnmpc_ros::SolverDiagnostics>(topics::kDiagnostics, 10);
    // Cooperative mode: this vehicle's plan on <ns>/<vehicle>/plan, its formation
    // neighbours' plans from theirs (the link is the ROS topic; controller.plan_timeout
    // decides what is late).
    if (scenario_.compensation >= formation::Compensation::kCooperative) {
      plan_pub_ = nh_.advertise<fnmpc_ros::Plan>(topics::kPlan, 2);
      const std::string parent = ros::names::parentNamespace(nh_.getNamespace());
      for (const auto& n : v.neighbours) {
        const std::string topic =
            (parent == "/" ? "" : parent) + "/" + n.vehicle + "/" + topics::kPlan;
        plan_subs_.push_back(nh_.subscribe<fnmpc_ros::Plan>(
            topic, 10,
            [this](const auto& m) {
              if (FromPlan(*m, &plan_)) controller_->ReceivePlan(plan_);
            },
            {}, ros::TransportHints().tcpNoDelay()));
      }
    }

    // Large queues: in lockstep a whole control period of IMU samples arrives at once.
    const int q = 1000;
    auto hints = ros::TransportHints().tcpNoDelay();
    subs_.push_back(nh_.subscribe<geometry_msgs::PoseStamped>(
        topics::kMocapPose, q, [this](const auto& m) { Receive(FromPose(*m, index_)); }, {},
        hints));
    subs_.push_back(nh_.subscribe<sensor_msgs::Imu>(
        topics::kImu, q, [this](const auto& m) { Receive(FromImu(*m, index_)); }, {}, hints));
    subs_.push_back(nh_.subscribe<fnmpc_ros::OpticalFlow>(
        topics::kOpticalFlow, q, [this](const auto& m) { Receive(FromOpticalFlow(*m, index_)); },
        {}, hints));
    subs_.push_back(nh_.subscribe<fnmpc_ros::Heading>(
        topics::kCompass, q, [this](const auto& m) { Receive(FromHeading(*m, index_)); }, {},
        hints));
    subs_.push_back(nh_.subscribe<sensor_msgs::BatteryState>(
        topics::kBattery, q, [this](const auto& m) { Receive(FromBattery(*m, index_)); }, {},
        hints));
    subs_.push_back(nh_.subscribe<fnmpc_ros::RelativeMeasurement>(
        topics::kRelative, q, [this](const auto& m) { Receive(FromRelative(*m, index_)); }, {},
        hints));
    if (link_lockstep_) {
      // Control steps on the link's ticks (Poll).
    } else if (lockstep_) {
      sync_sub_ = nh_.subscribe<fnmpc_ros::SimSync>(
          topics::kSync, 10, [this](const auto& m) { syncs_.push_back(*m); }, {}, hints);
    } else {
      timer_ = nh_.createTimer(ros::Duration(scenario_.rti.sample_time),
                               [this](const ros::TimerEvent&) { Step(ros::Time::now().toSec()); });
    }
    ROS_INFO("vehicle_node %s (%s, vehicle %d of %s): %s%s", name_.c_str(),
             v.leader ? "leader" : "follower", index_, scenario_file.c_str(),
             link_lockstep_ ? "lockstep with the link's autopilot"
                            : (lockstep_ ? "lockstep with sim_node" : "free-running on ROS time"),
             link_ ? (", flying over " + link_->describe()).c_str() : "");
    if (link_ && link_->moved_takeoff()) {
      ROS_INFO("vehicle_node %s: take-off at %.2f s instead of %.2f s (autopilot handshake)",
               name_.c_str(), link_->ready_time(), link_->scenario_takeoff_time());
    }
  }

  /// The link (~link): reads what came, steps on a tick (~link_clock: autopilot), logs the
  /// session's events. False once the link stopped commanding and has nothing more to do.
  void PollLink() {
    if (!link_) return;
    const double now = ros::Time::now().toSec();
    if (link_->Poll(link_lockstep_ ? 0.001 : 0.0, now)) Step(link_->tick_time());
    if (link_lockstep_ && link_->ticks() == 0 && now - last_hello_ >= 0.5) {
      link_->SayHello();
      last_hello_ = now;
    }
    std::string line;
    nlohmann::json event;
    while (link_->PopEvent(&line, &event))
      ROS_INFO("vehicle_node %s: %s", name_.c_str(), line.c_str());
    if (link_->stopped() && !stop_logged_) {
      stop_logged_ = true;
      ROS_WARN("vehicle_node %s: not commanding any more: %s", name_.c_str(),
               link_->stop_reason().c_str());
    }
  }

  /// Lockstep: answers the pending syncs, in turn, once their measurements are all here.
  void Poll() {
    while (lockstep_ && !syncs_.empty()) {
      const fnmpc_ros::SimSync& sync = syncs_.front();
      const double t = ToSec(sync.header.stamp);
      if (t == last_answered_) {  // a repeated sync (start-up handshake): repeat the answer
        syncs_.pop_front();
        setpoint_pub_.publish(last_setpoint_);
        continue;
      }
      if (t < last_answered_) {  // an older period (a stalled node catching up): answered
        syncs_.pop_front();
        continue;
      }
      if (received_ < sync.measurements) return;  // still in flight
      // Do not answer before every sensor subscription is connected, or measurements
      // published before the connection would be lost (sim_node repeats the first sync).
      for (const auto& s : subs_) {
        if (s.getNumPublishers() == 0) return;
      }
      Fuse(sync, t);
      syncs_.pop_front();
      Step(t);
    }
  }

 private:
  void Receive(Measurement m) {
    if (lockstep_) {
      // SimSync kinds are SensorKind's values (static_asserts below).
      queues_.at(static_cast<std::size_t>(m.kind)).push_back(m);
      ++received_;
    } else {
      m.arrival = ros::Time::now().toSec();
      controller_->Process(m);
    }
  }

  /// Feeds the measurements a sync covers to the controller in the simulator's delivery
  /// order: sync.order[i] is the kind of measurement sync.first + i, and each topic's
  /// messages arrive in publication order (one TCP stream per topic).
  void Fuse(const fnmpc_ros::SimSync& sync, double t) {
    std::array<std::size_t, kNumSensorKinds> need{};
    for (const std::uint8_t k : sync.order) {
      if (k >= kNumSensorKinds) throw std::runtime_error("SimSync: unknown sensor kind");
      ++need[k];
    }
    for (std::size_t k = 0; k < need.size(); ++k) {
      if (queues_[k].size() < need[k]) {
        throw std::runtime_error("SimSync at t = " + std::to_string(t) + " orders " +
                                 std::to_string(need[k]) + " measurements of kind " +
                                 std::to_string(k) + ", only " + std::to_string(queues_[k].size()) +
                                 " received");
      }
    }
    // Measurements of periods whose syncs were dropped (a node stalled for more than the
    // sync queue): their order is unknown, they go first, by time of validity.
    if (fused_ < sync.first) {
      const std::uint64_t gap = sync.first - fused_;
      ROS_WARN(
          "vehicle_node %s: %llu measurements before t = %.3f s without a delivery order "
          "(syncs lost), fused by time of validity",
          name_.c_str(), static_cast<unsigned long long>(gap), t);
      for (std::uint64_t n = 0; n < gap; ++n) {
        std::size_t best = queues_.size();
        for (std::size_t k = 0; k < queues_.size(); ++k) {
          if (queues_[k].size() <= need[k]) continue;
          if (best == queues_.size() || queues_[k].front().stamp < queues_[best].front().stamp) {
            best = k;
          }
        }
        if (best == queues_.size()) break;
        Fuse(&queues_[best], t);
      }
    }
    for (const std::uint8_t k : sync.order) Fuse(&queues_[k], t);
  }

  void Fuse(std::deque<Measurement>* queue, double t) {
    Measurement m = queue->front();
    queue->pop_front();
    m.arrival = t;
    controller_->Process(m);
    ++fused_;
  }

  void Step(double t) {
    formation::ControlOutput out;
    if (link_) {
      out = link_->Step(t);  // sent to the flight controller, diagnosed after
      last_setpoint_ = ToSetpoint(out);
      setpoint_pub_.publish(last_setpoint_);
    } else {
      out = controller_->Control(t);
      last_setpoint_ = ToSetpoint(out);
      setpoint_pub_.publish(last_setpoint_);
      controller_->Diagnose(&out);  // KKT value and cost after the command went out
    }
    if (plan_pub_ && controller_->MakePlan(&plan_)) plan_pub_.publish(ToPlan(plan_));
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
        p.header.stamp = ToRosTime(t + static_cast<double>(k) * scenario_.rti.sample_time);
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
  std::unique_ptr<formation::VehicleController> own_controller_;  // without ~link
  std::unique_ptr<onboard::OnboardLink> link_;                    // with ~link
  formation::VehicleController* controller_ = nullptr;            // either's controller
  bool link_lockstep_ = false;
  bool stop_logged_ = false;
  double last_hello_ = -1.0;
  ros::Publisher setpoint_pub_, estimate_pub_, path_pub_, diag_pub_, plan_pub_;
  std::vector<ros::Subscriber> subs_;
  std::vector<ros::Subscriber> plan_subs_;  // cooperative: the formation neighbours' plans
  formation::PlanMessage plan_;             // a plan being converted (either direction)
  ros::Subscriber sync_sub_;
  ros::Timer timer_;
  // Lockstep state.
  std::array<std::deque<Measurement>, kNumSensorKinds> queues_;  // per SensorKind, FIFO
  std::uint64_t received_ = 0, fused_ = 0;
  std::deque<fnmpc_ros::SimSync> syncs_;
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
      node.PollLink();
    }
  } catch (const std::exception& e) {
    ROS_FATAL("vehicle_node: %s", e.what());
    return 1;
  }
  return 0;
}
