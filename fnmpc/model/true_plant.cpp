// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/model/true_plant.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace fnmpc::model {

namespace {

void RequireRelative(double v, const char* name) {
  if (!(v >= 0.0 && v < 1.0 / 3.0)) {
    throw std::invalid_argument(std::string("[PlantSpread] ") + name +
                                " must be in [0, 1/3), got " + std::to_string(v));
  }
}

}  // namespace

void PlantSpread::Validate() const {
  RequireRelative(mass, "mass");
  RequireRelative(inertia, "inertia");
  RequireRelative(thrust_constant, "thrust_constant");
  RequireRelative(torque_constant, "torque_constant");
  RequireRelative(motor_time_constant, "motor_time_constant");
  RequireRelative(thrust_scale, "thrust_scale");
  RequireRelative(voltage_dependence, "voltage_dependence");
  RequireRelative(attitude_gains, "attitude_gains");
  if (!(voltage_reference > 0.0) || !std::isfinite(voltage_reference)) {
    throw std::invalid_argument("[PlantSpread] voltage_reference must be > 0");
  }
  if (!(attitude_bias_min >= 0.0 && attitude_bias_max >= attitude_bias_min &&
        attitude_bias_max < 0.2)) {
    throw std::invalid_argument(
        "[PlantSpread] attitude_bias needs 0 <= min <= max < 0.2 rad, got " +
        std::to_string(attitude_bias_min) + " and " + std::to_string(attitude_bias_max));
  }
}

ThrottlePolynomial ScaleVoltageDependence(const ThrottlePolynomial& p, double error, double v_ref) {
  // V' = a V + b with a = 1 + error, b = v_ref (1 - a); (a V + b)^j = sum_k C(j,k) a^k V^k
  // b^(j-k).
  const double a = 1.0 + error;
  const double b = v_ref * (1.0 - a);
  static constexpr int kBinom[4][4] = {{1, 0, 0, 0}, {1, 1, 0, 0}, {1, 2, 1, 0}, {1, 3, 3, 1}};
  ThrottlePolynomial out;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      if (p.c(i, j) == 0.0) continue;
      for (int k = 0; k <= j; ++k) {
        out.c(i, k) += p.c(i, j) * kBinom[j][k] * std::pow(a, k) * std::pow(b, j - k);
      }
    }
  }
  return out;
}

TruePlant DrawTruePlant(const VehicleParams& nominal, double nominal_motor_time_constant,
                        const PlantSpread& s, std::uint64_t seed, int vehicle) {
  s.Validate();
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    static_cast<std::uint32_t>(vehicle), 0x91A47u};
  std::mt19937_64 rng(seq);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // Every draw happens in a fixed order whatever the spreads (so one spread set to zero does
  // not shift the others' draws).
  auto factor = [&](double sd) { return 1.0 + sd * std::clamp(normal(rng), -3.0, 3.0); };
  TruePlant t;
  VehicleParams& p = t.params;
  p = nominal;
  p.mass = nominal.mass * factor(s.mass);
  for (int a = 0; a < 3; ++a) p.inertia[a] = nominal.inertia[a] * factor(s.inertia);
  if (!UnrealisableInertia(p.inertia).empty()) {
    // Independent per-axis factors can break the triangle inequality (Izz > Ixx + Iyy): no
    // rigid body, and MuJoCo refuses it. The three factors are drawn again, from a generator
    // of their own so that every other draw stays the seed's, until the body is realisable:
    // the inertia is drawn from the spread conditioned on a realisable body. A spread whose
    // draws almost never are (kInertiaRedraws in a row) is an error, never clamped.
    std::seed_seq redraw_seq{static_cast<std::uint32_t>(seed),
                             static_cast<std::uint32_t>(seed >> 32),
                             static_cast<std::uint32_t>(vehicle), 0x1E27Au};
    std::mt19937_64 redraw(redraw_seq);
    std::normal_distribution<double> redraw_normal(0.0, 1.0);  // (a distribution caches draws)
    for (int k = 0; k < kInertiaRedraws && !UnrealisableInertia(p.inertia).empty(); ++k) {
      for (int a = 0; a < 3; ++a) {
        p.inertia[a] =
            nominal.inertia[a] * (1.0 + s.inertia * std::clamp(redraw_normal(redraw), -3.0, 3.0));
      }
    }
    if (!UnrealisableInertia(p.inertia).empty()) {
      throw PlantDrawError(
          "inertia", "[PlantSpread] inertia: a spread of " + std::to_string(s.inertia) +
                         " around [" + std::to_string(nominal.inertia[0]) + ", " +
                         std::to_string(nominal.inertia[1]) + ", " +
                         std::to_string(nominal.inertia[2]) + "] kg m^2 drew no physically " +
                         "realisable body in " + std::to_string(kInertiaRedraws) + " draws (" +
                         UnrealisableInertia(p.inertia) + "); use a smaller spread");
    }
  }
  p.thrust_constant = nominal.thrust_constant * factor(s.thrust_constant);
  p.torque_constant = nominal.torque_constant * factor(s.torque_constant);
  t.motor_time_constant = nominal_motor_time_constant * factor(s.motor_time_constant);
  p.bias = CalibrationBias{};
  p.has_bias = true;
  p.bias.thrust_scale = factor(s.thrust_scale);
  p.throttle = ScaleVoltageDependence(nominal.throttle,
                                      s.voltage_dependence * std::clamp(normal(rng), -3.0, 3.0),
                                      s.voltage_reference);
  for (double* bias : {&p.bias.roll, &p.bias.pitch}) {
    const double magnitude =
        s.attitude_bias_min + (s.attitude_bias_max - s.attitude_bias_min) * uniform(rng);
    *bias = uniform(rng) < 0.5 ? -magnitude : magnitude;
  }
  for (int a = 0; a < 3; ++a) {
    p.attitude_kp[a] = nominal.attitude_kp[a] * factor(s.attitude_gains);
    p.attitude_kd[a] = nominal.attitude_kd[a] * factor(s.attitude_gains);
  }
  p.Validate();
  return t;
}

}  // namespace fnmpc::model
