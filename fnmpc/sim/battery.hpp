// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Core>

#include "fnmpc/sim/world_settings.hpp"

namespace fnmpc::sim {

/// State of one vehicle's battery (BatterySettings).
struct BatteryState {
  double voltage = 0.0;  ///< terminal voltage [V]
  double soc = 1.0;      ///< state of charge [-]
  double current = 0.0;  ///< [A]
};

/// The battery at t = 0: full voltage with fixed_voltage, else the open-circuit voltage of
/// the initial state of charge (no current yet).
BatteryState InitialBattery(const BatterySettings& settings);

/// One step of dt [s] with the rotor speeds `rpm` [rpm] of a vehicle whose rotors have the
/// torque constant `torque_constant` [N m / rpm^2]: the current from the shaft power at the
/// voltage before the step, then the state of charge and the terminal voltage (floored at a
/// tenth of the empty voltage).
void StepBattery(const BatterySettings& settings, double torque_constant,
                 const Eigen::Vector4d& rpm, double dt, BatteryState* state);

}  // namespace fnmpc::sim
