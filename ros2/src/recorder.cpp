// SPDX-License-Identifier: BSD-3-Clause
// fnmpc_ros2_record: records a formation's ROS 2 topics into the run folder of `fnmpc run`
// (one <vehicle>.csv with its columns, summary.json) so `fnmpc report OUT_DIR` plots a ROS 2
// run; the ROS 1 package's bag_to_csv role, live (docs/ros2.md). Subscribes to every vehicle's
// ground_truth, setpoint, status and odom; ends at simulated time `duration` (the scenario's)
// on /clock or on SIGINT, then writes. One row per setpoint; formation errors from the ground
// truth with onboard::FormationError and the runner's window/steady definitions; columns
// without a topic (the unblended NMPC command, aerodynamic forces, voltages) are NaN.
//   fnmpc_ros2_record --ros-args -p scenario:=FILE -p out:=DIR [-p duration:=S]
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <thread>

#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include "conversions.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/run_log.hpp"
#include "fnmpc/onboard/controller_setup.hpp"
#include "node_common.hpp"
#include "parameters.hpp"

namespace fnmpc::ros2 {
namespace {

struct TrueSample {
  Vec3 position = Vec3::Constant(kNaN), velocity = Vec3::Constant(kNaN),
       euler = Vec3::Constant(kNaN);
};
struct Setpoint {
  std::string phase;
  double thrust, throttle, roll, pitch, yaw;
};
struct Status {
  bool nmpc = false, fallback = false, guarded = false;
  std::string status, recovery, recovery_reason;
  double cost = kNaN, kkt = kNaN, solver_time = kNaN, voltage = kNaN;
  int sqp = 0, qp = 0, active = 0;
  long rejections = 0;
  Vec3 reference = Vec3::Constant(kNaN);
  std::vector<Vec3> neighbour_relative;
};
struct VehicleData {
  std::map<std::int64_t, TrueSample> truth;  // ns stamp -> sample
  std::map<std::int64_t, Setpoint> setpoints;
  std::map<std::int64_t, Status> status;
  std::map<std::int64_t, TrueSample> estimates;
};

std::int64_t Ns(const builtin_interfaces_msg_dds__Time_& t) {
  return std::int64_t{t.sec} * 1000000000 + t.nanosec;
}

template <class T>
const T* AtOrBefore(const std::map<std::int64_t, T>& m, std::int64_t t) {
  auto it = m.upper_bound(t);
  if (it == m.begin()) return nullptr;
  return &std::prev(it)->second;
}
double Mean(const std::vector<double>& v) {
  if (v.empty()) return kNaN;
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}
double Max(const std::vector<double>& v) {
  double m = kNaN;
  for (double x : v) m = std::isnan(m) ? x : std::max(m, x);
  return m;
}
nlohmann::json Num(double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(); }

struct VehicleTopics {
  VehicleTopics(const Participant& p, const NodeOptions& o, const std::string& v)
      : setpoint(p, o.Topic("/" + v + "/" + topics::kSetpoint), {true, 1000}),
        status(p, o.Topic("/" + v + "/" + topics::kStatus), {true, 1000}),
        odom(p, o.Topic("/" + v + "/" + topics::kOdom), {true, 1000}) {}
  void CreateTruthReader(const Participant& p, const NodeOptions& o, const std::string& v) {
    truth = std::make_unique<Reader<nav_msgs_msg_dds__Odometry_>>(
        p, o.Topic("/" + v + "/" + topics::kGroundTruth), QosProfile{true, 1000});
  }
  std::unique_ptr<Reader<nav_msgs_msg_dds__Odometry_>> truth;
  Reader<fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_> setpoint;
  Reader<fnmpc_msgs_msg_dds__ControllerStatus_> status;
  Reader<nav_msgs_msg_dds__Odometry_> odom;
};

void Write(const config::ScenarioConfig& sc, const std::vector<VehicleData>& data,
           const std::string& dir) {
  const int nv = static_cast<int>(sc.vehicles.size());
  const auto trajectory = onboard::LeaderTrajectory(sc, sc.seed);
  std::filesystem::create_directories(dir);
  nlohmann::json vehicles = nlohmann::json::object();
  double mean_worst = kNaN, steady_worst = kNaN, max_worst = kNaN;
  auto worse = [](double a, double b) {
    return std::isnan(a) ? b : (std::isnan(b) ? a : std::max(a, b));
  };
  for (int i = 0; i < nv; ++i) {
    const auto& v = sc.vehicles[i];
    const VehicleData& d = data[i];
    std::ofstream csv(dir + "/" + v.name + ".csv");
    if (!csv) throw std::runtime_error("cannot write " + dir + "/" + v.name + ".csv");
    csv << experiment::kVehicleLogCsvHeader;
    std::vector<double> errors, steady_errors, tracking, solver_time;
    long fallbacks = 0, steps = 0;
    for (const auto& [stamp, sp] : d.setpoints) {
      const double t = static_cast<double>(stamp) * 1e-9;
      auto sample = [&](int k) {
        const TrueSample* s = AtOrBefore(data[k].truth, stamp);
        return s ? *s : TrueSample{};
      };
      std::vector<Vec3> positions(nv);
      for (int k = 0; k < nv; ++k) positions[k] = sample(k).position;
      const TrueSample x = sample(i);
      TrueSample e;
      if (auto it = d.estimates.find(stamp); it != d.estimates.end()) e = it->second;
      const Status* dg = nullptr;
      if (auto it = d.status.find(stamp); it != d.status.end()) dg = &it->second;
      const bool window = t >= sc.trajectory_start && t < config::LandingTime(sc, i);
      const bool steady =
          window && trajectory.TimeSinceStop(t - sc.trajectory_start) >= sc.metrics.settle_time;
      std::array<double, formation::kMaxNeighbours> err;
      err.fill(kNaN);
      std::array<Vec3, formation::kMaxNeighbours> rel, est_rel;
      rel.fill(Vec3::Constant(kNaN));
      est_rel.fill(Vec3::Constant(kNaN));
      double ferr = kNaN, track = kNaN;
      Vec3 ref = Vec3::Constant(kNaN);
      if (!v.leader) {
        ferr = onboard::FormationError(sc, i, positions, x.euler.z(), &err, &rel);
        if (window && std::isfinite(ferr)) errors.push_back(ferr);
        if (steady && std::isfinite(ferr)) steady_errors.push_back(ferr);
        if (dg) {
          for (std::size_t j = 0; j < dg->neighbour_relative.size() && j < 2; ++j)
            est_rel[j] = dg->neighbour_relative[j];
        }
      } else if (dg) {
        ref = dg->reference;
        track = (x.position - ref).norm();
        if (window && std::isfinite(track)) tracking.push_back(track);
      }
      if (dg && dg->nmpc) {
        ++steps;
        solver_time.push_back(dg->solver_time);
        if (dg->fallback) ++fallbacks;
      }
      const double nan = kNaN;
      fmt::print(
          csv,
          "{:.3f},{},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
          "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
          "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
          "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
          "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
          "{:d},{:.6g},{:.6g},{:.6g},{},{},{:d},{},{:d},{},{:.4f},{:.4f},{},{},{},"
          "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f}\n",
          t, sp.phase, x.position.x(), x.position.y(), x.position.z(), x.velocity.x(),
          x.velocity.y(), x.velocity.z(), x.euler.x(), x.euler.y(), x.euler.z(), e.position.x(),
          e.position.y(), e.position.z(), e.velocity.x(), e.velocity.y(), e.velocity.z(),
          e.euler.x(), e.euler.y(), e.euler.z(), sp.thrust, sp.throttle, sp.roll, sp.pitch, sp.yaw,
          nan, nan, nan, ref.x(), ref.y(), ref.z(), track, rel[0].x(), rel[0].y(), rel[0].z(),
          est_rel[0].x(), est_rel[0].y(), est_rel[0].z(), err[0], rel[1].x(), rel[1].y(),
          rel[1].z(), est_rel[1].x(), est_rel[1].y(), est_rel[1].z(), err[1], ferr, steady ? 1 : 0,
          dg ? dg->cost : nan, dg ? dg->kkt : nan, dg ? dg->solver_time : nan, dg ? dg->sqp : 0,
          dg ? dg->qp : 0, dg && dg->fallback ? 1 : 0, dg ? dg->status : std::string("?"),
          dg && dg->guarded ? 1 : 0, dg ? dg->rejections : 0, nan, dg ? dg->voltage : nan,
          dg ? dg->recovery : std::string("none"), dg ? dg->recovery_reason : std::string("none"),
          dg ? dg->active : 0, nan, nan, nan, nan, nan, nan);
    }
    nlohmann::json j;
    j["role"] = v.leader ? "leader" : "follower";
    j["control_steps"] = d.setpoints.size();
    j["nmpc_steps"] = steps;
    j["fallbacks"] = fallbacks;
    j["solver_time_max_s"] = Num(Max(solver_time));
    if (!v.leader) {
      j["formation_error_mean_m"] = Num(Mean(errors));
      j["formation_error_steady_state_mean_m"] = Num(Mean(steady_errors));
      j["formation_error_max_m"] = Num(Max(errors));
      nlohmann::json order = nlohmann::json::array();
      for (const auto& n : v.neighbours) order.push_back(n.vehicle);
      j["neighbours"] = order;
      mean_worst = worse(mean_worst, Mean(errors));
      steady_worst = worse(steady_worst, Mean(steady_errors));
      max_worst = worse(max_worst, Max(errors));
    } else {
      j["tracking_error_mean_m"] = Num(Mean(tracking));
      j["tracking_error_max_m"] = Num(Max(tracking));
    }
    vehicles[v.name] = j;
    fmt::print("{}: {} rows, {} ground-truth samples\n", v.name, d.setpoints.size(),
               d.truth.size());
  }
  nlohmann::json s;
  s["scenario"] = sc.name;
  s["source"] = "ROS 2 topics (fnmpc_ros2_record)";
  s["seed"] = sc.seed;
  s["formation_window_s"] = {sc.trajectory_start, sc.landing_time};
  s["sample_time_s"] = sc.rti.sample_time;
  s["steady_state_formation_error_m"] = Num(steady_worst);
  s["mean_formation_error_m"] = Num(mean_worst);
  s["max_formation_error_m"] = Num(max_worst);
  s["vehicles"] = vehicles;
  std::ofstream(dir + "/summary.json") << s.dump(2) << "\n";
}

int Record(const NodeOptions& o) {
  const std::string scenario_file = o.RequiredString("scenario");
  const std::string out = o.RequiredString("out");
  const config::ScenarioConfig sc = config::LoadScenarioFile(scenario_file);
  double duration = o.Double("duration", -1.0);
  if (duration <= 0.0) duration = sc.duration;
  Participant participant;
  Reader<rosgraph_msgs_msg_dds__Clock_> clock(participant, o.Topic("/clock"), {true, 1000});
  std::vector<std::unique_ptr<VehicleTopics>> topics;
  for (const auto& v : sc.vehicles)
    topics.push_back(std::make_unique<VehicleTopics>(participant, o, v.name));
  std::vector<VehicleData> data(sc.vehicles.size());
  // The simulator starts when the ground-truth readers match (ground_truth_subscribers): those
  // are created only after the vehicle nodes' setpoint writers are matched, so that the first
  // setpoints are not published before the recorder can receive them (DDS topics are volatile).
  const auto wait_start = std::chrono::steady_clock::now();
  for (bool all = false; !all && !StopRequested();) {
    all = true;
    for (const auto& t : topics)
      all = all && t->setpoint.Publications() > 0 && t->status.Publications() > 0;
    if (std::chrono::steady_clock::now() - wait_start > std::chrono::seconds(60)) {
      throw std::runtime_error(
          "the vehicle nodes' setpoint and status writers did not appear within 60 s");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  for (std::size_t i = 0; i < topics.size(); ++i)
    topics[i]->CreateTruthReader(participant, o, sc.vehicles[i].name);
  Log(o.fully_qualified_name(), "recording {} vehicles of {} until t = {:.1f} s into {}",
      sc.vehicles.size(), scenario_file, duration, out);
  double now = -1.0;
  auto take_all = [&] {
    clock.TakeAll(
        [&](const rosgraph_msgs_msg_dds__Clock_& c) { now = std::max(now, FromRosTime(c.clock)); });
    for (std::size_t i = 0; i < topics.size(); ++i) {
      VehicleData& d = data[i];
      topics[i]->truth->TakeAll([&](const nav_msgs_msg_dds__Odometry_& m) {
        TrueSample s;
        FromOdometry(m, &s.position, &s.velocity, &s.euler);
        d.truth[Ns(m.header.stamp)] = s;
      });
      topics[i]->odom.TakeAll([&](const nav_msgs_msg_dds__Odometry_& m) {
        TrueSample s;
        FromOdometry(m, &s.position, &s.velocity, &s.euler);
        d.estimates[Ns(m.header.stamp)] = s;
      });
      topics[i]->setpoint.TakeAll([&](const fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_& m) {
        d.setpoints[Ns(m.header.stamp)] = {
            m.phase ? m.phase : "", m.thrust, m.throttle, m.roll, m.pitch, m.yaw};
      });
      topics[i]->status.TakeAll([&](const fnmpc_msgs_msg_dds__ControllerStatus_& m) {
        Status s;
        s.nmpc = m.nmpc;
        s.fallback = m.fallback;
        s.guarded = m.guarded;
        s.status = m.status ? m.status : "";
        s.recovery = m.recovery ? m.recovery : "none";
        s.recovery_reason = m.recovery_reason ? m.recovery_reason : "none";
        s.cost = m.cost;
        s.kkt = m.kkt;
        s.solver_time = m.solver_time;
        s.voltage = m.voltage;
        s.sqp = m.sqp_iterations;
        s.qp = m.qp_iterations;
        s.active = m.active_neighbours;
        s.rejections = static_cast<long>(m.estimator_rejections);
        s.reference = Vec3(m.reference.x, m.reference.y, m.reference.z);
        for (std::uint32_t k = 0; k < m.neighbour_relative._length; ++k) {
          const auto& p = m.neighbour_relative._buffer[k];
          s.neighbour_relative.emplace_back(p.x, p.y, p.z);
        }
        d.status[Ns(m.header.stamp)] = s;
      });
    }
  };
  // Until the simulated end, then 0.5 s (wall) more for the last period's answers.
  std::chrono::steady_clock::time_point end{};
  while (!StopRequested()) {
    take_all();
    if (now >= duration - 1e-9 && end == std::chrono::steady_clock::time_point{}) {
      end = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
    }
    if (end != std::chrono::steady_clock::time_point{} && std::chrono::steady_clock::now() >= end)
      break;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  take_all();
  Write(sc, data, out);
  Log(o.fully_qualified_name(), "wrote {} (last /clock t = {:.2f} s)", out, now);
  return 0;
}

}  // namespace
}  // namespace fnmpc::ros2

int main(int argc, char** argv) {
  using namespace fnmpc::ros2;
  return RunNodeMain(argc, argv, "record", Record);
}
