// SPDX-License-Identifier: BSD-3-Clause
// Google Benchmark figures of the estimators' hot paths:
//   BM_EkfPredict/<filter>: one prediction (VehicleEkf: an IMU sample at 250 Hz in flying
//     mode, i.e. a 4 ms strapdown step; NeighbourEkf: PredictTo 10 ms ahead).
//   BM_EkfUpdate/<filter>: one measurement update at the current stamp (no prediction):
//     VehicleEkf mocap (6-D), optical flow (3-D), compass (1-D); NeighbourEkf relative (4-D).
//   BM_EkfReplay/Vehicle: a mocap fix 0.1 s late (restore + replay of ~40 events).
// Median and max over repetitions are reported (real-time budgets use the worst case).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <vector>

#include "fnmpc/estimation/neighbour_ekf.hpp"
#include "fnmpc/estimation/vehicle_ekf.hpp"

namespace fnmpc::estimation {
namespace {

double Max(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }

VehicleEkfConfig FlyingConfig() {
  VehicleEkfConfig c;
  c.initial_mode = VehicleMode::kFlying;
  c.auto_mode_switch = false;
  return c;
}

Measurement Imu(double t) {
  Measurement m;
  m.kind = SensorKind::kImu;
  m.stamp = t;
  m.accel = Vec3(0.1, -0.05, kGravity);
  m.gyro = Vec3(0.01, 0.02, -0.01);
  return m;
}

Measurement Mocap(double t) {
  Measurement m;
  m.kind = SensorKind::kMocapPose;
  m.stamp = t;
  m.position = Vec3(0.001, 0.0, 1.0);
  m.euler = Vec3(0.0, 0.001, 0.3);
  return m;
}

// A flying filter warmed up with 2 s of IMU at 250 Hz and mocap at 60 Hz.
VehicleEkf WarmVehicle(double* t_end) {
  VehicleEkf ekf(FlyingConfig(), model::VehicleParams{});
  ekf.Initialize(0.0, Vec3(0, 0, 1), Vec3(0, 0, 0.3));
  double t = 0.0;
  for (int k = 1; k <= 500; ++k) {
    t = k * 0.004;
    ekf.Process(Imu(t));
    if (k % 4 == 0) ekf.Process(Mocap(t + 0.001));
  }
  *t_end = t + 0.001;
  return ekf;
}

void BM_EkfPredict_Vehicle(benchmark::State& state) {
  double t = 0.0;
  VehicleEkf ekf = WarmVehicle(&t);
  for (auto _ : state) {
    t += 0.004;
    benchmark::DoNotOptimize(ekf.Process(Imu(t)));
  }
}

void BM_EkfUpdate_Vehicle(benchmark::State& state) {
  double t = 0.0;
  const VehicleEkf warm = WarmVehicle(&t);
  VehicleEkf ekf = warm;
  const auto kind = static_cast<SensorKind>(state.range(0));
  Measurement m = Mocap(t);
  m.kind = kind;
  m.velocity = Vec3(0.01, 0.0, 0.0);
  m.yaw = 0.3;
  int n = 0;
  for (auto _ : state) {
    if (++n % 200 == 0) {  // keep the covariance realistic
      state.PauseTiming();
      ekf = warm;
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(ekf.Process(m));  // same stamp: update only
  }
  state.SetLabel(std::string(ToString(kind)));
}

void BM_EkfReplay_Vehicle(benchmark::State& state) {
  double t = 0.0;
  const VehicleEkf warm = WarmVehicle(&t);
  VehicleEkf ekf = warm;
  for (auto _ : state) {
    state.PauseTiming();
    ekf = warm;
    state.ResumeTiming();
    benchmark::DoNotOptimize(ekf.Process(Mocap(t - 0.1)));
  }
}

Measurement Relative(double t) {
  Measurement m;
  m.kind = SensorKind::kRelative;
  m.stamp = t;
  m.relative = {1, 2.5, 0.4, 0.05, 0.2};
  return m;
}

NeighbourEkf WarmNeighbour(double* t_end) {
  NeighbourEkf ekf(NeighbourEkfConfig{});
  const Vec3 e(0.01, -0.02, 0.3), v(0.2, 0.0, 0.0);
  double t = 0.0;
  for (int k = 1; k <= 200; ++k) {
    t = k * 0.01;
    ekf.PredictTo(t, v);
    if (k % 2 == 0) ekf.Process(Relative(t), e, v);
  }
  *t_end = t;
  return ekf;
}

void BM_EkfPredict_Neighbour(benchmark::State& state) {
  double t = 0.0;
  NeighbourEkf ekf = WarmNeighbour(&t);
  const Vec3 v(0.2, 0.0, 0.0);
  for (auto _ : state) {
    t += 0.01;
    benchmark::DoNotOptimize(ekf.PredictTo(t, v));
  }
}

void BM_EkfUpdate_Neighbour(benchmark::State& state) {
  double t = 0.0;
  const NeighbourEkf warm = WarmNeighbour(&t);
  NeighbourEkf ekf = warm;
  const Vec3 e(0.01, -0.02, 0.3), v(0.2, 0.0, 0.0);
  const Measurement m = Relative(t);
  int n = 0;
  for (auto _ : state) {
    if (++n % 200 == 0) {
      state.PauseTiming();
      ekf = warm;
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(ekf.Process(m, e, v));
  }
}

#define FNMPC_EKF_BENCH(fn) \
  BENCHMARK(fn)->Repetitions(10)->ReportAggregatesOnly(true)->ComputeStatistics("max", Max)

FNMPC_EKF_BENCH(BM_EkfPredict_Vehicle);
FNMPC_EKF_BENCH(BM_EkfUpdate_Vehicle)
    ->Arg(static_cast<int>(SensorKind::kMocapPose))
    ->Arg(static_cast<int>(SensorKind::kOpticalFlow))
    ->Arg(static_cast<int>(SensorKind::kCompass));
FNMPC_EKF_BENCH(BM_EkfReplay_Vehicle);
FNMPC_EKF_BENCH(BM_EkfPredict_Neighbour);
FNMPC_EKF_BENCH(BM_EkfUpdate_Neighbour);

}  // namespace
}  // namespace fnmpc::estimation
