// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/battery.hpp"

#include <algorithm>
#include <cmath>

namespace fnmpc::sim {

namespace {
constexpr double kRpmToRadPerSec = 2.0 * M_PI / 60.0;
}  // namespace

BatteryState InitialBattery(const BatterySettings& b) {
  BatteryState s;
  s.voltage = b.full_voltage;
  s.soc = b.fixed_voltage ? 1.0 : b.initial_soc;
  if (!b.fixed_voltage) s.voltage = b.empty_voltage + (b.full_voltage - b.empty_voltage) * s.soc;
  return s;
}

void StepBattery(const BatterySettings& b, double torque_constant, const Eigen::Vector4d& rpm,
                 double dt, BatteryState* s) {
  double power = 0.0;
  for (int r = 0; r < 4; ++r) power += torque_constant * rpm[r] * rpm[r] * rpm[r] * kRpmToRadPerSec;
  s->current = power / (b.efficiency * std::max(s->voltage, 1e-3));
  if (b.fixed_voltage) {
    s->voltage = b.full_voltage;
    return;
  }
  s->soc = std::max(0.0, s->soc - s->current * dt / (3600.0 * b.capacity_ah));
  s->voltage = b.empty_voltage + (b.full_voltage - b.empty_voltage) * s->soc -
               b.internal_resistance * s->current;
  s->voltage = std::max(s->voltage, 0.1 * b.empty_voltage);
}

}  // namespace fnmpc::sim
