// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/model/vehicle_params.hpp"
#include "fnmpc/sim/world_settings.hpp"
#include "fnmpc/sim/world_vehicle.hpp"

/// The emulated autopilot of sim::World (docs/simulator.md "Autopilot"): attitude loop,
/// mixer with yaw given up first, the throttle polynomial's inverse at the battery voltage,
/// and the command-timeout failsafe (CommandTimeoutSettings).
namespace fnmpc::sim {

/// Thrust of one rotor [N] at steady state for a throttle, by Newton warm-started at
/// *guess with the robust bracketing inverse as fallback. Below the idle throttle
/// (the polynomial's value at zero thrust) the rotor does not turn.
double ThrustForThrottle(const model::ThrottlePolynomial& p, double throttle, double voltage,
                         double* guess);

namespace detail {

/// One autopilot tick at time t [s] of vehicle v with its kinematics `kin`: the failsafe,
/// then the rotor speed targets (v.rpm_target) and throttles from v's command (or its
/// direct throttles).
void AutopilotTick(const WorldConfig& config, double t, const Kinematics& kin, Vehicle& v);

}  // namespace detail

}  // namespace fnmpc::sim
