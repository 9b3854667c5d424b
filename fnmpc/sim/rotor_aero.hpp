// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"

/// Rotor aerodynamics of the simulator's reality models (docs/simulator.md, "Reality"):
/// thrust in axial inflow by combined blade-element momentum theory, ground effect, rotor
/// drag. Pure functions, no allocation.
namespace fnmpc::sim {

/// Blade-element data of one propeller (uniform pitch and chord, Leishman 2006, Principles
/// of Helicopter Aerodynamics, 2nd ed., sec. 3.3: C_T = (sigma a / 2) (theta / 3 - lambda / 2)
/// with momentum inflow lambda = lambda_c + lambda_i, C_T = 2 lambda_i lambda).
struct RotorBlade {
  double radius = 0.127;       ///< R [m] (10 inch propeller)
  double solidity = 0.10;      ///< sigma = N c / (pi R): 2 blades of ~20 mm chord at 0.75 R
  double lift_slope = 5.73;    ///< a [1/rad]: 2 pi x 0.91 (thin aerofoil with a 3-D loss)
  double air_density = 1.225;  ///< rho [kg/m^3]
};

/// Thrust of one rotor in axial inflow relative to its static thrust at the same rotor
/// speed, T(V_c) / T(0), for the axial climb velocity V_c [m/s] (air moving down through
/// the disc relative to the rotor: > 0 for climb or for the wake of a vehicle above), the
/// static thrust T0 [N] and the rotor speed omega [rad/s]. The effective pitch theta is
/// the one that gives T0 statically (so the identified T_k is kept in still air). Combined
/// BEMT: lambda solves 2 lambda^2 + (sigma a / 4 - 2 lambda_c) lambda - sigma a theta / 6 = 0.
/// Momentum theory fails in the vortex-ring state: descent inflow is limited to
/// lambda_c >= -lambda_h (ratio still finite and continuous there). Returns 1 for T0 <= 0.
double AxialInflowThrustRatio(const RotorBlade& blade, double static_thrust, double omega,
                              double climb_velocity);

/// Ground effect of Cheeseman and Bennett (1955, ARC R&M 3021): T_IGE / T_OGE =
/// 1 / (1 - (R / (4 z))^2) for a rotor at height z above the ground [m]; z is limited below to
/// R / 2 (the model's validity starts there, ratio 4/3), 1 for z <= 0 or far away.
double GroundEffectRatio(double radius, double height);

/// Rotor drag (induced drag and blade flapping) of one rotor, linear in its speed and the
/// in-plane air velocity (Martin and Salaun 2010, ICRA, "The true role of accelerometer
/// feedback in quadrotor control"; coefficients as identified by Faessler, Franchi and
/// Scaramuzza 2018, RA-L 3(2), "Differential flatness of quadrotor dynamics subject to rotor
/// drag": mass-normalised d_x = 0.544, d_y = 0.386 1/s at hover): F = -k omega / omega_h (I -
/// b_z b_z^T) v_rel per rotor with k = m d / 4. Returns the force [N] (world frame).
Vec3 RotorDrag(double mass_normalised_coefficient, double mass, double omega_ratio,
               const Vec3& thrust_axis, const Vec3& air_relative_velocity);

}  // namespace fnmpc::sim
