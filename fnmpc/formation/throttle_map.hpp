// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/model/vehicle_params.hpp"

/// Conversion of the NMPC's collective thrust into the autopilot's collective throttle.
namespace fnmpc::formation {

/// Collective throttle in [0, 1] that makes four rotors produce `thrust` [N] in total at the
/// battery voltage `voltage` [V], from the thrust-throttle-voltage polynomial of one rotor:
/// throttle = poly(thrust / 4, V), clamped to [0, 1]. Non-finite inputs give NaN (the caller
/// must not send it). A lower voltage needs a higher throttle for the same thrust.
double ThrustToThrottle(const model::ThrottlePolynomial& poly, double thrust, double voltage);

/// Inverse: total thrust [N] of four rotors at collective `throttle` and `voltage` [V];
/// 0 below the idle throttle, NaN when the polynomial has no solution.
double ThrottleToThrust(const model::ThrottlePolynomial& poly, double throttle, double voltage);

}  // namespace fnmpc::formation
