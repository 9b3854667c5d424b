// SPDX-License-Identifier: BSD-3-Clause
// bag_to_csv BAG SCENARIO.yaml OUT_DIR: converts a recorded ROS run (simulation or flight)
// into the run folder of `fnmpc run` (one <vehicle>.csv with the same columns, summary.json)
// so `fnmpc report OUT_DIR` plots it. One row per setpoint of a vehicle (its control steps);
// the "true" state is the sim's ground_truth topic or, in flight, the motion-capture pose
// (velocity then NaN). Formation errors use onboard::FormationError on those positions and the
// runner's window/steady definitions; columns without a source are NaN (docs/ros.md).
#include <fmt/core.h>
#include <fmt/ostream.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "conversions.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::ros_bridge {
namespace {

struct TrueSample {
  Vec3 position = Vec3::Constant(kNaN), velocity = Vec3::Constant(kNaN),
       euler = Vec3::Constant(kNaN);
  double voltage = kNaN;
};

struct VehicleData {
  std::map<std::int64_t, TrueSample> truth;  // ns stamp -> sample
  std::map<std::int64_t, TrueSample> mocap;
  std::map<std::int64_t, double> true_voltage;
  std::map<std::int64_t, fnmpc_ros::AttitudeThrustSetpoint> setpoints;
  std::map<std::int64_t, fnmpc_ros::SolverDiagnostics> diagnostics;
  std::map<std::int64_t, nav_msgs::Odometry> estimates;
};

/// The latest entry at or before `t` (or nullptr).
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

int Convert(const std::string& bag_file, const std::string& scenario_file, const std::string& dir) {
  const config::ScenarioConfig sc = config::LoadScenarioFile(scenario_file);
  const int nv = static_cast<int>(sc.vehicles.size());
  std::vector<VehicleData> data(nv);
  std::map<std::string, int> index;
  for (int i = 0; i < nv; ++i) index["/" + sc.vehicles[i].name + "/"] = i;

  rosbag::Bag bag(bag_file, rosbag::bagmode::Read);
  rosbag::View view(bag);
  for (const rosbag::MessageInstance& mi : view) {
    const std::string& topic = mi.getTopic();
    int i = -1;
    std::string rest;
    for (const auto& [prefix, k] : index) {
      if (topic.rfind(prefix, 0) == 0) {
        i = k;
        rest = topic.substr(prefix.size());
      }
    }
    if (i < 0) continue;
    VehicleData& d = data[i];
    if (rest == topics::kGroundTruth) {
      if (auto m = mi.instantiate<nav_msgs::Odometry>()) {
        TrueSample s;
        FromOdometry(*m, &s.position, &s.velocity, &s.euler);
        d.truth[static_cast<std::int64_t>(m->header.stamp.toNSec())] = s;
      }
    } else if (rest == topics::kTrueBattery) {
      if (auto m = mi.instantiate<sensor_msgs::BatteryState>()) {
        d.true_voltage[static_cast<std::int64_t>(m->header.stamp.toNSec())] = m->voltage;
      }
    } else if (rest == topics::kMocapPose) {
      if (auto m = mi.instantiate<geometry_msgs::PoseStamped>()) {
        const Measurement x = FromPose(*m, i);
        TrueSample s;
        s.position = x.position;
        s.euler = x.euler;
        d.mocap[static_cast<std::int64_t>(m->header.stamp.toNSec())] = s;
      }
    } else if (rest == topics::kSetpoint) {
      if (auto m = mi.instantiate<fnmpc_ros::AttitudeThrustSetpoint>()) {
        d.setpoints[static_cast<std::int64_t>(m->header.stamp.toNSec())] = *m;
      }
    } else if (rest == topics::kDiagnostics) {
      if (auto m = mi.instantiate<fnmpc_ros::SolverDiagnostics>()) {
        d.diagnostics[static_cast<std::int64_t>(m->header.stamp.toNSec())] = *m;
      }
    } else if (rest == topics::kEstimate) {
      if (auto m = mi.instantiate<nav_msgs::Odometry>()) {
        d.estimates[static_cast<std::int64_t>(m->header.stamp.toNSec())] = *m;
      }
    }
  }
  bag.close();

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
    const bool have_truth = !d.truth.empty();
    std::ofstream csv(dir + "/" + v.name + ".csv");
    if (!csv) throw std::runtime_error("cannot write " + dir + "/" + v.name + ".csv");
    csv << experiment::kVehicleLogCsvHeader;
    std::vector<double> errors, steady_errors, tracking, solver_time;
    long fallbacks = 0, steps = 0;
    for (const auto& [stamp, sp] : d.setpoints) {
      const double t = static_cast<double>(stamp) * 1e-9;
      auto sample = [&](int k) {
        const auto& src = have_truth ? data[k].truth : data[k].mocap;
        const TrueSample* s = AtOrBefore(src, stamp);
        return s ? *s : TrueSample{};
      };
      std::vector<Vec3> positions(nv);
      for (int k = 0; k < nv; ++k) positions[k] = sample(k).position;
      TrueSample x = sample(i);
      if (const double* tv = AtOrBefore(d.true_voltage, stamp)) x.voltage = *tv;
      Vec3 ep = Vec3::Constant(kNaN), ev = ep, ee = ep;
      if (auto it = d.estimates.find(stamp); it != d.estimates.end()) {
        FromOdometry(it->second, &ep, &ev, &ee);
      }
      const fnmpc_ros::SolverDiagnostics* dg = nullptr;
      if (auto it = d.diagnostics.find(stamp); it != d.diagnostics.end()) dg = &it->second;
      // Each vehicle's own window, as in `fnmpc run`: up to its own landing.
      const bool window = t >= sc.trajectory_start && t < config::LandingTime(sc, i);
      const bool steady =
          window && trajectory.TimeSinceStop(t - sc.trajectory_start) >= sc.metrics.settle_time;
      // Every neighbour's error; the CSV has columns for the first two.
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
          for (std::size_t j = 0; j < dg->neighbour_relative.size() && j < 2; ++j) {
            const auto& p = dg->neighbour_relative[j];
            est_rel[j] = Vec3(p.x, p.y, p.z);
          }
        }
      } else if (dg) {
        ref = Vec3(dg->reference.x, dg->reference.y, dg->reference.z);
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
          x.velocity.y(), x.velocity.z(), x.euler.x(), x.euler.y(), x.euler.z(), ep.x(), ep.y(),
          ep.z(), ev.x(), ev.y(), ev.z(), ee.x(), ee.y(), ee.z(), sp.thrust, sp.throttle, sp.roll,
          sp.pitch, sp.yaw, dg ? dg->nmpc_thrust : nan, dg ? dg->nmpc_roll : nan,
          dg ? dg->nmpc_pitch : nan, ref.x(), ref.y(), ref.z(), track, rel[0].x(), rel[0].y(),
          rel[0].z(), est_rel[0].x(), est_rel[0].y(), est_rel[0].z(), err[0], rel[1].x(),
          rel[1].y(), rel[1].z(), est_rel[1].x(), est_rel[1].y(), est_rel[1].z(), err[1], ferr,
          steady ? 1 : 0, dg ? dg->cost : nan, dg ? dg->kkt : nan, dg ? dg->solver_time : nan,
          dg ? dg->sqp_iterations : 0, dg ? dg->qp_iterations : 0, dg && dg->fallback ? 1 : 0,
          dg ? dg->status : std::string("?"), dg && dg->guarded ? 1 : 0,
          dg ? dg->estimator_rejections : 0, x.voltage, dg ? dg->voltage : nan,
          dg ? dg->recovery : std::string("none"), dg ? dg->recovery_reason : std::string("none"),
          dg ? dg->active_neighbours : 0, nan, nan, nan, nan, nan,
          nan);  // aero_f*, est_f*: not in the bag
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
    fmt::print("{}: {} rows{}\n", v.name, d.setpoints.size(),
               have_truth ? "" : (d.mocap.empty() ? " (no ground truth, no mocap)" : " (mocap)"));
  }
  nlohmann::json s;
  s["scenario"] = sc.name;
  s["source"] = "bag " + bag_file;
  s["seed"] = sc.seed;
  s["formation_window_s"] = {sc.trajectory_start, sc.landing_time};
  s["sample_time_s"] = sc.rti.sample_time;
  s["steady_state_formation_error_m"] = Num(steady_worst);
  s["mean_formation_error_m"] = Num(mean_worst);
  s["max_formation_error_m"] = Num(max_worst);
  s["vehicles"] = vehicles;
  std::ofstream(dir + "/summary.json") << s.dump(2) << "\n";
  fmt::print("{}\n", dir);
  return 0;
}

}  // namespace
}  // namespace fnmpc::ros_bridge

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: bag_to_csv BAG SCENARIO.yaml OUT_DIR\n"
                 "  writes OUT_DIR/<vehicle>.csv (the columns of `fnmpc run`) and "
                 "OUT_DIR/summary.json; then: fnmpc report OUT_DIR\n";
    return 2;
  }
  try {
    return fnmpc::ros_bridge::Convert(argv[1], argv[2], argv[3]);
  } catch (const std::exception& e) {
    std::cerr << "bag_to_csv: " << e.what() << "\n";
    return 1;
  }
}
