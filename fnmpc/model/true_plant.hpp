// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>

#include "fnmpc/core/serialize.hpp"
#include "fnmpc/model/vehicle_params.hpp"

/// The true plant of a simulated vehicle: the controller keeps its vehicle file,
/// the simulator flies parameters drawn around it. Pure functions, no files (the scenario
/// parser reads the spread, `fnmpc run` writes the drawn plant). See docs/simulator.md,
/// "Reality", for each spread's justification.
namespace fnmpc::model {

/// Spread of the true plant around the nominal (identified) vehicle file. Relative spreads
/// are standard deviations of a normal factor (1 + sd N(0, 1)), cut at +-3 sd so that a
/// draw stays physical; the attitude biases are uniform in magnitude with a random sign.
struct PlantSpread {
  double mass = 0.02;                 ///< [-] battery and payload differences between flights
  double inertia = 0.10;              ///< [-] per axis, bifilar-pendulum / CAD uncertainty
  double thrust_constant = 0.05;      ///< [-] T_k, propeller-to-propeller and wear
  double torque_constant = 0.05;      ///< [-] T_q
  double motor_time_constant = 0.20;  ///< [-] ESC/motor lag
  double thrust_scale = 0.03;         ///< [-] sd of the throttle->thrust scale error
  /// [-] relative error of the voltage dependence of the throttle map: the plant's map is
  /// the nominal one evaluated at V_ref + (1 + e) (V - V_ref).
  double voltage_dependence = 0.10;
  double voltage_reference = 15.0;  ///< V_ref [V], middle of the 4S range
  double attitude_bias_min = 0.5 * 3.141592653589793 / 180.0;  ///< [rad] level calibration
  double attitude_bias_max = 2.0 * 3.141592653589793 / 180.0;  ///< [rad]
  double attitude_gains = 0.10;  ///< [-] autopilot K_p and K_d per axis

  /// Every field with its key (scenario block `reality.plant`), accepted values and meaning.
  /// A relative spread stays below 1/3: a 3-sd draw must not reach zero.
  template <class Archive>
  void Serialize(Archive* a) {
    const Limit spread = NonNegative().Below(1.0 / 3.0, "");
    a->Visit("mass", &mass, spread, "relative sd: mass factor 1 + sd N(0,1) (cut at ±3 sd)");
    a->Visit("inertia", &inertia, spread,
             "relative sd, per axis; a draw no rigid body has (triangle inequality) is drawn "
             "again (docs/simulator.md)");
    a->Visit("thrust_constant", &thrust_constant, spread, "relative sd of T_k");
    a->Visit("torque_constant", &torque_constant, spread, "relative sd of T_q");
    a->Visit("motor_time_constant", &motor_time_constant, spread,
             "relative sd around the simulator's 0.02 s");
    a->Visit("thrust_scale", &thrust_scale, spread,
             "relative sd of the throttle→thrust scale error (the plant's `bias.thrust`)");
    a->Visit("voltage_dependence", &voltage_dependence, spread,
             "relative sd of the error e of the throttle map's voltage dependence: P(f, V_ref + "
             "(1+e)(V − V_ref))");
    a->Visit("voltage_reference", &voltage_reference, Positive(), "[V] V_ref");
    a->VisitRange("attitude_bias_deg", &attitude_bias_min, &attitude_bias_max,
                  RangeLimit{true, 10.0, "deg", 3.141592653589793 / 180.0},
                  "[deg] roll and pitch level-calibration biases, uniform magnitude, random sign");
    a->Visit("attitude_gains", &attitude_gains, spread,
             "relative sd of the autopilot K_p, K_d per axis");
  }

  /// Throws std::invalid_argument naming the field on a negative or non-finite spread, a
  /// relative spread >= 1/3 (a 3-sd draw would reach zero) or bias_min > bias_max.
  void Validate() const;
};

/// A plant draw that cannot give a physical vehicle; `key` names the spread's field
/// (`reality.plant.<key>`) so that the caller can point at the scenario's line.
class PlantDrawError : public std::invalid_argument {
 public:
  PlantDrawError(std::string key, const std::string& what)
      : std::invalid_argument(what), key_(std::move(key)) {}
  [[nodiscard]] const std::string& key() const { return key_; }

 private:
  std::string key_;
};

/// Draws of the inertia factors before DrawTruePlant gives up on a realisable body.
inline constexpr int kInertiaRedraws = 1000;

/// One vehicle's true plant: its parameters (vehicle-file format, the calibration `bias`
/// block holding the true attitude biases and thrust scale) and its motor time constant.
struct TruePlant {
  VehicleParams params;
  double motor_time_constant = 0.02;  ///< [s]
};

/// Draws the true plant of vehicle `vehicle` for `seed` around `nominal` (deterministic in
/// (seed, vehicle), independent of the other vehicles). The nominal's own calibration bias
/// is not inherited: the plant's bias block is the drawn truth. The inertia is a physically
/// realisable body (UnrealisableInertia): a draw that is not has its three inertia factors
/// drawn again from a generator of their own (the other draws stay the seed's); after
/// kInertiaRedraws PlantDrawError("inertia").
TruePlant DrawTruePlant(const VehicleParams& nominal, double nominal_motor_time_constant,
                        const PlantSpread& spread, std::uint64_t seed, int vehicle);

/// The throttle map whose voltage dependence is scaled by (1 + error) about `v_ref`:
/// P'(f, V) = P(f, v_ref + (1 + error) (V - v_ref)), re-expanded into coefficients.
ThrottlePolynomial ScaleVoltageDependence(const ThrottlePolynomial& p, double error, double v_ref);

}  // namespace fnmpc::model
