// SPDX-License-Identifier: BSD-3-Clause
// rostest node: watches a ROS formation flight (sim_node + vehicle nodes) through the sim's
// ground-truth topics until `duration` of simulated time, optionally kills one vehicle node
// (SIGKILL) mid-flight and optionally runs `fnmpc run` on the same scenario and seed; then
// the gtest cases (selected with --gtest_filter in the .test file) assert on what it saw.
// Metrics are computed with onboard::FormationError and the runner's window/steady definitions.
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/callback_queue.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <ros/spinner.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>

#include "conversions.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"
#include "fnmpc_ros/Plan.h"
#include "fnmpc_ros/SimSync.h"

namespace fnmpc::ros_bridge {
namespace {

struct Settings {
  std::string scenario_file;
  int seed = -1;
  double duration = 20.0;     // simulated time watched [s]
  double wall_timeout = 150;  // [s]
  std::string kill_vehicle;   // vehicle whose node is killed ("" none)
  double kill_time = 1e9;     // [s] simulated
  std::string cli;            // fnmpc executable for the comparison ("" none)
  std::string out_dir;
};

struct Stats {
  std::vector<double> errors, steady;  // worst-follower metrics are taken per follower
};

/// One control instant of a follower: per-neighbour formation errors (truth).
struct Sample {
  double t = kNaN;
  bool steady = false;
  std::array<double, formation::kMaxNeighbours> per = [] {
    std::array<double, formation::kMaxNeighbours> a;
    a.fill(kNaN);
    return a;
  }();
};

struct Observed {
  bool completed = false;
  double last_time = kNaN;
  int samples = 0;
  std::vector<Stats> follower;                       // per vehicle (leaders empty)
  std::vector<std::vector<double>> pair_after_kill;  // per vehicle: error to live neighbours
  std::vector<double> min_z_after_kill;              // per vehicle, from kill_time + 1 s
  std::vector<double> final_z, final_tilt;
  double min_separation = kInf;
  std::vector<double> last_diagnostics;         // per vehicle: stamp of the last diagnostics
  std::vector<std::vector<Sample>> samples_of;  // per vehicle (leaders empty)
  // Per vehicle: the first diagnostics stamp after the kill with fewer neighbours in the
  // NMPC cost than configured (the dead neighbour dropped; NaN: never), and the fewest.
  std::vector<double> drop_time;
  std::vector<int> min_active_after_kill;
  std::vector<int> last_active;
  // Cooperative mode: per vehicle, plans seen on <vehicle>/plan, those with another length
  // than horizon + 1 or another sender, and the last one's stamp.
  std::vector<int> plans, bad_plans;
  std::vector<double> last_plan;
  std::atomic<bool> killed{false};
  std::atomic<int> killed_pid{-1};
  std::atomic<double> kill_stamp{kNaN};      // the sync stamp at which the node was killed
  std::map<std::string, bool> alive_at_end;  // node name -> alive
  nlohmann::json cli_summary;
  int cli_rc = -1;
};

Settings g_settings;
config::ScenarioConfig g_scenario;
Observed g_obs;

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

/// PID of a ROS node through its XML-RPC API; -1 when it does not answer (dead).
int NodePid(const std::string& node) {
  XmlRpc::XmlRpcValue req, res, payload;
  req[0] = ros::this_node::getName();
  req[1] = node;
  if (!ros::master::execute("lookupNode", req, res, payload, false)) return -1;
  const std::string uri = payload;
  std::string host;
  std::uint32_t port = 0;
  if (!ros::network::splitURI(uri, host, port)) return -1;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue args, result;
  args[0] = ros::this_node::getName();
  if (!client.execute("getPid", args, result) || client.isFault()) return -1;
  if (result.getType() != XmlRpc::XmlRpcValue::TypeArray || result.size() < 3) return -1;
  const int pid = result[2];
  return ::kill(pid, 0) == 0 ? pid : -1;
}

std::string VehicleNodeName(const std::string& vehicle) { return "/" + vehicle + "/vehicle_node"; }

void Watch() {
  ros::NodeHandle nh;
  const int nv = static_cast<int>(g_scenario.vehicles.size());
  const auto trajectory =
      onboard::LeaderTrajectory(g_scenario, static_cast<std::uint64_t>(g_settings.seed));
  const double window_end = config::FormationWindowEnd(g_scenario);
  g_obs.follower.resize(nv);
  g_obs.pair_after_kill.resize(nv);
  g_obs.min_z_after_kill.assign(nv, kInf);
  g_obs.final_z.assign(nv, kNaN);
  g_obs.final_tilt.assign(nv, kNaN);
  g_obs.last_diagnostics.assign(nv, kNaN);
  g_obs.samples_of.resize(nv);
  g_obs.drop_time.assign(nv, kNaN);
  g_obs.min_active_after_kill.assign(nv, std::numeric_limits<int>::max());
  g_obs.last_active.assign(nv, -1);
  g_obs.plans.assign(nv, 0);
  g_obs.bad_plans.assign(nv, 0);
  g_obs.last_plan.assign(nv, kNaN);
  int killed_index = -1;
  for (int i = 0; i < nv; ++i) {
    if (g_scenario.vehicles[i].name == g_settings.kill_vehicle) killed_index = i;
  }
  if (!g_settings.kill_vehicle.empty() && killed_index < 0) {
    throw std::runtime_error("parameter ~kill_vehicle names no vehicle: " +
                             g_settings.kill_vehicle);
  }

  // Truth per control instant (ns stamp) until every vehicle's sample is in.
  std::map<std::int64_t, std::vector<std::optional<nav_msgs::Odometry>>> pending;
  std::vector<ros::Subscriber> subs;
  for (int i = 0; i < nv; ++i) {
    const std::string ns = "/" + g_scenario.vehicles[i].name + "/";
    subs.push_back(nh.subscribe<nav_msgs::Odometry>(
        ns + topics::kGroundTruth, 1000, [&pending, i, nv](const auto& m) {
          auto& slot = pending[static_cast<std::int64_t>(m->header.stamp.toNSec())];
          if (slot.empty()) slot.resize(nv);
          slot[i] = *m;
        }));
    subs.push_back(nh.subscribe<fnmpc_ros::Plan>(ns + topics::kPlan, 100, [i](const auto& m) {
      ++g_obs.plans[i];
      g_obs.last_plan[i] = m->header.stamp.toSec();
      if (m->displacement.size() != static_cast<std::size_t>(g_scenario.rti.horizon + 1) ||
          m->vehicle != i) {
        ++g_obs.bad_plans[i];
      }
    }));
    subs.push_back(nh.subscribe<fnmpc_ros::SolverDiagnostics>(
        ns + topics::kDiagnostics, 100, [i](const auto& m) {
          const double t = m->header.stamp.toSec();
          g_obs.last_diagnostics[i] = t;
          g_obs.last_active[i] = m->active_neighbours;
          if (!g_obs.killed || t < g_settings.kill_time || g_scenario.vehicles[i].leader) return;
          if (m->phase != "nmpc") return;  // the NMPC's cost only
          g_obs.min_active_after_kill[i] =
              std::min(g_obs.min_active_after_kill[i], static_cast<int>(m->active_neighbours));
          const auto configured = g_scenario.vehicles[i].neighbours.size();
          if (std::isnan(g_obs.drop_time[i]) &&
              static_cast<std::size_t>(m->active_neighbours) < configured) {
            g_obs.drop_time[i] = t;
          }
        }));
  }

  // The kill: on the victim's own SimSync for the first period at or after kill_time, in a
  // callback thread of its own (the truth above is processed in batches, behind the sim), so
  // the node dies within about one control period of kill_time.
  ros::CallbackQueue kill_queue;
  ros::AsyncSpinner kill_spinner(1, &kill_queue);
  ros::Subscriber kill_sub;
  if (killed_index >= 0) {
    ros::SubscribeOptions o = ros::SubscribeOptions::create<fnmpc_ros::SimSync>(
        "/" + g_settings.kill_vehicle + "/" + topics::kSync, 10,
        [](const fnmpc_ros::SimSync::ConstPtr& m) {
          static int pid = -1;
          if (g_obs.killed) return;
          if (pid <= 0) pid = NodePid(VehicleNodeName(g_settings.kill_vehicle));
          const double t = m->header.stamp.toSec();
          if (t < g_settings.kill_time) return;
          if (pid > 0 && ::kill(pid, SIGKILL) == 0) {
            g_obs.killed_pid = pid;
            g_obs.kill_stamp = t;
            g_obs.killed = true;
            ROS_WARN("formation_check: killed %s (pid %d) on its sync for t = %.2f s",
                     VehicleNodeName(g_settings.kill_vehicle).c_str(), pid, t);
          } else {
            ROS_ERROR("formation_check: could not kill %s",
                      VehicleNodeName(g_settings.kill_vehicle).c_str());
          }
        },
        ros::VoidConstPtr(), &kill_queue);
    o.transport_hints = ros::TransportHints().tcpNoDelay();
    kill_sub = nh.subscribe(o);
    kill_spinner.start();
  }

  const ros::WallTime start = ros::WallTime::now();
  while (ros::ok() && !g_obs.completed &&
         (ros::WallTime::now() - start).toSec() < g_settings.wall_timeout) {
    ros::getGlobalCallbackQueue()->callAvailable(ros::WallDuration(0.01));
    while (!pending.empty()) {
      auto it = pending.begin();
      const bool complete = std::all_of(it->second.begin(), it->second.end(),
                                        [](const auto& o) { return o.has_value(); });
      if (!complete) break;
      const double t = static_cast<double>(it->first) * 1e-9;
      std::vector<Vec3> pos(nv), vel(nv), euler(nv);
      for (int i = 0; i < nv; ++i) FromOdometry(*it->second[i], &pos[i], &vel[i], &euler[i]);
      pending.erase(it);
      ++g_obs.samples;
      g_obs.last_time = t;
      const bool window = t >= g_scenario.trajectory_start && t < window_end;
      const bool steady = window && trajectory.TimeSinceStop(t - g_scenario.trajectory_start) >=
                                        g_scenario.metrics.settle_time;
      for (int i = 0; i < nv; ++i) {
        for (int j = i + 1; j < nv; ++j) {
          if (i == killed_index || j == killed_index) continue;
          g_obs.min_separation = std::min(g_obs.min_separation, (pos[i] - pos[j]).norm());
        }
        g_obs.final_z[i] = pos[i].z();
        g_obs.final_tilt[i] =
            std::acos(std::clamp(std::cos(euler[i].x()) * std::cos(euler[i].y()), -1.0, 1.0));
        // Until the scheduled landing: from then on every vehicle descends on purpose.
        if (g_obs.killed && t >= g_settings.kill_time + 1.0 && t < window_end) {
          g_obs.min_z_after_kill[i] = std::min(g_obs.min_z_after_kill[i], pos[i].z());
        }
        const auto& v = g_scenario.vehicles[i];
        if (v.leader) continue;
        std::array<double, formation::kMaxNeighbours> per;  // filled by FormationError
        const double e = onboard::FormationError(g_scenario, i, pos, euler[i].z(), &per);
        if (window) g_obs.samples_of[i].push_back({t, steady, per});
        if (window) g_obs.follower[i].errors.push_back(e);
        if (steady) g_obs.follower[i].steady.push_back(e);
        if (g_obs.killed && t >= g_settings.kill_time + 1.0 && window && i != killed_index) {
          double sum = 0.0;
          int n = 0;
          for (std::size_t j = 0; j < v.neighbours.size(); ++j) {
            if (v.neighbours[j].index == killed_index) continue;
            sum += per[j];
            ++n;
          }
          if (n > 0) g_obs.pair_after_kill[i].push_back(sum / n);
        }
      }
      if (t >= g_settings.duration - 1e-9) g_obs.completed = true;
    }
  }
  // Liveness at the end: the sim and every vehicle node (the killed one must be gone).
  g_obs.alive_at_end["/sim"] = NodePid("/sim") > 0;
  for (const auto& v : g_scenario.vehicles) {
    g_obs.alive_at_end[VehicleNodeName(v.name)] = NodePid(VehicleNodeName(v.name)) > 0;
  }
  ROS_INFO("formation_check: %d samples up to t = %.2f s in %.1f s wall", g_obs.samples,
           g_obs.last_time, (ros::WallTime::now() - start).toSec());
}

void RunCli() {
  if (g_settings.cli.empty()) return;
  const std::string dir = g_settings.out_dir + "/cli";
  const std::string cmd = g_settings.cli + " run '" + g_settings.scenario_file + "' -o '" + dir +
                          "' --seed " + std::to_string(g_settings.seed) + " -q > /dev/null";
  const int status = std::system(cmd.c_str());
  g_obs.cli_rc = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream f(dir + "/run-01/summary.json");
  if (f) g_obs.cli_summary = nlohmann::json::parse(f);
}

/// `fnmpc run` ran to the end: exit 0, or exit 3 (docs/failure.md) when its only failures
/// are vehicles not landed at the end (triangle_20s stops at 20 s, during the descent).
bool CliRan() {
  if (g_obs.cli_rc == 0) return true;
  if (g_obs.cli_rc != 3 || !g_obs.cli_summary.value("complete", false)) return false;
  for (const auto& f : g_obs.cli_summary.value("failures", nlohmann::json::array())) {
    if (f.value("reason", std::string()).find("not landed safely at the end") ==
        std::string::npos) {
      return false;
    }
  }
  return true;
}

/// The largest per-follower metric, as `fnmpc run` reports it.
double WorstFollower(bool steady) {
  double worst = kNaN;
  for (std::size_t i = 0; i < g_obs.follower.size(); ++i) {
    if (g_scenario.vehicles[i].leader) continue;
    const double m = Mean(steady ? g_obs.follower[i].steady : g_obs.follower[i].errors);
    worst = std::isnan(worst) ? m : std::max(worst, m);
  }
  return worst;
}

double Param(const char* name) {
  double v = kNaN;
  if (!ros::NodeHandle("~").getParam(name, v)) {
    ADD_FAILURE() << "missing parameter ~" << name;
  }
  return v;
}

// ---- Flight of the whole formation.
TEST(Triangle, FlewTheWholeDuration) {
  EXPECT_TRUE(g_obs.completed) << "last ground truth at t = " << g_obs.last_time;
  EXPECT_GE(g_obs.samples, static_cast<int>(g_settings.duration / g_scenario.rti.sample_time));
}

TEST(Triangle, FormationErrorWithinBound) {
  const double mean = WorstFollower(false), steady = WorstFollower(true);
  ROS_INFO("ROS formation error: window mean %.4f m, steady %.4f m", mean, steady);
  EXPECT_LE(mean, Param("mean_error_bound"));
  EXPECT_LE(steady, Param("steady_error_bound"));
  double worst_max = kNaN;
  for (const auto& f : g_obs.follower) {
    if (!f.errors.empty())
      worst_max = std::isnan(worst_max) ? Max(f.errors) : std::max(worst_max, Max(f.errors));
  }
  EXPECT_LE(worst_max, Param("max_error_bound"));
  EXPECT_GT(g_obs.min_separation, 1.0);
}

TEST(Triangle, NoNodeDied) {
  for (const auto& [node, alive] : g_obs.alive_at_end) EXPECT_TRUE(alive) << node << " died";
  for (std::size_t i = 0; i < g_obs.last_diagnostics.size(); ++i) {
    EXPECT_GE(g_obs.last_diagnostics[i], g_settings.duration - 0.5)
        << g_scenario.vehicles[i].name << " stopped publishing diagnostics";
  }
}

// ---- Cooperative mode: every vehicle publishes its plan every control step of its NMPC phase.
TEST(Cooperative, EveryVehiclePublishesItsPlan) {
  const double landing = g_scenario.landing_time;
  for (std::size_t i = 0; i < g_obs.plans.size(); ++i) {
    const std::string& name = g_scenario.vehicles[i].name;
    // NMPC from about 4.5 s to the landing: at least 80 % of those control periods,
    EXPECT_GE(g_obs.plans[i], static_cast<int>(0.8 * (landing - 4.5) / g_scenario.rti.sample_time))
        << name;
    // each of horizon + 1 points from its own vehicle, the last one at the landing.
    EXPECT_EQ(g_obs.bad_plans[i], 0) << name;
    EXPECT_NEAR(g_obs.last_plan[i], landing, 0.2) << name;
  }
}

// ---- One follower's node killed mid-flight.
TEST(KillFollower, KilledNodeIsGoneOthersAlive) {
  ASSERT_TRUE(g_obs.killed);
  for (const auto& [node, alive] : g_obs.alive_at_end) {
    if (node == VehicleNodeName(g_settings.kill_vehicle)) {
      EXPECT_FALSE(alive) << node << " still alive";
    } else {
      EXPECT_TRUE(alive) << node << " died";
    }
  }
  for (std::size_t i = 0; i < g_scenario.vehicles.size(); ++i) {
    if (g_scenario.vehicles[i].name == g_settings.kill_vehicle) continue;
    EXPECT_GE(g_obs.last_diagnostics[i], g_settings.duration - 0.5)
        << g_scenario.vehicles[i].name << " stopped publishing diagnostics";
  }
}

TEST(KillFollower, OthersKeepFlyingAndFormation) {
  ASSERT_TRUE(g_obs.completed);
  const double min_alt = Param("min_altitude");
  const double pair_bound = Param("pair_error_bound");
  for (std::size_t i = 0; i < g_scenario.vehicles.size(); ++i) {
    const auto& v = g_scenario.vehicles[i];
    if (v.name == g_settings.kill_vehicle) {
      // The failsafe set it down upright.
      EXPECT_LT(g_obs.final_z[i], 0.2) << v.name << " did not land in failsafe";
      EXPECT_LT(g_obs.final_tilt[i], 0.3) << v.name << " tipped over";
      continue;
    }
    EXPECT_GT(g_obs.min_z_after_kill[i], min_alt) << v.name << " lost altitude";
    EXPECT_LT(g_obs.final_tilt[i], 0.3) << v.name;
    if (!v.leader) {
      ASSERT_FALSE(g_obs.pair_after_kill[i].empty());
      const double mean = Mean(g_obs.pair_after_kill[i]), mx = Max(g_obs.pair_after_kill[i]);
      ROS_INFO("%s error to its live neighbours after the kill: mean %.3f m, max %.3f m",
               v.name.c_str(), mean, mx);
      EXPECT_LE(mean, pair_bound);
    }
  }
  EXPECT_GT(g_obs.min_separation, 1.0);
}

/// The surviving followers drop the dead neighbour from their NMPC cost (docs/safety.md,
/// neighbour loss) and then hold their offset to the live neighbours (the leader) within
/// `steady_ratio_bound` times their no-fault steady state, which is `fnmpc run` on the same
/// scenario and seed without the kill (the ROS run matches it: VsCli).
TEST(KillFollowerNeighbourLoss, SurvivorDropsDeadNeighbourAndHoldsLeaderOffset) {
  ASSERT_TRUE(g_obs.completed);
  ASSERT_TRUE(CliRan()) << "fnmpc run failed (exit " << g_obs.cli_rc << ")";
  ASSERT_TRUE(g_obs.cli_summary.contains("vehicles"));
  const double ratio_bound = Param("steady_ratio_bound");
  for (std::size_t i = 0; i < g_scenario.vehicles.size(); ++i) {
    const auto& v = g_scenario.vehicles[i];
    if (v.leader || v.name == g_settings.kill_vehicle) continue;
    const auto& by_nb = g_obs.cli_summary["vehicles"][v.name]["formation_error_by_neighbour"];
    double ref = 0.0;
    int live = 0;
    for (const auto& n : v.neighbours) {
      if (n.vehicle == g_settings.kill_vehicle) continue;
      ref += by_nb[n.vehicle]["steady_state_mean_m"].get<double>();
      ++live;
    }
    ASSERT_GT(live, 0);
    ref /= live;
    const bool dropped = !std::isnan(g_obs.drop_time[i]);
    const double from = dropped ? g_obs.drop_time[i] : g_settings.kill_time + 1.0;
    std::vector<double> after;
    for (const Sample& s : g_obs.samples_of[i]) {
      if (!s.steady || s.t < from) continue;
      double sum = 0.0;
      for (std::size_t j = 0; j < v.neighbours.size(); ++j) {
        if (v.neighbours[j].vehicle != g_settings.kill_vehicle) sum += s.per[j];
      }
      after.push_back(sum / live);
    }
    const double mean = Mean(after);
    ROS_INFO(
        "%s: dead neighbour %s %s; neighbours in the cost: fewest %d after the kill, %d at the "
        "end; steady-state error to its live neighbours from t = %.2f s: %.4f m over %zu "
        "samples, no-fault (fnmpc run) %.4f m, ratio %.2f (bound %.2f)",
        v.name.c_str(), g_settings.kill_vehicle.c_str(),
        dropped ? ("dropped at t = " + std::to_string(g_obs.drop_time[i]) + " s").c_str()
                : "never dropped",
        g_obs.min_active_after_kill[i], g_obs.last_active[i], from, mean, after.size(), ref,
        mean / ref, ratio_bound);
    EXPECT_TRUE(dropped) << v.name << " kept the dead " << g_settings.kill_vehicle
                         << " in its NMPC cost";
    ASSERT_FALSE(after.empty()) << v.name << ": no steady-state sample after t = " << from;
    EXPECT_LE(mean, ratio_bound * ref)
        << v.name << ": steady-state error to the live neighbours " << mean << " m is "
        << mean / ref << " x its no-fault " << ref << " m";
  }
}

// ---- ROS vs `fnmpc run`.
/// |ros - cli| <= tolerance * cli, printed.
void ExpectClose(const char* what, double ros, double cli, double tolerance) {
  ROS_INFO("%-32s ROS %.6f m, CLI %.6f m, difference %+.2e %%", what, ros, cli,
           100.0 * (ros - cli) / cli);
  EXPECT_LE(std::abs(ros - cli), tolerance * cli) << what << ": ROS " << ros << ", CLI " << cli;
}

TEST(VsCli, FormationErrorsMatchCli) {
  ASSERT_TRUE(g_obs.completed);
  ASSERT_TRUE(CliRan()) << "fnmpc run failed (exit " << g_obs.cli_rc << ")";
  ASSERT_TRUE(g_obs.cli_summary.contains("mean_formation_error_m"));
  const double tol = Param("relative_tolerance");
  ExpectClose("worst follower, window mean", WorstFollower(false),
              g_obs.cli_summary["mean_formation_error_m"].get<double>(), tol);
  ExpectClose("worst follower, steady state", WorstFollower(true),
              g_obs.cli_summary["steady_state_formation_error_m"].get<double>(), tol);
  for (std::size_t i = 0; i < g_scenario.vehicles.size(); ++i) {
    const auto& v = g_scenario.vehicles[i];
    if (v.leader) continue;
    const auto& c = g_obs.cli_summary["vehicles"][v.name];
    ExpectClose((v.name + ", window mean").c_str(), Mean(g_obs.follower[i].errors),
                c["formation_error_mean_m"].get<double>(), tol);
    ExpectClose((v.name + ", steady state").c_str(), Mean(g_obs.follower[i].steady),
                c["formation_error_steady_state_mean_m"].get<double>(), tol);
    ExpectClose((v.name + ", max").c_str(), Max(g_obs.follower[i].errors),
                c["formation_error_max_m"].get<double>(), tol);
  }
}

}  // namespace
}  // namespace fnmpc::ros_bridge

int main(int argc, char** argv) {
  using namespace fnmpc::ros_bridge;
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "formation_check");
  ros::NodeHandle pnh("~");
  try {
    g_settings.scenario_file = RequiredParam(pnh, "scenario");
    g_scenario = fnmpc::config::LoadScenarioFile(g_settings.scenario_file);
    pnh.param("seed", g_settings.seed, -1);
    if (g_settings.seed < 0) g_settings.seed = static_cast<int>(g_scenario.seed);
    pnh.param("duration", g_settings.duration, g_settings.duration);
    pnh.param("wall_timeout", g_settings.wall_timeout, g_settings.wall_timeout);
    pnh.param("kill_vehicle", g_settings.kill_vehicle, std::string());
    pnh.param("kill_time", g_settings.kill_time, g_settings.kill_time);
    pnh.param("cli", g_settings.cli, std::string());
    const char* tmp = std::getenv("ROS_LOG_DIR");
    // One folder per test process: the rostests share ROS_LOG_DIR, and `fnmpc run` refuses
    // a non-empty run folder (docs/failure.md).
    pnh.param("out_dir", g_settings.out_dir,
              std::string(tmp ? tmp : "/tmp") + "/formation_check-" + std::to_string(getpid()));
    Watch();
    RunCli();  // after the flight: the sim is idle then and the CLI run gets the CPU
  } catch (const std::exception& e) {
    ROS_FATAL("formation_check: %s", e.what());
    return 1;
  }
  return RUN_ALL_TESTS();
}
