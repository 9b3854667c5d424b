// SPDX-License-Identifier: BSD-3-Clause
// The external-acceleration state of VehicleEkf (disturbance observer): observable and
// converging for a step, a ramp and a random walk with sensor noise; decoupled from the
// other states in the IMU model; NaN inputs never reach it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <vector>

#include "fnmpc/estimation/vehicle_ekf.hpp"
#include "synthetic_truth.hpp"

namespace fnmpc::estimation {
namespace {

using Idx = VehicleStateIndex;
using testing::FlyingConfig;

// Steady-state time constant of the filter's d for a continuous random walk (density q)
// observed continuously (density r): K = sqrt(q / r), tau = 1 / K [s].
double DisturbanceTimeConstant(const VehicleEkfConfig& c) {
  const double q = c.disturbance_noise * c.disturbance_noise;
  const double r = c.sensors.imu.noise.x() * c.sensors.imu.noise.x() / c.sensors.imu.rate_hz +
                   c.command_accel_noise * c.command_accel_noise;
  return std::sqrt(r / q);
}

struct Sample {
  double t = 0.0;
  Vec3 truth = Vec3::Zero(), estimate = Vec3::Zero();
  VehicleEstimate full;
};

// A level vehicle (yaw 0) commanded at hover thrust m g, pushed by an external acceleration
// d(t): its true acceleration is d(t). Truth integrated at 1 kHz; IMU (specific force
// d + g e3), motion capture and commands (50 Hz) at their default rates and noise, in stamp
// order. `thrust_offset` is added to the command the filter is told (a thrust-model error
// that d must absorb). Returns the estimate every 0.05 s.
std::vector<Sample> Fly(const std::function<Vec3(double)>& d_of_t, double duration,
                        std::uint32_t seed, const VehicleEkfConfig& cfg, double thrust_offset = 0.0,
                        const std::function<Vec3(double)>& known_of_t = nullptr) {
  const model::VehicleParams vp;
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const auto noise = [&](const Vec3& std) {
    return Vec3(std.x() * n01(rng), std.y() * n01(rng), std.z() * n01(rng));
  };
  VehicleEkf ekf(cfg, vp);
  const double h = 1e-3;
  const int imu_every = static_cast<int>(std::lround(1.0 / (cfg.sensors.imu.rate_hz * h)));
  const int mocap_every = static_cast<int>(std::lround(1.0 / (cfg.sensors.mocap.rate_hz * h)));
  const int command_every = 20, sample_every = 50;
  Vec3 p(0.0, 0.0, 1.0), v = Vec3::Zero();
  std::vector<Sample> out;
  const int steps = static_cast<int>(std::lround(duration / h));
  for (int i = 0; i <= steps; ++i) {
    const double t = i * h;
    const Vec3 d = d_of_t(t);
    if (i % command_every == 0) {
      ekf.SetCommand(t, vp.mass * kGravity + thrust_offset, 0.0, 0.0, 0.0,
                     known_of_t ? known_of_t(t) : Vec3(Vec3::Zero()));
    }
    if (i % mocap_every == 0) {
      Measurement m;
      m.kind = SensorKind::kMocapPose;
      m.stamp = m.arrival = t;
      m.position = p + noise(cfg.sensors.mocap.noise);
      m.euler = noise(cfg.sensors.mocap.noise2);
      ekf.Process(m);
    }
    if (i % imu_every == 0) {
      Measurement m;
      m.kind = SensorKind::kImu;
      m.stamp = m.arrival = t;
      m.accel = d + Vec3(0.0, 0.0, kGravity) + noise(cfg.sensors.imu.noise);
      m.gyro = noise(cfg.sensors.imu.noise2);
      ekf.Process(m);
    }
    if (i % sample_every == 0 && ekf.initialized()) {
      Sample s;
      s.t = t;
      s.truth = d - Vec3(0.0, 0.0, thrust_offset / vp.mass);
      s.full = ekf.Estimate(t);
      s.estimate = s.full.disturbance;
      out.push_back(s);
    }
    // Truth: exact for a constant acceleration over the step.
    p += h * v + 0.5 * h * h * d;
    v += h * d;
  }
  return out;
}

TEST(DisturbanceObserverTest, StepForceIsObservedAndConverges) {
  // Given a vehicle at hover that is pushed from t = 2 s by a constant force of a wake or a
  // gust: 1.5 m/s^2 down (2 N on 1.37 kg) and 0.8 / -0.5 m/s^2 sideways
  const VehicleEkfConfig cfg = FlyingConfig();
  const Vec3 step(0.8, -0.5, -1.5);
  const auto runs = Fly([&](double t) { return t < 2.0 ? Vec3(Vec3::Zero()) : step; }, 8.0, 3, cfg);
  const double tau = DisturbanceTimeConstant(cfg);
  std::printf("[disturbance step] filter time constant %.3f s\n", tau);
  double before = 0.0, after = 0.0, reached_63 = kInf;
  for (const Sample& s : runs) {
    ASSERT_TRUE(s.full.valid) << s.t;
    if (s.t > 1.0 && s.t < 2.0) before = std::max(before, s.estimate.norm());
    if (s.t >= 2.0 + 6.0 * tau) after = std::max(after, (s.estimate - s.truth).norm());
    if (s.t >= 2.0 && !std::isfinite(reached_63) &&
        (s.estimate - s.truth).norm() <= std::exp(-1.0) * step.norm()) {
      reached_63 = s.t - 2.0;
    }
  }
  std::printf("[disturbance step] |d| before %.4f, 63%% after %.3f s, max error after 6 tau %.4f\n",
              before, reached_63, after);
  // Then d is zero before the push, follows it within about one time constant (plus one
  // 0.05 s sample), and then stays within 0.05 m/s^2 (0.07 N) of it
  EXPECT_LT(before, 0.05);
  EXPECT_LT(reached_63, 1.2 * tau + 0.05);
  EXPECT_LT(after, 0.05);
}

TEST(DisturbanceObserverTest, KnownAccelerationIsNotEstimatedAgain) {
  // Given the step push of a wake from t = 2 s, of which the controller's wake model knows
  // 1.2 m/s^2 down (told with each command, as Compensation::kWake does)
  const VehicleEkfConfig cfg = FlyingConfig();
  const Vec3 step(0.8, -0.5, -1.5), known(0.0, 0.0, -1.2);
  const auto push = [&](double t) { return t < 2.0 ? Vec3(Vec3::Zero()) : step; };
  const auto model = [&](double t) { return t < 2.0 ? Vec3(Vec3::Zero()) : known; };
  const auto runs = Fly(push, 8.0, 3, cfg, 0.0, model);
  const double tau = DisturbanceTimeConstant(cfg);
  double after = 0.0;
  for (const Sample& s : runs) {
    ASSERT_TRUE(s.full.valid) << s.t;
    if (s.t >= 2.0 + 6.0 * tau) after = std::max(after, (s.estimate - (s.truth - known)).norm());
  }
  // Then d converges to the rest only (no double counting in the prediction)
  EXPECT_LT(after, 0.05);
  // And a non-finite known acceleration is refused with its command
  VehicleEkf ekf(cfg, model::VehicleParams{});
  EXPECT_EQ(ekf.SetCommand(0.0, 13.0, 0.0, 0.0, 0.0, Vec3(kNaN, 0.0, 0.0)),
            EkfStatus::kRejectedNonFinite);
}

TEST(DisturbanceObserverTest, RampIsTrackedWithTheRandomWalksLag) {
  // Given a force growing linearly (0.3, 0, -0.2) m/s^3 from t = 2 s (flying into a wake)
  const VehicleEkfConfig cfg = FlyingConfig();
  const Vec3 slope(0.3, 0.0, -0.2);
  const auto runs =
      Fly([&](double t) { return t < 2.0 ? Vec3(Vec3::Zero()) : Vec3((t - 2.0) * slope); }, 10.0, 5,
          cfg);
  const double tau = DisturbanceTimeConstant(cfg);
  // When in the steady state of the ramp (after 6 time constants), averaged over 2 s
  Vec3 lag = Vec3::Zero();
  int n = 0;
  for (const Sample& s : runs) {
    if (s.t < 8.0) continue;
    lag += s.truth - s.estimate;
    ++n;
  }
  lag /= n;
  std::printf("[disturbance ramp] lag (%.4f, %.4f, %.4f) m/s^2, predicted slope * tau = %.4f s\n",
              lag.x(), lag.y(), lag.z(), tau);
  // Then the estimate lags by slope * tau on every axis (a random-walk model's known ramp
  // error), within 20 % and 0.01 m/s^2
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(lag(i), slope(i) * tau, 0.2 * std::abs(slope(i)) * tau + 0.01) << i;
  }
}

TEST(DisturbanceObserverTest, RandomWalkWithNoiseStaysWithinTheFiltersOwnStd) {
  // Given a disturbance drawn as the filter's own random walk, default sensor noise and a
  // thrust-model error (the command 0.4 N above the true hover thrust)
  const VehicleEkfConfig cfg = FlyingConfig();
  std::mt19937 rng(11);
  std::normal_distribution<double> n01(0.0, 1.0);
  const double h = 1e-3;
  std::vector<Vec3> walk(20001, Vec3::Zero());
  for (std::size_t i = 1; i < walk.size(); ++i) {
    walk[i] =
        walk[i - 1] + cfg.disturbance_noise * std::sqrt(h) * Vec3(n01(rng), n01(rng), n01(rng));
  }
  const auto runs = Fly(
      [&](double t) {
        return walk[std::min(walk.size() - 1, static_cast<std::size_t>(std::lround(t / h)))];
      },
      20.0, 13, cfg, 0.4);
  // When compared after a 3 s burn-in
  double sq = 0.0, var = 0.0;
  int n = 0;
  for (const Sample& s : runs) {
    if (s.t < 3.0) continue;
    ASSERT_TRUE(s.estimate.allFinite());
    sq += (s.estimate - s.truth).squaredNorm() / 3.0;
    var += s.full.covariance.block<3, 3>(Idx::kDisturbance, Idx::kDisturbance).trace() / 3.0;
    ++n;
  }
  const double rms = std::sqrt(sq / n), std_filter = std::sqrt(var / n);
  // A steady-state filter with gain K = 1 / tau tracking a random walk of density q with
  // (nearly) noise-free pseudo-measurements lags it with error variance q / (2 K) per axis.
  const double q = cfg.disturbance_noise * cfg.disturbance_noise;
  const double expected = std::sqrt(q * DisturbanceTimeConstant(cfg) / 2.0);
  std::printf("[disturbance walk] rms error %.4f m/s^2 (expected %.4f), filter std %.4f m/s^2\n",
              rms, expected, std_filter);
  // Then the error is the random walk's tracking error, within 20 %, and below the filter's
  // stated std (conservative: the thrust model's error density is larger than this truth's)
  EXPECT_NEAR(rms, expected, 0.2 * expected);
  EXPECT_LT(rms, std_filter);
}

TEST(DisturbanceObserverTest, OtherStatesAreThoseOfTheFilterWithoutDisturbance) {
  // Given two filters on the same measurements, one told a command that explains the motion
  // and one told a command 3 N off (a large unexplained force)
  const VehicleEkfConfig cfg = FlyingConfig();
  const auto push = [](double t) { return Vec3(0.2 * std::sin(t), -0.1, 0.3 * std::cos(2 * t)); };
  const auto a = Fly(push, 4.0, 17, cfg, 0.0);
  const auto b = Fly(push, 4.0, 17, cfg, 3.0);
  ASSERT_EQ(a.size(), b.size());
  // Then d differs, and every other state and its covariance are bit for bit the same
  EXPECT_GT((a.back().estimate - b.back().estimate).norm(), 1.0);
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].full.x.head<Idx::kDisturbance>(), b[i].full.x.head<Idx::kDisturbance>()) << i;
    EXPECT_EQ((a[i].full.covariance.topLeftCorner<Idx::kDisturbance, Idx::kDisturbance>()),
              (b[i].full.covariance.topLeftCorner<Idx::kDisturbance, Idx::kDisturbance>()))
        << i;
  }
}

TEST(DisturbanceObserverTest, NonFiniteInputsNeverReachTheDisturbance) {
  // Given a filter in flight with a fresh command
  const VehicleEkfConfig cfg = FlyingConfig();
  VehicleEkf ekf(cfg, model::VehicleParams{});
  ekf.Initialize(0.0, Vec3(0, 0, 1), Vec3::Zero());
  ASSERT_EQ(ekf.SetCommand(0.0, 13.0, 0.0, 0.0, 0.0), EkfStatus::kAccepted);
  Measurement imu;
  imu.kind = SensorKind::kImu;
  imu.stamp = imu.arrival = 0.004;
  imu.accel = Vec3(0.0, 0.0, kGravity);
  imu.gyro = Vec3::Zero();
  ASSERT_EQ(ekf.Process(imu), EkfStatus::kAccepted);
  // When a NaN command, a NaN and an infinite specific force arrive
  EXPECT_EQ(ekf.SetCommand(0.006, kNaN, 0.0, 0.0, 0.0), EkfStatus::kRejectedNonFinite);
  imu.stamp = imu.arrival = 0.008;
  imu.accel = Vec3(kNaN, 0.0, kGravity);
  EXPECT_EQ(ekf.Process(imu), EkfStatus::kRejectedNonFinite);
  imu.stamp = imu.arrival = 0.012;
  imu.accel = Vec3(0.0, kInf, kGravity);
  EXPECT_NE(ekf.Process(imu), EkfStatus::kAccepted);
  // Then d and its covariance stay finite and the estimate valid
  imu.stamp = imu.arrival = 0.016;
  imu.accel = Vec3(0.0, 0.0, kGravity);
  ASSERT_EQ(ekf.Process(imu), EkfStatus::kAccepted);
  const VehicleEstimate e = ekf.Estimate(0.016);
  EXPECT_TRUE(e.disturbance.allFinite());
  EXPECT_TRUE(e.covariance.allFinite());
  EXPECT_TRUE(e.valid);
  // And the disturbance noise settings are validated
  VehicleEkfConfig bad = cfg;
  bad.disturbance_noise = kNaN;
  EXPECT_THROW(VehicleEkf(bad, model::VehicleParams{}), std::invalid_argument);
  bad = cfg;
  bad.initial_disturbance_std = 0.0;
  EXPECT_THROW(VehicleEkf(bad, model::VehicleParams{}), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::estimation
