// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/sim/world.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

/// Running mean and standard deviation.
struct Stats {
  double n = 0, sum = 0, sum2 = 0;
  void Add(double x) {
    n += 1;
    sum += x;
    sum2 += x * x;
  }
  [[nodiscard]] double Mean() const { return sum / n; }
  [[nodiscard]] double Std() const { return std::sqrt(sum2 / n - Mean() * Mean()); }
};

/// Steps `world` for `duration`, logging the truth of every vehicle at every step and
/// popping every delivered measurement; checks the delivery order and time on the way.
struct Recorder {
  std::vector<std::vector<TrueState>> truth;  // [step][vehicle]
  std::vector<Measurement> log;
  void Run(World* world, double duration) {
    const int steps = static_cast<int>(std::lround(duration / world->physics_dt()));
    for (int k = 0; k < steps; ++k) {
      std::vector<TrueState> now;
      for (int v = 0; v < world->num_vehicles(); ++v) now.push_back(world->GetTrueState(v));
      truth.push_back(now);
      world->StepOnce();
      Measurement m;
      while (world->PopMeasurement(&m)) {
        ASSERT_LE(m.arrival, world->time() + 1e-9);
        if (!log.empty()) {
          ASSERT_GE(m.arrival, log.back().arrival);
        }
        log.push_back(m);
      }
    }
  }
  [[nodiscard]] const TrueState& At(const Measurement& m, double dt) const {
    return truth[static_cast<std::size_t>(std::lround(m.stamp / dt))][m.vehicle];
  }
};

constexpr double kDuration = 20.0;

WorldConfig TwoVehiclesWithSensors() {
  WorldConfig c = test::QuietConfig(2);
  c.vehicles[1].position = Vec3(3.0, 0.0, World::kRestHeight);
  c.vehicles[1].yaw = 0.5;
  for (auto& v : c.vehicles) v.sensors = SensorsConfig{};
  return c;
}

TEST(SensorsTest, RatesLatenciesAndNoiseStatistics) {
  // Given two vehicles resting 3 m apart with the default sensors,
  const WorldConfig c = TwoVehiclesWithSensors();
  World world(c);
  // When 20 s are simulated,
  Recorder rec;
  rec.Run(&world, kDuration);
  const double dt = world.physics_dt();
  const SensorsConfig& s = c.vehicles[0].sensors;
  std::array<int, kNumSensorKinds> count{};
  std::array<Stats, 3> mocap_pos, imu_acc, imu_gyro, flow;
  Stats mocap_yaw, compass, battery, range, bearing, elevation, rel_yaw;
  for (const Measurement& m : rec.log) {
    if (m.vehicle != 0) continue;
    ++count[static_cast<int>(m.kind)];
    const TrueState& x = rec.At(m, dt);
    const SensorSpec& spec = m.kind == SensorKind::kMocapPose     ? s.mocap
                             : m.kind == SensorKind::kImu         ? s.imu
                             : m.kind == SensorKind::kOpticalFlow ? s.optical_flow
                             : m.kind == SensorKind::kCompass     ? s.compass
                             : m.kind == SensorKind::kBattery     ? s.battery
                                                                  : s.relative;
    // Then every measurement arrives exactly its sensor's latency after its stamp,
    ASSERT_NEAR(m.arrival - m.stamp, spec.latency_s, 1e-12);
    const Mat3 r = RotationZyx(x.euler.x(), x.euler.y(), x.euler.z());
    switch (m.kind) {
      case SensorKind::kMocapPose:
        for (int a = 0; a < 3; ++a) mocap_pos[a].Add(m.position[a] - x.position[a]);
        mocap_yaw.Add(WrapAngle(m.euler.z() - x.euler.z()));
        break;
      case SensorKind::kImu: {
        const Vec3 f = r.transpose() * (x.acceleration + Vec3(0, 0, kGravity));
        for (int a = 0; a < 3; ++a) {
          imu_acc[a].Add(m.accel[a] - f[a]);
          imu_gyro[a].Add(m.gyro[a] - x.body_rates[a]);
        }
        break;
      }
      case SensorKind::kOpticalFlow:
        for (int a = 0; a < 3; ++a) flow[a].Add(m.velocity[a] - x.velocity[a]);
        break;
      case SensorKind::kCompass:
        compass.Add(WrapAngle(m.yaw - x.euler.z()));
        break;
      case SensorKind::kBattery:
        battery.Add(m.voltage - x.voltage);
        break;
      case SensorKind::kRelative: {
        ASSERT_EQ(m.relative.target, 1);
        const TrueState& y = rec.truth[std::lround(m.stamp / dt)][1];
        const Vec3 d = r.transpose() * (y.position - x.position);
        range.Add(m.relative.range - d.norm());
        bearing.Add(WrapAngle(m.relative.bearing - std::atan2(d.y(), d.x())));
        elevation.Add(m.relative.elevation - std::asin(d.z() / d.norm()));
        rel_yaw.Add(WrapAngle(m.relative.relative_yaw - (y.euler.z() - x.euler.z())));
        break;
      }
    }
  }
  // ... each sensor delivers at its rate,
  EXPECT_NEAR(count[0], s.mocap.rate_hz * kDuration, 2);
  EXPECT_NEAR(count[1], s.imu.rate_hz * kDuration, 2);
  EXPECT_NEAR(count[2], s.optical_flow.rate_hz * kDuration, 2);
  EXPECT_NEAR(count[3], s.compass.rate_hz * kDuration, 2);
  EXPECT_NEAR(count[4], s.battery.rate_hz * kDuration, 2);
  EXPECT_NEAR(count[5], s.relative.rate_hz * kDuration, 2);
  // ... and the errors are zero-mean with the configured standard deviation.
  auto check = [](const Stats& st, double sd, const char* what) {
    EXPECT_NEAR(st.Mean(), 0.0, 5.0 * sd / std::sqrt(st.n) + 1e-12) << what;
    EXPECT_NEAR(st.Std(), sd, 0.1 * sd + 1e-12) << what;
  };
  for (int a = 0; a < 3; ++a) {
    check(mocap_pos[a], s.mocap.noise[a], "mocap position");
    check(imu_gyro[a], s.imu.noise2[a], "gyro");
    check(flow[a], s.optical_flow.noise[a], "optical flow");
  }
  // The accelerometer error also holds the contact jitter of the resting vehicle.
  for (int a = 0; a < 3; ++a) check(imu_acc[a], s.imu.noise[a], "accelerometer");
  check(mocap_yaw, s.mocap.noise2.z(), "mocap yaw");
  check(compass, s.compass.noise.x(), "compass");
  check(battery, s.battery.noise.x(), "battery");
  const double range_sd = s.relative.noise.x() * (1.0 + s.relative.range_noise_growth * 3.0);
  check(range, range_sd, "range");
  check(bearing, s.relative.noise.y(), "bearing");
  check(elevation, s.relative.noise.z(), "elevation");
  check(rel_yaw, s.relative.noise2.x(), "relative yaw");
}

TEST(SensorsTest, DropoutRemovesTheConfiguredShare) {
  // Given a mocap that loses 30 % of its samples,
  WorldConfig c = TwoVehiclesWithSensors();
  c.vehicles[0].sensors.mocap.dropout_probability = 0.3;
  World world(c);
  Recorder rec;
  rec.Run(&world, kDuration);
  int n = 0;
  for (const auto& m : rec.log) n += m.vehicle == 0 && m.kind == SensorKind::kMocapPose;
  // Then about 70 % arrive (binomial sd ~ 13 of 1200).
  EXPECT_NEAR(n, 0.7 * 60.0 * kDuration, 60.0);
}

TEST(SensorsTest, RelativeSensorRangeFieldOfViewAndNoiseGrowth) {
  // Given an observer at the origin looking along +x with a 90 degree cone and 6 m range,
  // a neighbour 1 m ahead, one 5 m ahead and one 2 m behind,
  WorldConfig c = test::QuietConfig(4);
  c.vehicles[1].position = Vec3(1.0, 0.0, World::kRestHeight);
  c.vehicles[2].position = Vec3(5.0, 0.0, World::kRestHeight);
  c.vehicles[3].position = Vec3(-2.0, 0.0, World::kRestHeight);
  c.vehicles[2].position.y() = 0.3;
  SensorSpec& rel = c.vehicles[0].sensors.relative;
  rel = SensorsConfig{}.relative;
  rel.field_of_view = M_PI / 2;
  rel.max_range = 6.0;
  rel.range_noise_growth = 0.5;
  World world(c);
  // When 20 s are simulated,
  Recorder rec;
  rec.Run(&world, kDuration);
  std::array<Stats, 4> range;
  for (const auto& m : rec.log) {
    ASSERT_EQ(m.kind, SensorKind::kRelative);
    const Vec3 d =
        rec.truth[std::lround(m.stamp / world.physics_dt())][m.relative.target].position -
        rec.At(m, world.physics_dt()).position;
    range[m.relative.target].Add(m.relative.range - d.norm());
  }
  // Then the one behind is never seen, the others at the full rate,
  EXPECT_EQ(range[3].n, 0);
  EXPECT_NEAR(range[1].n, 50.0 * kDuration, 2);
  EXPECT_NEAR(range[2].n, 50.0 * kDuration, 2);
  // and the range noise grows with range as sd0 (1 + growth r).
  EXPECT_NEAR(range[1].Std(), 0.02 * 1.5, 0.003);
  EXPECT_NEAR(range[2].Std(), 0.02 * (1.0 + 0.5 * std::hypot(5.0, 0.3)), 0.006);
  // When the neighbour moves out of range, it is no longer observed.
  world.SetPose(1, Vec3(7.0, 0.0, 1.0), Vec3::Zero());
  world.SetPose(2, Vec3(7.0, 1.0, 1.0), Vec3::Zero());
  world.Step(0.1);
  Measurement m;
  while (world.PopMeasurement(&m)) {
  }
  world.Step(1.0);
  EXPECT_FALSE(world.PopMeasurement(&m));
}

TEST(SensorsTest, IdenticalSeedsGiveIdenticalLogs) {
  // Given three vehicles in flight with all sensors, gusts and downwash,
  auto make = [](std::uint64_t seed) {
    WorldConfig c = TwoVehiclesWithSensors();
    c.vehicles.push_back(c.vehicles[0]);
    c.vehicles[2].position = Vec3(0.3, 0.2, 1.5);
    c.vehicles[0].sensors.mocap.dropout_probability = 0.2;
    c.wind.enabled = true;
    c.wind.velocity = Vec3(1.0, 0.5, 0.0);
    c.wind.gust_std = 0.5;
    c.downwash.enabled = true;
    c.seed = seed;
    return c;
  };
  auto run = [](const WorldConfig& c) {
    World world(c);
    const double w = c.vehicles[0].params.mass * kGravity;
    for (int v = 0; v < 3; ++v) world.SetCommand(v, AttitudeCommand{1.1 * w, 0.05, -0.03, 0.2});
    Recorder rec;
    rec.Run(&world, 2.0);
    return rec;
  };
  auto same = [](double a, double b) { return (std::isnan(a) && std::isnan(b)) || a == b; };
  // When the same seed runs twice and another seed once,
  const Recorder a = run(make(7)), b = run(make(7)), other = run(make(8));
  // Then the two logs and trajectories are identical bit for bit, the third differs.
  ASSERT_EQ(a.log.size(), b.log.size());
  ASSERT_GT(a.log.size(), 1000u);
  for (std::size_t i = 0; i < a.log.size(); ++i) {
    const Measurement &x = a.log[i], &y = b.log[i];
    ASSERT_EQ(x.kind, y.kind);
    ASSERT_EQ(x.vehicle, y.vehicle);
    ASSERT_EQ(x.stamp, y.stamp);
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(same(x.position[k], y.position[k]) && same(x.euler[k], y.euler[k]) &&
                  same(x.accel[k], y.accel[k]) && same(x.gyro[k], y.gyro[k]) &&
                  same(x.velocity[k], y.velocity[k]));
    }
    ASSERT_TRUE(same(x.yaw, y.yaw) && same(x.voltage, y.voltage) &&
                same(x.relative.range, y.relative.range) &&
                same(x.relative.bearing, y.relative.bearing));
  }
  for (int v = 0; v < 3; ++v) {
    EXPECT_EQ(a.truth.back()[v].position, b.truth.back()[v].position);
  }
  bool differs = a.log.size() != other.log.size();
  for (std::size_t i = 0; !differs && i < a.log.size(); ++i) {
    differs = !same(a.log[i].position.x(), other.log[i].position.x());
  }
  EXPECT_TRUE(differs);
  EXPECT_NE(a.truth.back()[0].position, other.truth.back()[0].position);
}

}  // namespace
}  // namespace fnmpc::sim
