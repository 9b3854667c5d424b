// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>
#include <cmath>

#include "fnmpc/core/types.hpp"
#include "fnmpc/model/vehicle_params.hpp"

/// The controller's model of a neighbour's rotor wake (compensation level `wake`,
/// docs/safety.md "The controllers' OCPs"): the vertical acceleration a vehicle feels at a
/// relative position below a neighbour of known thrust, smooth and with its analytic gradient,
/// for the follower's prediction. No dependency on the simulator: the same published models the
/// simulator uses (docs/simulator.md "Aerodynamic interaction" and "Rotor aerodynamics"),
/// re-derived here in a smooth form.
namespace fnmpc::model {

/// Constants of the wake model. Jet: round turbulent jet of momentum flux T along the
/// neighbour's thrust axis (Pope, Turbulent Flows, 2000, ch. 5): half width r_half(s) = r_0 +
/// S s, Gaussian radial profile exp(-ln2 (r / r_half)^2), centreline velocity from the momentum
/// balance U_c = v_h sqrt(4 ln2 A / pi) / r_half with v_h = sqrt(T / (2 rho A)), A = 4 pi R^2,
/// capped at exit_velocity_factor v_h (momentum theory). Thrust loss in the axial inflow U:
/// combined blade-element momentum theory of a uniform-pitch rotor (Leishman, Principles of
/// Helicopter Aerodynamics, 2nd ed., 2006, ch. 2-3) at the vehicle's hover rotor speed. Body
/// drag: quadratic, c_z U^2. Every value is the simulator's default (DownwashSettings,
/// RotorBlade, WorldConfig::drag_coefficient), none is fitted to a result; only
/// `onset_width` is new: the smoothing length of the rotor plane.
struct WakeModelSettings {
  double air_density = 1.225;         ///< rho [kg/m^3]
  double rotor_radius = 0.127;        ///< R, one propeller [m]
  double wake_radius = 0.3;           ///< r_0, half width at the rotor plane [m]
  double spreading_rate = 0.094;      ///< S [-] (Pope 2000)
  double exit_velocity_factor = 2.0;  ///< cap of U_c / v_h [-]
  double solidity = 0.10;             ///< sigma of the follower's blades [-]
  double lift_slope = 5.73;           ///< a [1/rad]
  double vertical_drag = 0.05;        ///< c_z, body z quadratic drag [N s^2/m^2]
  /// Width of the smooth onset at the neighbour's rotor plane [m]: the simulator's wake starts
  /// with a step there; here a logistic step (and a softplus distance) over this length, well
  /// below the vehicle's size, so the model is differentiable everywhere.
  double onset_width = 0.05;
};

/// Wake of one neighbour as the follower's controller predicts it. The neighbour's thrust
/// axis is taken vertical (its attitude is not estimated; tilts of a few degrees move the
/// wake by a few centimetres per metre below) and the follower's rotors at its hover speed
/// (the loss at another rotor speed differs; the disturbance observer absorbs it). Smooth
/// versions of the simulator's hard limits: the rotor-plane step becomes a logistic onset,
/// the cap a smooth minimum ((1 + (h_cap / h)^8)^(-1/8)), and the 3-half-width cut-off is
/// dropped (the Gaussian is 0.2 % there; only what is below double precision, under 1e-16 of
/// the jet's velocity, is exactly 0: a neighbour beside or below). The follower's four rotors at
/// the arm length a average the profile: approximated by a Gaussian of half width sqrt(r_half^2 +
/// ln2 a^2) and amplitude r_half^2 / (r_half^2 + ln2 a^2) (the profile convolved with the rotor
/// ring's spread, a^2 / 2 per axis). No allocation; no NaN for any finite input (r = 0, far away,
/// thrust 0).
class WakeForceModel {
 public:
  WakeForceModel() : WakeForceModel(VehicleParams{}) {}
  /// `follower`: the vehicle that feels the wake (mass, thrust constant, arm length).
  explicit WakeForceModel(const VehicleParams& follower, const WakeModelSettings& s = {})
      : s_(s), mass_(follower.mass) {
    const double jet_area = 4.0 * M_PI * s.rotor_radius * s.rotor_radius;
    inv_2_rho_a_ = 1.0 / (2.0 * s.air_density * jet_area);
    k_per_vh_ = std::sqrt(4.0 * M_LN2 * jet_area / M_PI);
    h_cap_ = k_per_vh_ / s.exit_velocity_factor;
    ring_ = M_LN2 * follower.arm_length * follower.arm_length;
    // Hover operating point of one rotor: T0 = m g / 4 = T_k rpm^2.
    const double t0 = mass_ * kGravity / 4.0;
    const double omega = std::sqrt(t0 / follower.thrust_constant) * 2.0 * M_PI / 60.0;
    tip_ = omega * s.rotor_radius;
    ct0_ = t0 / (s.air_density * M_PI * s.rotor_radius * s.rotor_radius * tip_ * tip_);
    sa_ = s.solidity * s.lift_slope;
    theta_ = 3.0 * (2.0 * ct0_ / sa_ + 0.5 * std::sqrt(ct0_ / 2.0));
  }

  [[nodiscard]] const WakeModelSettings& settings() const { return s_; }

  /// Thrust of a rotor at hover speed in the axial inflow u [m/s] (down through the disc)
  /// relative to its static thrust, and d ratio / d u. Valid below the inflow of zero thrust
  /// (about 10 m/s for the shipped vehicle; the jet's velocity stays below K / r_0).
  double ThrustRatio(double u, double* d_du = nullptr) const {
    const double lambda_c = u / tip_;
    const double b = sa_ / 4.0 - 2.0 * lambda_c;
    const double root = std::sqrt(b * b + 4.0 * sa_ * theta_ / 3.0);
    const double lambda = (-b + root) / 4.0;
    if (d_du != nullptr) *d_du = -(sa_ / 4.0) * 0.5 * (1.0 - b / root) / (tip_ * ct0_);
    return 0.5 * sa_ * (theta_ / 3.0 - 0.5 * lambda) / ct0_;
  }

  /// Downward wake velocity [m/s] averaged over the follower's rotors at r = p_follower -
  /// p_neighbour [m] (world) for the neighbour's thrust [N], and its gradient in r.
  double Velocity(const Vec3& r, double thrust, Vec3* grad = nullptr) const {
    const double eps = s_.onset_width;
    const double s = -r.z();
    const double z = s / eps;
    const double rho2 = r.x() * r.x() + r.y() * r.y();
    if (Negligible(z, rho2)) {
      if (grad != nullptr) grad->setZero();
      return 0.0;
    }
    // exp(-|z|) is the logistic's exp(-z) for z >= 0 (the wake's side): one exponential there.
    const double e_abs = std::exp(-std::abs(z));
    const double onset = 1.0 / (1.0 + (z >= 0.0 ? e_abs : std::exp(-z)));  // logistic
    const double dist = eps * (std::max(z, 0.0) + std::log1p(e_abs));      // softplus
    const double h = s_.wake_radius + s_.spreading_rate * dist;
    const double k = std::sqrt(std::max(thrust, 0.0) * inv_2_rho_a_) * k_per_vh_;
    const double q2 = (h_cap_ / h) * (h_cap_ / h);
    const double q = q2 * q2 * q2 * q2;                                 // (h_cap / h)^8
    const double cap = 1.0 / std::sqrt(std::sqrt(std::sqrt(1.0 + q)));  // (1 + q)^(-1/8)
    const double uc = k / h * cap;
    const double he2 = h * h + ring_;
    const double amp = h * h / he2;
    const double gauss = std::exp(-M_LN2 * rho2 / he2);
    const double u = onset * uc * amp * gauss;
    if (grad != nullptr) {
      const double duc_dh = -uc / (h * (1.0 + q));
      const double damp_dh = 2.0 * h * ring_ / (he2 * he2);
      const double dgauss_dh = gauss * M_LN2 * rho2 * 2.0 * h / (he2 * he2);
      const double du_dh =
          onset * (duc_dh * amp * gauss + uc * damp_dh * gauss + uc * amp * dgauss_dh);
      const double du_ds = onset * (1.0 - onset) / eps * uc * amp * gauss +
                           du_dh * s_.spreading_rate * onset;  // d dist / d s = onset
      const double du_drho2 = -onset * uc * amp * gauss * M_LN2 / he2;
      *grad = Vec3(2.0 * r.x() * du_drho2, 2.0 * r.y() * du_drho2, -du_ds);
    }
    return u;
  }

  /// Vertical acceleration [m/s^2] (negative: down) of the follower at r = p_follower -
  /// p_neighbour [m] in the wake of a neighbour of thrust `thrust` [N]: the hover thrust lost
  /// in the inflow, m g (1 - ratio(U)), plus the drag c_z U^2, over the follower's mass; and
  /// its gradient in r.
  double Acceleration(const Vec3& r, double thrust, Vec3* grad = nullptr) const {
    Vec3 du = Vec3::Zero();
    const double u = Velocity(r, thrust, grad != nullptr ? &du : nullptr);
    double dratio = 0.0;
    const double ratio = ThrustRatio(u, grad != nullptr ? &dratio : nullptr);
    const double a = -kGravity * (1.0 - ratio) - s_.vertical_drag * u * u / mass_;
    if (grad != nullptr) *grad = (kGravity * dratio - 2.0 * s_.vertical_drag * u / mass_) * du;
    return a;
  }

 private:
  /// Whether the wake at the onset coordinate z = s / onset_width and the squared axis
  /// distance rho2 is below double precision: the logistic onset or the Gaussian factor under
  /// exp(-kNegligibleExponent) = 1e-16, i.e. a velocity under 1e-16 times the jet's capped
  /// centreline velocity (at most exit_velocity_factor v_h, a few m/s). Velocity then returns
  /// exactly 0 without evaluating any transcendental function (a neighbour beside or below the
  /// follower, most slots of a formation). Uses an upper bound of the Gaussian's width (the
  /// softplus distance is at most eps (max(z, 0) + ln 2)), so it never drops more than that.
  [[nodiscard]] bool Negligible(double z, double rho2) const {
    if (z < -kNegligibleExponent) return true;
    const double h_max =
        s_.wake_radius + s_.spreading_rate * s_.onset_width * (std::max(z, 0.0) + M_LN2);
    return M_LN2 * rho2 > kNegligibleExponent * (h_max * h_max + ring_);
  }
  static constexpr double kNegligibleExponent = 36.84;  // exp(-36.84) = 1.0e-16

  WakeModelSettings s_;
  double mass_;
  double inv_2_rho_a_ = 0.0, k_per_vh_ = 0.0, h_cap_ = 0.0, ring_ = 0.0;
  double tip_ = 0.0, ct0_ = 0.0, sa_ = 0.0, theta_ = 0.0;
};

}  // namespace fnmpc::model
