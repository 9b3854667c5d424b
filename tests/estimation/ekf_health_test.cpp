// SPDX-License-Identifier: BSD-3-Clause
// Estimator health: validity from covariance limits and staleness per measurement kind,
// capped extrapolation, forward time jumps and time going backwards, the pitch envelope.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "fnmpc/estimation/neighbour_ekf.hpp"
#include "fnmpc/estimation/vehicle_ekf.hpp"
#include "synthetic_truth.hpp"

namespace fnmpc::estimation {
namespace {

using testing::GenerateVehicleStream;
using testing::LissajousTrajectory;
using testing::SensorStream;
using testing::SensorStreamOptions;
using Idx = VehicleStateIndex;
using testing::FlyingConfig;

SensorStream Stream(const VehicleEkfConfig& cfg, std::uint32_t seed, double t1, bool mocap = true) {
  std::mt19937 rng(seed);
  SensorStreamOptions opt;
  opt.t1 = t1;
  opt.mocap = mocap;
  return GenerateVehicleStream(LissajousTrajectory{}, cfg.sensors, opt, &rng);
}

constexpr auto kMocapBit = 1u << static_cast<unsigned>(SensorKind::kMocapPose);
constexpr auto kFlowBit = 1u << static_cast<unsigned>(SensorKind::kOpticalFlow);
constexpr auto kImuBit = 1u << static_cast<unsigned>(SensorKind::kImu);

TEST(VehicleEkfHealthTest, ValidThroughoutNominalFlightLeaderAndFollower) {
  // Given a 10 s flight with every sensor (leader) and one without mocap (follower,
  // initialised explicitly as the controller does), default health limits
  const VehicleEkfConfig cfg = FlyingConfig();
  for (const bool leader : {true, false}) {
    const SensorStream s = Stream(cfg, 5, 10.0, leader);
    VehicleEkf ekf(cfg, model::VehicleParams{});
    if (!leader) ekf.Initialize(0.0, Vec3::Zero(), LissajousTrajectory{}.At(0.0).euler);
    int invalid = 0, checked = 0;
    double max_imu_staleness = 0.0;
    // When every measurement is fused and the estimate queried 10 ms after its stamp
    for (const Measurement& m : s.measurements) {
      ekf.Process(m);
      if (!ekf.initialized() || m.stamp < 0.5) continue;
      const VehicleEstimate e = ekf.Estimate(m.stamp + 0.01);
      ++checked;
      invalid += e.valid ? 0 : 1;
      EXPECT_EQ(e.valid, e.health.flags == 0u);
      max_imu_staleness = std::max(max_imu_staleness,
                                   e.health.staleness[static_cast<std::size_t>(SensorKind::kImu)]);
    }
    const VehicleEstimate end = ekf.Estimate(10.0);
    std::printf(
        "[health nominal %s] %d/%d invalid; position std %.4f m, velocity %.4f m/s, "
        "attitude %.4f rad; IMU staleness <= %.4f s\n",
        leader ? "leader" : "follower", invalid, checked, end.health.position_std,
        end.health.velocity_std, end.health.attitude_std, max_imu_staleness);
    // Then it is valid throughout (the follower's mocap is not monitored: never fused)
    EXPECT_EQ(invalid, 0);
    EXPECT_GT(checked, 1000);
    EXPECT_LT(max_imu_staleness, 0.02);
    EXPECT_EQ(std::isfinite(end.health.staleness[0]), leader);
  }
}

TEST(VehicleEkfHealthTest, StaleKindFlaggedUntilItReturns) {
  // Given a leader flight whose mocap stops in [4, 6) s and optical flow in [7, 8) s
  const VehicleEkfConfig cfg = FlyingConfig();
  const SensorStream s = Stream(cfg, 8, 10.0);
  VehicleEkf ekf(cfg, model::VehicleParams{});
  std::uint32_t stale_at_5 = 0, stale_at_7_8 = 0, stale_at_9 = 99;
  double mocap_staleness_at_5 = 0.0;
  bool valid_at_4_3 = false, valid_at_9 = false;
  // When processed (Estimate at each stamp)
  for (const Measurement& m : s.measurements) {
    const bool lost = (m.kind == SensorKind::kMocapPose && m.stamp >= 4.0 && m.stamp < 6.0) ||
                      (m.kind == SensorKind::kOpticalFlow && m.stamp >= 7.0 && m.stamp < 8.0);
    if (!lost) ekf.Process(m);
    const VehicleEstimate e = ekf.Estimate(m.stamp);
    if (std::abs(m.stamp - 4.3) < 0.002) valid_at_4_3 = e.valid;
    if (std::abs(m.stamp - 5.0) < 0.002) {
      stale_at_5 = e.health.stale_kinds;
      mocap_staleness_at_5 = e.health.staleness[0];
      EXPECT_TRUE(e.health.Has(HealthFlag::kStale));
      EXPECT_FALSE(e.valid);
      EXPECT_TRUE(e.health.IsStale(SensorKind::kMocapPose));
    }
    if (std::abs(m.stamp - 7.8) < 0.002) stale_at_7_8 = e.health.stale_kinds;
    if (std::abs(m.stamp - 9.0) < 0.002) {
      stale_at_9 = e.health.stale_kinds;
      valid_at_9 = e.valid;
    }
  }
  std::printf("[health stale] mocap staleness at 5 s: %.3f s\n", mocap_staleness_at_5);
  // Then mocap is flagged (alone) once older than 0.5 s, flow likewise, both recover
  EXPECT_TRUE(valid_at_4_3);
  EXPECT_EQ(stale_at_5, kMocapBit);
  EXPECT_NEAR(mocap_staleness_at_5, 1.0, 0.02);
  EXPECT_EQ(stale_at_7_8, kFlowBit);
  EXPECT_EQ(stale_at_9, 0u);
  EXPECT_TRUE(valid_at_9);
}

TEST(VehicleEkfHealthTest, CovarianceLimitsFlagTheUncertainPart) {
  // Given a leader whose mocap stops at 3 s (staleness of mocap not monitored, position std
  // limit 5 mm), and a follower (no mocap) with the same limit
  VehicleEkfConfig cfg = FlyingConfig();
  cfg.max_staleness[0] = kInf;
  cfg.max_position_std = 0.005;
  for (const bool leader : {true, false}) {
    const SensorStream s = Stream(cfg, 9, 10.0, leader);
    VehicleEkf ekf(cfg, model::VehicleParams{});
    if (!leader) ekf.Initialize(0.0, Vec3::Zero(), LissajousTrajectory{}.At(0.0).euler);
    bool valid_at_2 = false, uncertain_at_end = false;
    double std_at_end = 0.0;
    // When processed
    for (const Measurement& m : s.measurements) {
      if (m.kind == SensorKind::kMocapPose && m.stamp >= 3.0) continue;
      ekf.Process(m);
      if (std::abs(m.stamp - 2.0) < 0.002) valid_at_2 = ekf.Estimate(m.stamp).valid;
    }
    const VehicleEstimate e = ekf.Estimate(10.0);
    uncertain_at_end = e.health.Has(HealthFlag::kPositionUncertain);
    std_at_end = e.health.position_std;
    std::printf("[health covariance %s] position std at 10 s %.4f m, flags %#x\n",
                leader ? "leader" : "follower", std_at_end, e.health.flags);
    // Then the leader is valid with mocap, and flagged position-uncertain (only) when its
    // dead-reckoned std passes 5 mm; the follower's position in {m} is never monitored
    EXPECT_TRUE(valid_at_2 || !leader);
    EXPECT_GT(std_at_end, 0.005);
    EXPECT_EQ(uncertain_at_end, leader);
    EXPECT_EQ(e.health.flags,
              leader ? static_cast<std::uint32_t>(HealthFlag::kPositionUncertain) : 0u);
  }
}

TEST(VehicleEkfHealthTest, ExtrapolationCappedAndFlagged) {
  // Given a filter after 3 s of flight
  const VehicleEkfConfig cfg = FlyingConfig();
  const SensorStream s = Stream(cfg, 11, 3.0);
  VehicleEkf ekf(cfg, model::VehicleParams{});
  for (const Measurement& m : s.measurements) ekf.Process(m);
  const double t0 = ekf.time();
  // When the estimate is asked 0.04 s, 0.2 s, 0.4 s, 1 h and 1e300 s ahead, and at NaN
  const VehicleEstimate near = ekf.Estimate(t0 + 0.04);
  const VehicleEstimate fallback = ekf.Estimate(t0 + 0.2);
  const VehicleEstimate imu_stale = ekf.Estimate(t0 + 0.4);
  const VehicleEstimate hour = ekf.Estimate(t0 + 3600.0);
  const VehicleEstimate huge = ekf.Estimate(1e300);
  const VehicleEstimate nan = ekf.Estimate(kNaN);
  // Then within the IMU timeout it is valid; at 0.2 s the constant-velocity fallback has
  // made the velocity uncertain (std above 1 m/s); at 0.4 s the IMU is stale too; beyond
  // max_extrapolation the state is that at t0 + 0.5 s, finite, flagged
  EXPECT_TRUE(near.valid);
  EXPECT_DOUBLE_EQ(near.time, t0 + 0.04);
  EXPECT_EQ(fallback.health.flags, static_cast<std::uint32_t>(HealthFlag::kVelocityUncertain));
  EXPECT_FALSE(imu_stale.valid);
  EXPECT_EQ(imu_stale.health.stale_kinds & kImuBit, kImuBit);
  EXPECT_FALSE(imu_stale.health.Has(HealthFlag::kExtrapolationLimit));
  for (const VehicleEstimate* e : {&hour, &huge}) {
    EXPECT_FALSE(e->valid);
    EXPECT_TRUE(e->health.Has(HealthFlag::kExtrapolationLimit));
    EXPECT_DOUBLE_EQ(e->time, t0 + cfg.max_extrapolation);
    EXPECT_TRUE(e->x.allFinite());
    EXPECT_TRUE(e->covariance.allFinite());
  }
  EXPECT_LT((hour.x - huge.x).norm(), 1e-12);
  EXPECT_FALSE(nan.valid);
  EXPECT_TRUE(nan.health.Has(HealthFlag::kNonFinite));
}

TEST(VehicleEkfHealthTest, TimeJumpsRejectedCountedAndReanchored) {
  // Given a filter after 5 s of flight
  const VehicleEkfConfig cfg = FlyingConfig();
  const SensorStream s = Stream(cfg, 13, 12.0);
  VehicleEkf ekf(cfg, model::VehicleParams{});
  std::size_t i = 0;
  for (; s.measurements[i].stamp < 5.0; ++i) ekf.Process(s.measurements[i]);
  const VehicleEstimate before = ekf.Estimate(ekf.time());
  // When single measurements arrive stamped 1 h, 1e300 and -1 h away, and a command 1 h ahead
  Measurement jump = s.measurements[i];
  jump.stamp += 3600.0;
  EXPECT_EQ(ekf.Process(jump), EkfStatus::kRejectedTimeJump);
  jump.stamp = 1e300;
  EXPECT_EQ(ekf.Process(jump), EkfStatus::kRejectedTimeJump);
  jump.stamp = s.measurements[i].stamp - 3600.0;
  EXPECT_EQ(ekf.Process(jump), EkfStatus::kRejectedTooOld);
  EXPECT_EQ(ekf.SetCommand(1e300, 13.0, 0.0, 0.0, 0.0), EkfStatus::kRejectedTimeJump);
  // Then the state is untouched, each is counted under its reason
  EXPECT_EQ((ekf.Estimate(before.time).x - before.x).norm(), 0.0);
  const SensorKind k = jump.kind;
  EXPECT_EQ(ekf.counters().Get(EkfStatus::kRejectedTimeJump, k), 2);
  EXPECT_EQ(ekf.counters().Get(EkfStatus::kRejectedTooOld, k), 1);
  EXPECT_EQ(ekf.counters().commands_rejected, 1);
  // And the stream continues as if nothing happened
  for (; s.measurements[i].stamp < 8.0; ++i) {
    EXPECT_EQ(ekf.Process(s.measurements[i]) == EkfStatus::kRejectedTimeJump, false);
  }
  EXPECT_TRUE(ekf.Estimate(8.0).valid);
  EXPECT_EQ(ekf.counters().time_resets, 0);
  // When the clock of every sensor really jumps by 100 s
  int rejected = 0;
  double t_reset = kNaN;
  const LissajousTrajectory traj;
  double err_end = kNaN;
  for (; i < s.measurements.size(); ++i) {
    Measurement m = s.measurements[i];
    m.stamp += 100.0;
    if (ekf.Process(m) == EkfStatus::kRejectedTimeJump) ++rejected;
    if (!std::isfinite(t_reset) && ekf.counters().time_resets == 1) t_reset = m.stamp;
    err_end = (ekf.Estimate(m.stamp).position - traj.At(m.stamp - 100.0).p).norm();
  }
  const VehicleEstimate end = ekf.Estimate(112.0);
  std::printf("[health time jump] %d rejected, re-anchored at %.3f s, end position error %.4f m\n",
              rejected, t_reset, err_end);
  // Then the first time_jump_reset_count - 1 are rejected, the filter re-anchors at the next
  // and tracks again: valid, position error at the mocap level
  EXPECT_EQ(rejected, cfg.time_jump_reset_count - 1);
  EXPECT_EQ(ekf.counters().time_resets, 1);
  EXPECT_TRUE(end.valid);
  EXPECT_LT(err_end, 0.005);
}

TEST(VehicleEkfHealthTest, PitchBeyondEnvelopeFlaggedAndFinite) {
  // Given a flying filter initialised at pitch 1.3 rad and one at 1.5699 rad (next to the
  // Euler singularity), IMU samples with body rates
  const VehicleEkfConfig cfg = FlyingConfig();
  for (const double pitch : {1.3, 1.5699}) {
    VehicleEkf ekf(cfg, model::VehicleParams{});
    ekf.Initialize(0.0, Vec3(0, 0, 1), Vec3(0.1, pitch, 0.2));
    // When the IMU drives it for 0.2 s
    for (int k = 1; k <= 50; ++k) {
      Measurement m;
      m.kind = SensorKind::kImu;
      m.stamp = 0.004 * k;
      m.accel = Vec3(0, 0, kGravity);
      m.gyro = Vec3(0.3, -0.2, 0.5);
      ekf.Process(m);
    }
    const VehicleEstimate e = ekf.Estimate(0.2);
    // Then the state and covariance stay finite and the envelope flag is set
    EXPECT_TRUE(e.x.allFinite());
    EXPECT_TRUE(e.covariance.allFinite());
    EXPECT_TRUE(e.health.Has(HealthFlag::kAttitudeEnvelope));
    EXPECT_FALSE(e.valid);
  }
}

// --- NeighbourEkf ----------------------------------------------------------------------

Measurement Relative(double t, const Vec3& offset, std::mt19937* rng) {
  const SensorSpec spec = SensorsConfig{}.relative;
  std::normal_distribution<double> nd(0.0, 1.0);
  Measurement m;
  m.kind = SensorKind::kRelative;
  m.vehicle = 0;
  m.stamp = t;
  m.relative = testing::TrueRelative(Vec3::Zero(), Vec3::Zero(), offset, 0.5, 1);
  m.relative.range +=
      spec.noise.x() * (1.0 + spec.range_noise_growth * m.relative.range) * nd(*rng);
  m.relative.bearing += spec.noise.y() * nd(*rng);
  m.relative.elevation += spec.noise.z() * nd(*rng);
  m.relative.relative_yaw += spec.noise2.x() * nd(*rng);
  return m;
}

TEST(NeighbourEkfHealthTest, StaleAndUncertainAfterLossValidAgainOnReturn) {
  // Given a neighbour at rest measured at 50 Hz for 3 s, then lost for 3 s, then back
  NeighbourEkf ekf(NeighbourEkfConfig{});
  std::mt19937 rng(3);
  const Vec3 offset(2.0, 1.0, 0.3);
  NeighbourEstimate at_3, at_3_4, at_3_6, at_5_9, at_6_5;
  // When PredictTo runs at 100 Hz throughout
  for (int k = 0; k <= 700; ++k) {
    const double t = 0.01 * k;
    if (k % 2 == 1 && !(t > 3.0 && t < 6.0)) {
      ekf.Process(Relative(t, offset, &rng), Vec3::Zero(), Vec3::Zero());
    } else if (ekf.initialized()) {
      ekf.PredictTo(t, Vec3::Zero());
    }
    const NeighbourEstimate e = ekf.EstimateAt(t, Vec3::Zero());
    if (k == 300) at_3 = e;
    if (k == 340) at_3_4 = e;
    if (k == 360) at_3_6 = e;
    if (k == 590) at_5_9 = e;
    if (k == 650) at_6_5 = e;
  }
  const auto rel = static_cast<std::size_t>(SensorKind::kRelative);
  std::printf("[neighbour health] dx std %.4f -> %.4f m (5.9 s), staleness at 3.6 s %.3f s\n",
              at_3.health.position_std, at_5_9.health.position_std, at_3_6.health.staleness[rel]);
  // Then valid before and 0.4 s into the loss, stale after 0.5 s, also position-uncertain
  // before the measurements return (dx std above 0.5 m), valid again after
  EXPECT_TRUE(at_3.valid);
  EXPECT_TRUE(at_3_4.valid);
  EXPECT_FALSE(at_3_6.valid);
  EXPECT_EQ(at_3_6.health.flags, static_cast<std::uint32_t>(HealthFlag::kStale));
  EXPECT_TRUE(at_3_6.health.IsStale(SensorKind::kRelative));
  EXPECT_NEAR(at_3_6.health.staleness[rel], 0.61, 1e-9);
  EXPECT_TRUE(at_5_9.health.Has(HealthFlag::kPositionUncertain));
  EXPECT_TRUE(at_6_5.valid);
  EXPECT_LT((at_6_5.x.head<3>() - offset).norm(), 0.05);
  // And EstimateAt agrees with StateAt / covariance()
  EXPECT_EQ((ekf.EstimateAt(7.0, Vec3::Zero()).x - ekf.StateAt(7.0, Vec3::Zero())).norm(), 0.0);
}

TEST(NeighbourEkfHealthTest, TimeJumpsRejectedExtrapolationCappedReinitialised) {
  // Given a neighbour filter after 2 s
  NeighbourEkf ekf(NeighbourEkfConfig{});
  std::mt19937 rng(4);
  const Vec3 offset(-1.0, 0.5, 0.2);
  for (int k = 0; k <= 200; ++k) {
    const double t = 0.01 * k;
    if (k % 2 == 1) {
      ekf.Process(Relative(t, offset, &rng), Vec3::Zero(), Vec3::Zero());
    } else if (ekf.initialized()) {
      ekf.PredictTo(t, Vec3::Zero());
    }
  }
  const NeighbourStateVec x = ekf.state();
  // When PredictTo and a measurement jump 1 h ahead, and the estimate is asked 1e300 ahead
  EXPECT_EQ(ekf.PredictTo(3602.0, Vec3::Zero()), EkfStatus::kRejectedTimeJump);
  EXPECT_EQ(ekf.Process(Relative(1e300, offset, &rng), Vec3::Zero(), Vec3::Zero()),
            EkfStatus::kRejectedTimeJump);
  const NeighbourEstimate far = ekf.EstimateAt(1e300, Vec3::Zero());
  // Then nothing changed, the far estimate is capped (finite, flagged)
  EXPECT_EQ((ekf.state() - x).norm(), 0.0);
  EXPECT_EQ(ekf.counters().Get(EkfStatus::kRejectedTimeJump, SensorKind::kRelative), 1);
  EXPECT_EQ(ekf.counters().commands_rejected, 1);
  EXPECT_TRUE(far.x.allFinite());
  EXPECT_TRUE(far.covariance.allFinite());
  EXPECT_DOUBLE_EQ(far.time, 2.0 + NeighbourEkfConfig{}.max_extrapolation);
  EXPECT_TRUE(far.health.Has(HealthFlag::kExtrapolationLimit));
  EXPECT_FALSE(far.valid);
  // When the clock really jumps: measurements continue 100 s later
  int rejected = 0;
  for (int k = 1; k <= 100; ++k) {
    const double t = 102.0 + 0.02 * k;
    if (ekf.Process(Relative(t, offset, &rng), Vec3::Zero(), Vec3::Zero()) ==
        EkfStatus::kRejectedTimeJump) {
      ++rejected;
    }
  }
  // Then after time_jump_reset_count - 1 rejections the filter re-initialises and is valid
  const NeighbourEstimate end = ekf.EstimateAt(104.0, Vec3::Zero());
  EXPECT_EQ(rejected, NeighbourEkfConfig{}.time_jump_reset_count - 1);
  EXPECT_EQ(ekf.counters().time_resets, 1);
  EXPECT_TRUE(end.valid);
  EXPECT_LT((end.x.head<3>() - offset).norm(), 0.05);
}

}  // namespace
}  // namespace fnmpc::estimation
