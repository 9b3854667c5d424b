// SPDX-License-Identifier: BSD-3-Clause
// World::SetParallelFor: a dense formation with every reality model on steps bit for bit as on
// one thread (states and the measurement stream).
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <functional>
#include <thread>
#include <vector>

#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

/// Two threads take the indices one at a time (the order differs from run to run).
void TwoThreads(int n, const std::function<void(int)>& f) {
  std::atomic<int> next{0};
  auto work = [&] {
    for (int i = next.fetch_add(1); i < n; i = next.fetch_add(1)) f(i);
  };
  std::thread other(work);
  work();
  other.join();
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

template <class M>
bool SameBits(const M& a, const M& b) {
  for (int k = 0; k < a.size(); ++k) {
    if (!SameBits(a.data()[k], b.data()[k])) return false;
  }
  return true;
}

/// 12 vehicles: a 2 x 3 grid at 1.5 m spacing in two layers 1 m apart (each upper vehicle
/// stacked above a lower one), all sensors on with the sensor reality and the relative
/// sensor's cell list, wind with gusts and turbulence, rotor aerodynamics and advected wakes.
WorldConfig DenseConfig() {
  WorldConfig c = test::QuietConfig(12);
  c.downwash.enabled = true;
  c.reality.wake = true;
  c.reality.rotor_aerodynamics = true;
  c.wind.enabled = true;
  c.wind.velocity = Vec3(1.0, 0.5, 0.0);
  c.wind.gust_std = 0.3;
  c.wind.turbulence = true;
  c.sensor_reality.enabled = true;
  c.relative_index_min_vehicles = 1;
  c.seed = 7;
  for (int i = 0; i < 12; ++i) {
    VehicleSpec& v = c.vehicles[i];
    v.sensors = SensorsConfig{};
    const int cell = i % 6;
    v.position = Vec3(1.5 * (cell % 3), 1.5 * (cell / 3), i < 6 ? 2.0 : 3.0);
  }
  return c;
}

struct Recording {
  std::vector<TrueState> states;
  std::vector<Measurement> measurements;
};

Recording Fly(bool parallel) {
  const WorldConfig c = DenseConfig();
  World w(c);
  if (parallel) w.SetParallelFor(TwoThreads);
  const model::VehicleParams& p = c.vehicles[0].params;
  Recording out;
  for (int k = 0; k < 1500; ++k) {
    for (int i = 0; i < w.num_vehicles(); ++i) {
      // Hover thrust with a small tilt that differs per vehicle: the wakes move and bend.
      AttitudeCommand cmd;
      cmd.thrust = p.mass * kGravity * (1.02 + 0.002 * i);
      cmd.roll = 0.02 * ((i % 3) - 1);
      cmd.pitch = 0.01 * ((i % 2) == 0 ? 1 : -1);
      w.SetCommand(i, cmd);
    }
    w.StepOnce();
    Measurement m;
    while (w.PopMeasurement(&m)) out.measurements.push_back(m);
  }
  for (int i = 0; i < w.num_vehicles(); ++i) out.states.push_back(w.GetTrueState(i));
  return out;
}

TEST(ParallelStepTest, TwoThreadsStepADenseFormationBitForBitAsOne) {
  // Given the dense formation flown for 1.5 s on one thread and on two,
  const Recording one = Fly(false);
  const Recording two = Fly(true);
  // then every vehicle's final state has the same bits,
  ASSERT_EQ(one.states.size(), two.states.size());
  for (std::size_t i = 0; i < one.states.size(); ++i) {
    const TrueState& a = one.states[i];
    const TrueState& b = two.states[i];
    EXPECT_TRUE(SameBits(a.position, b.position) && SameBits(a.velocity, b.velocity) &&
                SameBits(a.euler, b.euler) && SameBits(a.body_rates, b.body_rates) &&
                SameBits(a.rotor_rpm, b.rotor_rpm) && SameBits(a.aero_force, b.aero_force) &&
                SameBits(a.aero_torque, b.aero_torque) && SameBits(a.voltage, b.voltage))
        << "vehicle " << i;
    // (the upper layer flew, the lower one was pushed down by the wakes above it)
    if (i >= 6) {
      EXPECT_GT(a.position.z(), 2.5) << "vehicle " << i;
    }
    EXPECT_GT(a.aero_force.norm(), 0.0);
  }
  // and the measurement stream is the same, in the same order, with the same bits,
  ASSERT_EQ(one.measurements.size(), two.measurements.size());
  int relative = 0;
  for (std::size_t k = 0; k < one.measurements.size(); ++k) {
    const Measurement& a = one.measurements[k];
    const Measurement& b = two.measurements[k];
    relative += a.kind == SensorKind::kRelative ? 1 : 0;
    ASSERT_TRUE(a.kind == b.kind && a.vehicle == b.vehicle && SameBits(a.stamp, b.stamp) &&
                SameBits(a.arrival, b.arrival) && SameBits(a.position, b.position) &&
                SameBits(a.accel, b.accel) && SameBits(a.gyro, b.gyro) &&
                a.relative.target == b.relative.target &&
                SameBits(a.relative.range, b.relative.range) &&
                SameBits(a.relative.bearing, b.relative.bearing))
        << "measurement " << k;
  }
  // relative observations among them.
  EXPECT_GT(relative, 1000);
}

}  // namespace
}  // namespace fnmpc::sim
