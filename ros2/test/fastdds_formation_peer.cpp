// SPDX-License-Identifier: BSD-3-Clause
// fastdds_formation_peer DOMAIN VEHICLE MASS ALTITUDE DURATION: a Fast DDS program (no code of
// ros2/src) that takes part in a formation run of the ROS 2 nodes using only the ROS 2
// conventions (ros2/test/formation_test.sh, mode fastdds):
//  * it is VEHICLE's node: it reads VEHICLE's sensor topics and sim/sync (RELIABLE, lockstep),
//    counts the measurements against each sync, and answers every sync with a setpoint stamped
//    with the sync's time that holds VEHICLE at ALTITUDE (a vertical-speed loop on the
//    ground truth; MASS [kg]), i.e. it commands the vehicle;
//  * it reads every vehicle's ground_truth, setpoint, odom and status and /clock;
//  * it checks the discovered writers' type names, reliability and typehash USER_DATA.
// Prints what it saw and exits 0 when every check passed, 1 otherwise.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "fastdds_types.hpp"

using namespace fnmpc_fastdds_peer;

namespace {

int failures = 0;
void Check(bool ok, const std::string& what) {
  std::printf("%s %s\n", ok ? "ok  " : "FAIL", what.c_str());
  if (!ok) ++failures;
}
double Sec(const Time& t) { return t.sec + t.nanosec * 1e-9; }

}  // namespace

int main(int argc, char** argv) {
  if (argc != 6) {
    std::fprintf(stderr, "usage: fastdds_formation_peer DOMAIN VEHICLE MASS ALTITUDE DURATION\n");
    return 2;
  }
  const int domain = std::atoi(argv[1]);
  const std::string me = argv[2];
  const double mass = std::atof(argv[3]), altitude = std::atof(argv[4]),
               duration = std::atof(argv[5]);
  const std::vector<std::string> vehicles = {"leader", "follower1", "follower2"};
  FastDdsSide fast(domain);
  if (!fast.ok()) return 1;
  const std::string ns = "rt/" + me + "/";
  auto* pose = fast.Reader<PoseStamped>(ns + "mocap/pose", true, 1000);
  auto* imu = fast.Reader<Imu>(ns + "imu", true, 1000);
  auto* flow = fast.Reader<OpticalFlow>(ns + "optical_flow", true, 1000);
  auto* compass = fast.Reader<Heading>(ns + "compass", true, 1000);
  auto* battery = fast.Reader<BatteryState>(ns + "battery", true, 1000);
  auto* relative = fast.Reader<RelativeObservation>(ns + "relative", true, 1000);
  auto* sync = fast.Reader<SimSync>(ns + "sim/sync", true, 10);
  auto* clock = fast.Reader<Clock>("rt/clock", false, 10);
  // The setpoint writer carries the type hash ROS 2 Jazzy computes for our message (checked
  // against the Cyclone side's USER_DATA below, not taken from it).
  std::map<std::string, fdds::DataReader*> truth, setpoints, odoms;
  for (const auto& v : vehicles) {
    if (v != me) {
      setpoints[v] = fast.Reader<Setpoint>("rt/" + v + "/setpoint", true, 1000);
      odoms[v] = fast.Reader<Odometry>("rt/" + v + "/odom", true, 1000);
    }
  }
  // The simulator starts once the ground-truth readers match (ground_truth_subscribers): they
  // are created after the vehicle nodes' writers matched these readers, or the first setpoints
  // would be published before Fast DDS could receive them (volatile topics).
  const bool matched = WaitFor([&] {
    for (const auto& [v, r] : setpoints) {
      fdds::SubscriptionMatchedStatus a, b;
      r->get_subscription_matched_status(a);
      odoms[v]->get_subscription_matched_status(b);
      if (a.current_count == 0 || b.current_count == 0) return false;
    }
    return true;
  });
  Check(matched, "the followers' setpoint and odom writers discovered");
  for (const auto& v : vehicles)
    truth[v] = fast.Reader<Odometry>("rt/" + v + "/ground_truth", true, 1000);
  std::string setpoint_hash;
  // Wait for the simulator's writers to be discovered, then take their setpoint type hash.
  WaitFor([&] {
    std::lock_guard<std::mutex> lock(fast.listener.mutex);
    return fast.listener.writers.count("rt/follower1/setpoint") > 0;
  });
  {
    std::lock_guard<std::mutex> lock(fast.listener.mutex);
    const auto& w = fast.listener.writers;
    if (w.count("rt/follower1/setpoint")) {
      const std::string u = w.at("rt/follower1/setpoint").user_data;
      setpoint_hash = u.substr(9, u.size() - 10);  // typehash=...;
    }
  }
  auto* command = fast.Writer<Setpoint>(ns + "setpoint", setpoint_hash);
  Check(command != nullptr && !setpoint_hash.empty(),
        "setpoint writer for " + me + " with the discovered type hash");
  if (!command) return 1;

  std::uint64_t received = 0;
  std::map<std::string, int> counts;
  std::map<std::string, double> max_z;
  double z = 0.1, vz = 0.0, last_answer = -1.0, last_clock = -1.0;
  bool clock_monotonic = true, counts_match = true;
  std::vector<SimSync> pending;
  auto take_sensors = [&] {
    PoseStamped p;
    while (TakeOne(pose, &p)) ++received, ++counts["mocap/pose"];
    Imu i;
    while (TakeOne(imu, &i)) {
      ++received, ++counts["imu"];
      if (i.header.frame_id != me + "/base_link") counts_match = false;
    }
    OpticalFlow f;
    while (TakeOne(flow, &f)) ++received, ++counts["optical_flow"];
    Heading h;
    while (TakeOne(compass, &h)) ++received, ++counts["compass"];
    BatteryState b;
    while (TakeOne(battery, &b)) ++received, ++counts["battery"];
    RelativeObservation r;
    while (TakeOne(relative, &r)) ++received, ++counts["relative"];
  };
  const auto start = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - start < std::chrono::seconds(120)) {
    take_sensors();
    for (const auto& v : vehicles) {
      Odometry o;
      while (TakeOne(truth[v], &o)) {
        ++counts[v + "/ground_truth"];
        max_z[v] = std::max(max_z[v], o.position.z);
        if (v == me) {
          z = o.position.z;
          vz = o.linear.z;  // body frame; level flight: about the vertical speed
        }
      }
      if (v == me) continue;
      Setpoint s;
      while (TakeOne(setpoints[v], &s)) ++counts[v + "/setpoint"];
      while (TakeOne(odoms[v], &o)) ++counts[v + "/odom"];
    }
    Clock c;
    while (TakeOne(clock, &c)) {
      clock_monotonic = clock_monotonic && Sec(c.clock) >= last_clock;
      last_clock = Sec(c.clock);
    }
    SimSync s;
    while (TakeOne(sync, &s)) pending.push_back(s);
    while (!pending.empty()) {
      const SimSync& next = pending.front();
      const double t = Sec(next.header.stamp);
      if (t <= last_answer) {  // repeated start-up sync
        pending.erase(pending.begin());
        continue;
      }
      if (received < next.measurements) break;  // still in flight
      if (received != next.measurements) counts_match = false;
      Setpoint sp;
      sp.header.stamp = next.header.stamp;
      sp.thrust = mass * (9.81 + 1.5 * (1.5 * (altitude - z) - vz));
      sp.throttle = std::numeric_limits<double>::quiet_NaN();
      sp.phase = "external";
      command->write(&sp);
      last_answer = t;
      pending.erase(pending.begin());
    }
    if (last_clock >= duration - 1e-6 && last_answer >= duration - 1e-6) break;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  std::printf("answered up to t = %.2f s, /clock to %.2f s, %llu measurements of %s\n", last_answer,
              last_clock, static_cast<unsigned long long>(received), me.c_str());
  for (const auto& [k, n] : counts) std::printf("  %s: %d\n", k.c_str(), n);
  Check(last_answer >= duration - 1e-6, "answered every sync to the end");
  Check(counts_match, "measurement counts equal each SimSync's, IMU frame " + me + "/base_link");
  Check(clock_monotonic && last_clock >= duration - 1e-6, "/clock monotonic to the end");
  for (const std::string k : {"mocap/pose", "imu", "battery", "relative"})
    Check(counts[k] > 0, "received " + me + "/" + k);
  for (const auto& v : vehicles)
    Check(counts[v + "/ground_truth"] >= 400, v + "/ground_truth every control period");
  for (const auto& v : vehicles) {
    if (v == me) continue;
    Check(counts[v + "/setpoint"] >= 400, v + "/setpoint every control period");
    Check(counts[v + "/odom"] > 0, v + "/odom");
  }
  std::printf("%s max z %.3f m (commanded %.2f m)\n", me.c_str(), max_z[me], altitude);
  Check(max_z[me] > altitude - 0.3 && max_z[me] < altitude + 0.5,
        me + " flew to the commanded altitude");
  {
    std::lock_guard<std::mutex> lock(fast.listener.mutex);
    const auto& w = fast.listener.writers;
    auto type_of = [&](const std::string& topic) {
      return w.count(topic) ? w.at(topic).type : std::string("(none)");
    };
    Check(type_of("rt/follower1/ground_truth") == "nav_msgs::msg::dds_::Odometry_",
          "ground_truth type");
    Check(type_of("rt/follower1/status") == "fnmpc_msgs::msg::dds_::ControllerStatus_",
          "status type");
    Check(type_of("rt/clock") == "rosgraph_msgs::msg::dds_::Clock_", "clock type");
    Check(type_of(ns + "sim/sync") == "fnmpc_msgs::msg::dds_::SimSync_", "sim/sync type");
    Check(w.count("rt/follower1/setpoint") && w.at("rt/follower1/setpoint").reliable,
          "setpoint RELIABLE");
    bool all_hashed = !w.empty();
    for (const auto& [topic, d] : w)
      all_hashed = all_hashed && d.user_data.rfind("typehash=RIHS01_", 0) == 0;
    Check(all_hashed,
          "every discovered writer (" + std::to_string(w.size()) + ") has a typehash USER_DATA");
  }
  std::printf("%d failure(s)\n", failures);
  return failures == 0 ? 0 : 1;
}
