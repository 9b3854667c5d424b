// SPDX-License-Identifier: BSD-3-Clause
// Pins the ideal plant ("reality off", docs/simulator.md "Reality"): a fixed command sequence
// through a world with every model of the simulator as it was before the reality models (three
// vehicles, all sensors with noise, dropouts and latency, battery sag, round-jet downwash,
// constant wind with Gauss-Markov gusts, attitude, throttle and direct-throttle commands) must
// give the recorded trajectory and measurement stream bit for bit. The recording
// (data/reality_off_trajectory.csv) was written by this test on 92c961d, before any
// reality model existed:
//   FNMPC_WRITE_REALITY_OFF_GOLDEN=tests/sim/data/reality_off_trajectory.csv sim_test
//     --gtest_filter=RealityOffTest.*
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fnmpc/config/sensors_yaml.hpp"
#include "fnmpc/sim/world.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

/// The world of the recording: today's models all switched on.
WorldConfig RecordedWorld() {
  WorldConfig c = test::QuietConfig(3);
  SensorsConfig sensors =
      config::LoadSensorsFile(std::string(FNMPC_SOURCE_DIR) + "/config/sensors/default.yaml");
  sensors.mocap.dropout_probability = 0.05;
  sensors.relative.dropout_probability = 0.1;
  for (auto& v : c.vehicles) v.sensors = sensors;
  c.vehicles[0].position = Vec3(0.0, 0.0, 2.0);  // above vehicle 1: its wake reaches it
  c.vehicles[0].initial_throttle = 0.45;
  c.vehicles[1].position = Vec3(0.1, 0.05, 1.0);
  c.vehicles[1].initial_throttle = 0.45;
  c.vehicles[2].position = Vec3(3.0, 1.0, World::kRestHeight);
  c.downwash.enabled = true;
  c.wind.enabled = true;
  c.wind.velocity = Vec3(0.8, -0.3, 0.0);
  c.wind.gust_std = 0.4;
  c.wind.gust_time_constant = 1.5;
  c.command_timeout.enabled = true;
  c.seed = 42;
  return c;
}

/// Fixed commands of step k (1 ms steps): vehicle 0 by thrust and attitude, vehicle 1 by
/// collective throttle, vehicle 2 by direct throttles, then silent (command timeout).
void Command(World& w, int k) {
  const double t = 0.001 * k;
  if (k % 20 == 0) {
    AttitudeCommand a;
    a.thrust = 13.6 + 1.5 * std::sin(2.0 * t);
    a.roll = 0.08 * std::sin(1.3 * t);
    a.pitch = -0.06 * std::cos(0.9 * t);
    a.yaw = 0.2 * t;
    w.SetCommand(0, a);
    AttitudeCommand b;
    b.throttle = 0.47 + 0.03 * std::sin(3.0 * t);
    b.roll = -0.05;
    b.pitch = 0.04 * std::sin(t);
    w.SetCommand(1, b);
  }
  if (k == 100) w.SetThrottles(2, Vec4(0.55, 0.56, 0.55, 0.56));
  if (k == 2500) w.SetThrottles(2, Vec4(0.2, 0.2, 0.2, 0.2));
}

std::string Row(const World& w, int k, double meas_sum, long meas_count) {
  std::ostringstream out;
  out.precision(17);
  out << k;
  for (int i = 0; i < w.num_vehicles(); ++i) {
    const TrueState s = w.GetTrueState(i);
    for (const Vec3* v : {&s.position, &s.velocity, &s.euler, &s.body_rates, &s.aero_force}) {
      for (int a = 0; a < 3; ++a) out << ',' << (*v)[a];
    }
    for (int r = 0; r < 4; ++r) out << ',' << s.rotor_rpm[r];
    out << ',' << s.voltage;
  }
  out << ',' << meas_sum << ',' << meas_count;
  return out.str();
}

/// Sum of every finite field of a measurement (a digest of the measurement stream).
double Digest(const Measurement& m) {
  double s = m.stamp + m.arrival + static_cast<int>(m.kind) + 10 * m.vehicle;
  for (const Vec3* v : {&m.position, &m.euler, &m.accel, &m.gyro, &m.velocity}) {
    for (int a = 0; a < 3; ++a) s += std::isfinite((*v)[a]) ? (*v)[a] : 0.0;
  }
  for (double x : {m.yaw, m.voltage, m.relative.range, m.relative.bearing, m.relative.elevation,
                   m.relative.relative_yaw}) {
    s += std::isfinite(x) ? x : 0.0;
  }
  return s;
}

std::vector<std::string> Simulate() {
  World w(RecordedWorld());
  std::vector<std::string> rows;
  double meas_sum = 0.0;
  long meas_count = 0;
  Measurement m;
  for (int k = 0; k <= 4000; ++k) {
    if (k < 3000) Command(w, k);
    while (w.PopMeasurement(&m)) {
      meas_sum += Digest(m);
      ++meas_count;
    }
    if (k % 50 == 0) rows.push_back(Row(w, k, meas_sum, meas_count));
    w.StepOnce();
  }
  return rows;
}

TEST(RealityOffTest, FixedCommandsGiveTheRecordedTrajectoryBitForBit) {
  const std::vector<std::string> rows = Simulate();
  const char* write = std::getenv("FNMPC_WRITE_REALITY_OFF_GOLDEN");
  if (write != nullptr) {
    std::ofstream out(write);
    for (const auto& r : rows) out << r << '\n';
    ASSERT_TRUE(out.good()) << "cannot write " << write;
  }
  std::ifstream in(std::string(FNMPC_SOURCE_DIR) + "/tests/sim/data/reality_off_trajectory.csv");
  ASSERT_TRUE(in.good()) << "missing tests/sim/data/reality_off_trajectory.csv";
  std::vector<std::string> recorded;
  for (std::string line; std::getline(in, line);) recorded.push_back(line);
  ASSERT_EQ(recorded.size(), rows.size());
  // Bit for bit in the build the recording was made with (Release, x86-64-v3). Other build
  // types may contract a*b+c into FMA differently (last-bit differences that the feedback
  // loops keep at that size), so values agree to 1e-9 relative; counts exactly.
  int identical = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i] == recorded[i]) {
      ++identical;
      continue;
    }
    std::stringstream a(rows[i]), b(recorded[i]);
    std::string x, y;
    int col = 0;
    while (std::getline(a, x, ',')) {
      ASSERT_TRUE(std::getline(b, y, ',')) << "row " << i << ": fewer columns recorded";
      const double vx = std::stod(x), vy = std::stod(y);
      const double dev = std::abs(vx - vy) / std::max(1.0, std::abs(vy));
      worst = std::max(worst, dev);
      ASSERT_LE(dev, 1e-9) << "row " << i << " (step " << 50 * i << ") column " << col << ": " << x
                           << " vs recorded " << y;
      ++col;
    }
    ASSERT_FALSE(std::getline(b, y, ',')) << "row " << i << ": more columns recorded";
  }
  std::printf(
      "reality off: %d of %zu rows bit-identical to the recording, worst relative "
      "deviation %.3g\n",
      identical, rows.size(), worst);
}

}  // namespace
}  // namespace fnmpc::sim
