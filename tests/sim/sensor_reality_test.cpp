// SPDX-License-Identifier: BSD-3-Clause
// Sensor and autopilot reality models (SensorRealitySettings).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/sim/world.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

WorldConfig HoverWorld(bool reality) {
  WorldConfig c = test::QuietConfig(1);
  c.battery.fixed_voltage = true;
  c.vehicles[0].position = Vec3(0.0, 0.0, 2.0);
  c.vehicles[0].sensors.mocap.enabled = true;
  c.vehicles[0].sensors.mocap.rate_hz = 100.0;
  c.vehicles[0].sensors.mocap.latency_s = 0.005;
  c.vehicles[0].sensors.mocap.noise2 = Vec3::Constant(0.002);
  c.vehicles[0].sensors.imu.enabled = true;
  c.vehicles[0].sensors.imu.rate_hz = 250.0;
  c.vehicles[0].sensors.imu.noise2 = Vec3::Constant(0.005);
  c.sensor_reality.enabled = reality;
  c.sensor_reality.burst_share = 0.05;  // large enough to count in 60 s
  c.sensor_reality.burst_length = 0.2;
  c.sensor_reality.mocap_outlier_rate = 0.02;
  c.seed = 11;
  return c;
}

TEST(SensorRealityTest, JitterBurstsOutliersAndBiasesAppearInTheMeasurements) {
  World w(HoverWorld(true));
  const SensorRealitySettings& sr = HoverWorld(true).sensor_reality;
  const double hover = 1.37 * kGravity;
  std::vector<double> stamps, delays;
  int outliers = 0, mocap = 0;
  Vec3 gyro_mean = Vec3::Zero();
  int imu = 0;
  Measurement m;
  for (int k = 0; k < 60000; ++k) {
    if (k % 4 == 0) w.SetCommand(0, {hover, 0.0, 0.0, 0.0});
    w.SetPose(0, Vec3(0.0, 0.0, 2.0), Vec3::Zero());  // held: truth is level and still
    w.StepOnce();
    while (w.PopMeasurement(&m)) {
      if (m.kind == SensorKind::kMocapPose) {
        ++mocap;
        stamps.push_back(m.stamp);
        delays.push_back(m.arrival - m.stamp);
        if ((m.position - Vec3(0.0, 0.0, 2.0)).norm() > 0.03) ++outliers;
      } else if (m.kind == SensorKind::kImu) {
        gyro_mean += m.gyro;
        ++imu;
      }
    }
  }
  // Latency: between the sensor's latency and latency + jitter, and not constant.
  double dmin = 1.0, dmax = 0.0;
  for (double d : delays) {
    dmin = std::min(dmin, d);
    dmax = std::max(dmax, d);
  }
  EXPECT_GE(dmin, 0.005 - 1e-12);
  EXPECT_LE(dmax, 0.005 + sr.latency_jitter + 1e-12);
  EXPECT_GT(dmax - dmin, 0.5 * sr.latency_jitter);
  // Bursty dropouts: the lost share near burst_share, in runs of about burst_length.
  const double expected = 60.0 * 100.0;
  const double lost = 1.0 - mocap / expected;
  EXPECT_NEAR(lost, sr.burst_share, 0.025);
  int gaps = 0;
  for (std::size_t i = 1; i < stamps.size(); ++i) gaps += stamps[i] - stamps[i - 1] > 0.015 ? 1 : 0;
  ASSERT_GT(gaps, 0);
  const double mean_gap_samples = (expected - mocap) / gaps;
  EXPECT_GT(mean_gap_samples, 0.4 * sr.burst_length * 100.0);
  EXPECT_LT(mean_gap_samples, 2.5 * sr.burst_length * 100.0);
  // Outliers: about the configured share of the delivered samples.
  EXPECT_NEAR(static_cast<double>(outliers) / mocap, 0.02, 0.008);
  // Gyro bias: the mean gyro of a still vehicle is not zero (0.005 rad/s sd per axis), far
  // above its noise average (0.005 / sqrt(15000)).
  gyro_mean /= imu;
  EXPECT_GT(gyro_mean.norm(), 5e-4);
}

TEST(SensorRealityTest, AutopilotFliesOnItsOwnEstimateThatStaysCloseToTheTruth) {
  // A vehicle hovering on attitude commands: its estimate is not the truth but within a
  // fraction of a degree (gyro bias 0.3 deg/s times the 0.5 s correction time constant).
  WorldConfig c = HoverWorld(true);
  c.vehicles[0].params.bias = model::CalibrationBias{};
  World w(c);
  double max_tilt = 0.0;
  for (int k = 0; k < 10000; ++k) {
    if (k % 20 == 0) w.SetCommand(0, {1.37 * kGravity, 0.0, 0.0, 0.0});
    w.StepOnce();
    const TrueState x = w.GetTrueState(0);
    if (k > 2000) max_tilt = std::max(max_tilt, std::hypot(x.euler.x(), x.euler.y()));
  }
  // The vehicle holds level to within a degree, but not exactly (it flies the estimate).
  EXPECT_LT(max_tilt, 1.0 * M_PI / 180.0);
  EXPECT_GT(max_tilt, 1e-4);
}

TEST(SensorRealityTest, OffLeavesTheMeasurementStreamUntouched) {
  // Two worlds with reality off and the same seed give the same stream; reality on differs.
  auto run = [](bool reality) {
    World w(HoverWorld(reality));
    std::vector<double> v;
    Measurement m;
    for (int k = 0; k < 2000; ++k) {
      w.StepOnce();
      while (w.PopMeasurement(&m)) v.push_back(m.arrival);
    }
    return v;
  };
  EXPECT_EQ(run(false), run(false));
  EXPECT_NE(run(false), run(true));
}

}  // namespace
}  // namespace fnmpc::sim
