// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"

/// Pure aerodynamic models of the simulator (no MuJoCo): the wake of a hovering quadrotor
/// as a self-similar round turbulent jet, and quadratic drag. See docs/simulator.md.
namespace fnmpc::sim {

/// Settings of the downwash (rotor wake) model: the wake of a vehicle with total thrust T
/// is a self-similar round turbulent jet along -b_z (b_z = body z axis of the upper
/// vehicle) that carries the momentum flux T. At the downstream distance s the half width is
/// r_half(s) = wake_radius + S s (a virtual origin wake_radius / S above the rotors), the
/// radial profile is Gaussian U = U_c exp(-ln2 (r / r_half)^2), and momentum conservation
/// (rho U_c^2 pi r_half^2 / (2 ln2) = T) gives U_c(s) = v_h sqrt(4 ln2 A / pi) / r_half(s)
/// with v_h = sqrt(T / (2 rho A)) and A = 4 pi R^2; U_c is capped at
/// exit_velocity_factor * v_h. Zero beyond cutoff_half_widths * r_half and above the rotors.
struct DownwashSettings {
  bool enabled = false;               ///< switch for the scenario
  double air_density = 1.225;         ///< rho [kg/m^3]
  double rotor_radius = 0.127;        ///< R, one propeller [m] (10 inch)
  double wake_radius = 0.3;           ///< half width of the wake at the rotor plane [m]
  double spreading_rate = 0.094;      ///< S [-], d r_half / d s (Pope 2000, ch. 5)
  double exit_velocity_factor = 2.0;  ///< cap of U_c / v_h [-] (momentum theory far wake)
  double cutoff_half_widths = 3.0;    ///< radial cut-off [half widths]

  /// Throws std::invalid_argument on non-physical values.
  void Validate() const;
};

/// Air velocity [m/s] (world frame) induced at `point` [m] by the wake of a vehicle at
/// `position` [m] whose thrust axis (body z in the world frame, unit) is `thrust_axis` and
/// whose total rotor thrust is `thrust` [N]. Zero above the rotor plane (s <= 0).
Vec3 DownwashVelocity(const DownwashSettings& settings, const Vec3& position,
                      const Vec3& thrust_axis, double thrust, const Vec3& point);

/// Hover induced velocity v_h = sqrt(T / (2 rho A)) [m/s] for total thrust T [N].
double HoverInducedVelocity(const DownwashSettings& settings, double thrust);

/// Quadratic drag [N] (world frame) on a body with rotation R (body to world), per-axis
/// body drag coefficients c [N s^2/m^2] and air velocity relative to the body v_rel [m/s]:
/// F = R diag(c) R^T v_rel |v_rel|.
Vec3 QuadraticDrag(const Mat3& rotation, const Vec3& drag_coefficient, const Vec3& v_rel);

}  // namespace fnmpc::sim
