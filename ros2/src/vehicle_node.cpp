// SPDX-License-Identifier: BSD-3-Clause
// fnmpc_ros2_vehicle: one vehicle's estimator + NMPC (formation::VehicleController built by
// onboard::ControllerConfigFor, as `fnmpc run` builds it) on ROS 2 topics in its namespace
// (docs/ros2.md). The ROS 1 vehicle_node's roles:
//  * lockstep (parameter lockstep: true): measurements are buffered per topic; on each SimSync
//    the node waits until it has every measurement the sync counts, fuses them in the
//    simulator's delivery order, runs Control(t_sync) and answers with a setpoint stamped
//    t_sync;
//  * free-running: each measurement goes to the estimators on arrival; Control runs every
//    sample time on the node's clock (the simulator's /clock).
// Publishes the setpoint, the estimate (odom) and the controller status.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <deque>
#include <memory>
#include <thread>

#include "conversions.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/onboard/controller_setup.hpp"
#include "node_common.hpp"
#include "parameters.hpp"

namespace fnmpc::ros2 {
namespace {

static_assert(fnmpc_msgs_SimSync_IMU == static_cast<int>(SensorKind::kImu));
static_assert(fnmpc_msgs_SimSync_RELATIVE == static_cast<int>(SensorKind::kRelative));
static_assert(fnmpc_msgs_SimSync_MOCAP_POSE == static_cast<int>(SensorKind::kMocapPose));
static_assert(fnmpc_msgs_SimSync_OPTICAL_FLOW == static_cast<int>(SensorKind::kOpticalFlow));
static_assert(fnmpc_msgs_SimSync_COMPASS == static_cast<int>(SensorKind::kCompass));
static_assert(fnmpc_msgs_SimSync_BATTERY == static_cast<int>(SensorKind::kBattery));

struct Sync {
  double t;
  std::uint64_t measurements, first;
  std::vector<std::uint8_t> order;
};

class VehicleNode {
 public:
  explicit VehicleNode(const NodeOptions& o)
      : o_(o),
        scenario_(config::LoadScenarioFile(o.RequiredString("scenario"))),
        name_(o.String("vehicle", o.node_namespace().substr(o.node_namespace().rfind('/') + 1))),
        lockstep_(o.Bool("lockstep", false)),
        setpoint_subscribers_(o.Int("setpoint_subscribers", 1)),
        setpoint_pub_(participant_, o.Topic(topics::kSetpoint), StreamQos(lockstep_)),
        odom_pub_(participant_, o.Topic(topics::kOdom), StreamQos(lockstep_)),
        status_pub_(participant_, o.Topic(topics::kStatus), StreamQos(lockstep_)),
        pose_(participant_, o.Topic(topics::kMocapPose), SensorQos(lockstep_)),
        imu_(participant_, o.Topic(topics::kImu), SensorQos(lockstep_)),
        flow_(participant_, o.Topic(topics::kOpticalFlow), SensorQos(lockstep_)),
        compass_(participant_, o.Topic(topics::kCompass), SensorQos(lockstep_)),
        battery_(participant_, o.Topic(topics::kBattery), SensorQos(lockstep_)),
        relative_(participant_, o.Topic(topics::kRelative), SensorQos(lockstep_)),
        sync_(participant_, o.Topic(topics::kSync), QosProfile::Default()),
        clock_(participant_, o.Topic("/clock"), StreamQos(lockstep_)) {
    for (std::size_t i = 0; i < scenario_.vehicles.size(); ++i) {
      if (scenario_.vehicles[i].name == name_) index_ = static_cast<int>(i);
    }
    if (index_ < 0) {
      throw std::invalid_argument(
          fmt::format("parameter vehicle of {} = '{}' names no vehicle of {}",
                      o.fully_qualified_name(), name_, o.RequiredString("scenario")));
    }
    const auto& v = scenario_.vehicles[index_];
    if (scenario_.leader_mode == "manual" && v.leader) {
      throw std::invalid_argument(
          fmt::format("{}: the manual leader has no controller, start no vehicle node for '{}'",
                      o.RequiredString("scenario"), name_));
    }
    int seed = o.Int("seed", -1);
    if (seed < 0) seed = static_cast<int>(scenario_.seed);
    const auto trajectory = onboard::LeaderTrajectory(scenario_, static_cast<std::uint64_t>(seed));
    controller_ = std::make_unique<formation::VehicleController>(
        onboard::ControllerConfigFor(scenario_, index_, trajectory));
    frame_ = v.leader ? std::string(kWorldFrame) : name_ + "/mpc";
    body_frame_ = name_ + "/base_link";
    Log(o.fully_qualified_name(), "vehicle {} ({}, index {}): {}", name_,
        v.leader ? "leader" : "follower", index_,
        lockstep_ ? "lockstep with the simulator node" : "free-running on /clock");
  }

  void Spin() {
    while (!StopRequested()) {
      pose_.TakeAll([this](const auto& m) { Receive(FromPose(m, index_)); });
      imu_.TakeAll([this](const auto& m) { Receive(FromImu(m, index_)); });
      flow_.TakeAll([this](const auto& m) { Receive(FromOpticalFlow(m, index_)); });
      compass_.TakeAll([this](const auto& m) { Receive(FromHeading(m, index_)); });
      battery_.TakeAll([this](const auto& m) { Receive(FromBattery(m, index_)); });
      relative_.TakeAll([this](const auto& m) { Receive(FromRelative(m, index_)); });
      if (lockstep_) {
        sync_.TakeAll([this](const fnmpc_msgs_msg_dds__SimSync_& s) {
          syncs_.push_back(
              {FromRosTime(s.header.stamp), s.measurements, s.first,
               std::vector<std::uint8_t>(s.order._buffer, s.order._buffer + s.order._length)});
        });
        AnswerSyncs();
      } else {
        clock_.TakeAll(
            [this](const rosgraph_msgs_msg_dds__Clock_& c) { now_ = FromRosTime(c.clock); });
        if (std::isfinite(now_) &&
            (!std::isfinite(last_step_) || now_ >= last_step_ + scenario_.rti.sample_time)) {
          Step(now_);
        }
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }

 private:
  void Receive(Measurement m) {
    if (lockstep_) {
      queues_.at(static_cast<std::size_t>(m.kind)).push_back(m);
      ++received_;
    } else {
      m.arrival = std::isfinite(now_) ? now_ : m.stamp;
      controller_->Process(m);
    }
  }

  void AnswerSyncs() {
    if (!std::isfinite(last_answered_) &&
        static_cast<int>(setpoint_pub_.Subscriptions()) < setpoint_subscribers_) {
      return;  // the syncs wait in the queue; the simulator repeats the first until answered
    }
    while (!syncs_.empty()) {
      const Sync& sync = syncs_.front();
      if (sync.t == last_answered_) {  // a repeated sync (start-up): repeat the answer
        setpoint_pub_.Write(last_setpoint_);
        syncs_.pop_front();
        continue;
      }
      if (sync.t < last_answered_) {
        syncs_.pop_front();
        continue;
      }
      if (received_ < sync.measurements) return;  // still in flight
      Fuse(sync);
      const double t = sync.t;
      syncs_.pop_front();
      Step(t);
    }
  }

  void Fuse(const Sync& sync) {
    std::array<std::size_t, kNumSensorKinds> need{};
    for (const std::uint8_t k : sync.order) {
      if (k >= kNumSensorKinds)
        throw std::runtime_error(fmt::format("SimSync: unknown sensor kind {}", k));
      ++need[k];
    }
    for (std::size_t k = 0; k < need.size(); ++k) {
      if (queues_[k].size() < need[k]) {
        throw std::runtime_error(
            fmt::format("SimSync at t = {} orders {} measurements of kind {}, only {} received",
                        sync.t, need[k], k, queues_[k].size()));
      }
    }
    if (fused_ < sync.first) {  // syncs lost: fuse the earlier ones by time of validity
      for (std::uint64_t n = fused_; n < sync.first; ++n) {
        std::size_t best = queues_.size();
        for (std::size_t k = 0; k < queues_.size(); ++k) {
          if (queues_[k].size() <= need[k]) continue;
          if (best == queues_.size() || queues_[k].front().stamp < queues_[best].front().stamp)
            best = k;
        }
        if (best == queues_.size()) break;
        FuseOne(&queues_[best], sync.t);
      }
    }
    for (const std::uint8_t k : sync.order) FuseOne(&queues_[k], sync.t);
  }

  void FuseOne(std::deque<Measurement>* queue, double t) {
    Measurement m = queue->front();
    queue->pop_front();
    m.arrival = t;
    controller_->Process(m);
    ++fused_;
  }

  void Step(double t) {
    formation::ControlOutput out = controller_->Control(t);
    last_setpoint_ = ToSetpoint(out);
    setpoint_pub_.Write(last_setpoint_);
    controller_->Diagnose(&out);  // KKT value and cost after the command went out
    last_answered_ = t;
    last_step_ = t;
    PublishStatus(out);
    const auto& e = controller_->estimates().own;
    if (e.valid) {
      odom_pub_.Write(ToOdometry(t, frame_.c_str(), body_frame_.c_str(), e.position, e.velocity,
                                 e.euler, Vec3::Constant(kNaN)));
    }
  }

  void PublishStatus(const formation::ControlOutput& out) {
    fnmpc_msgs_msg_dds__ControllerStatus_ s{};
    s.header.stamp = ToRosTime(out.time);
    s.header.frame_id = const_cast<char*>("");
    s.phase = const_cast<char*>(formation::ToString(out.phase).data());
    s.nmpc = out.nmpc;
    status_text_ = std::string(rti::ToString(out.status));
    s.status = status_text_.data();
    s.cost = out.cost;
    s.kkt = out.kkt;
    s.solver_time = out.solver_time;
    s.sqp_iterations = out.sqp_iterations;
    s.qp_iterations = out.qp_iterations;
    s.fallback = out.fallback;
    s.fallback_count = controller_->fallbacks();
    s.guarded = out.guarded;
    s.estimator_rejections = controller_->estimator_rejections();
    s.reference = {out.reference.x(), out.reference.y(), out.reference.z()};
    s.voltage = out.voltage;
    s.recovery = const_cast<char*>(formation::ToString(out.recovery).data());
    s.recovery_reason = const_cast<char*>(formation::ToString(out.recovery_reason).data());
    s.active_neighbours = out.active_neighbours;
    const auto& nbs = controller_->config().neighbours;
    ids_.clear();
    relative_points_.clear();
    for (std::size_t j = 0; j < nbs.size(); ++j) {
      ids_.push_back(nbs[j].vehicle);
      const Vec3 r = j < controller_->estimates().neighbours.size()
                         ? Vec3(controller_->estimates().neighbours[j].head<3>())
                         : Vec3::Constant(kNaN);
      relative_points_.push_back({r.x(), r.y(), r.z()});
    }
    s.neighbour_ids = {static_cast<std::uint32_t>(ids_.size()),
                       static_cast<std::uint32_t>(ids_.size()), ids_.data(), false};
    s.neighbour_relative = {static_cast<std::uint32_t>(relative_points_.size()),
                            static_cast<std::uint32_t>(relative_points_.size()),
                            relative_points_.data(), false};
    status_pub_.Write(s);
  }

  const NodeOptions& o_;
  config::ScenarioConfig scenario_;
  std::string name_;
  bool lockstep_;
  // Readers the setpoint writer must have matched before the first answer in lockstep (the
  // simulator, plus a recorder or another program reading the setpoints): a reader that saw
  // the writer may not yet be matched on the writer's side, and a volatile writer's samples
  // before that match are lost to it.
  int setpoint_subscribers_;
  Participant participant_;
  Writer<fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_> setpoint_pub_;
  Writer<nav_msgs_msg_dds__Odometry_> odom_pub_;
  Writer<fnmpc_msgs_msg_dds__ControllerStatus_> status_pub_;
  Reader<geometry_msgs_msg_dds__PoseStamped_> pose_;
  Reader<sensor_msgs_msg_dds__Imu_> imu_;
  Reader<fnmpc_msgs_msg_dds__OpticalFlow_> flow_;
  Reader<fnmpc_msgs_msg_dds__Heading_> compass_;
  Reader<sensor_msgs_msg_dds__BatteryState_> battery_;
  Reader<fnmpc_msgs_msg_dds__RelativeObservation_> relative_;
  Reader<fnmpc_msgs_msg_dds__SimSync_> sync_;
  Reader<rosgraph_msgs_msg_dds__Clock_> clock_;
  int index_ = -1;
  std::unique_ptr<formation::VehicleController> controller_;
  std::string frame_, body_frame_, status_text_;
  std::vector<std::int32_t> ids_;
  std::vector<geometry_msgs_msg_dds__Point_> relative_points_;
  std::array<std::deque<Measurement>, kNumSensorKinds> queues_;
  std::uint64_t received_ = 0, fused_ = 0;
  std::deque<Sync> syncs_;
  double last_answered_ = kNaN, last_step_ = kNaN, now_ = kNaN;
  fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_ last_setpoint_{};
};

}  // namespace
}  // namespace fnmpc::ros2

int main(int argc, char** argv) {
  using namespace fnmpc::ros2;
  return RunNodeMain(argc, argv, "vehicle_node", [](const NodeOptions& options) {
    VehicleNode node(options);
    node.Spin();
    return 0;
  });
}
