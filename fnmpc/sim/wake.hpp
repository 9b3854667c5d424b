// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/sim/downwash.hpp"

/// Advected, fluctuating rotor wake (docs/simulator.md "Wakes"): the mean
/// velocity is the round turbulent jet of DownwashVelocity, evaluated for the state the
/// upper vehicle had when the air now at the point left its rotors; turbulent fluctuations
/// scale with the local centreline velocity. No allocation after construction.
namespace fnmpc::sim {

/// Turbulence of the wake: intensities on the jet axis relative to the centreline velocity
/// (self-similar round jet: u'/U_c ~ 0.25 axially, v'/U_c ~ 0.20 radially; Wygnanski and
/// Fiedler 1969, J. Fluid Mech. 38; Hussein, Capp and George 1994, J. Fluid Mech. 258), their
/// radial decay, and the integral length scale relative to the half width (L_11 ~ 0.4
/// r_half on the axis; Wygnanski and Fiedler 1969).
struct WakeTurbulenceSettings {
  double axial_intensity = 0.25;      ///< u'_rms / U_c on the axis [-]
  double radial_intensity = 0.20;     ///< v'_rms / U_c on the axis [-]
  double intensity_half_width = 1.6;  ///< rms halves at this many jet half widths [-]
  double integral_length = 0.4;       ///< L / r_half [-]
  double history = 4.0;               ///< wake memory [s]
  double sample_period = 0.01;        ///< the upper vehicle's state is kept this often [s]

  void Validate() const;
};

/// Time to travel the distance `s` [m] down the jet axis at the centreline velocity
/// U_c(s) of DownwashVelocity (capped near the rotors) for total thrust `thrust` [N]:
/// t = int_0^s ds' / U_c(s') in closed form.
double WakeTravelTime(const DownwashSettings& settings, double thrust, double s);

/// Centreline velocity U_c(s) [m/s] and half width r_half(s) [m] of the jet.
double WakeCentrelineVelocity(const DownwashSettings& settings, double thrust, double s);
double WakeHalfWidth(const DownwashSettings& settings, double s);

/// Where a wake's sources were: the bounding box of the rotor states a wake is evaluated from
/// and the smallest vertical component of their thrust axes (the largest tilt).
struct WakeSources {
  Vec3 lo = Vec3::Constant(kInf);
  Vec3 hi = Vec3::Constant(-kInf);
  double min_axis_z = 1.0;
  /// Adds one source state.
  void Add(const Vec3& position, const Vec3& thrust_axis);
};

/// Horizontal reach [m] of the wakes of `sources` at points no lower than `lowest_z` [m]: a
/// point farther (horizontally) from the sources' box can feel none of them. From the jet's own
/// extent (DownwashVelocity): zero above the rotor plane and beyond cutoff_half_widths half
/// widths r_half(s) = wake_radius + spreading_rate s; the deepest downstream distance s that
/// still reaches z >= lowest_z under a tilt theta (cos theta >= min_axis_z) is D = (depth + c
/// r0 sin theta) / (cos theta - c S sin theta) with depth = top of the box - lowest_z, and the
/// reach D sin theta + c (r0 + S D). Infinite when the tilt is too large for a bound
/// (cos theta <= c S sin theta, beyond about 74 degrees with the defaults).
double WakeHorizontalReach(const DownwashSettings& settings, const WakeSources& sources,
                           double lowest_z);

/// Highest z [m] any point of the wakes of `sources` reaches: the jet acts below its rotor
/// plane only, so at most cutoff_half_widths wake_radius sin theta above the highest source.
double WakeTop(const DownwashSettings& settings, const WakeSources& sources);

/// History of one vehicle's rotor state and the wake it leaves.
class WakeHistory {
 public:
  WakeHistory(const DownwashSettings& downwash, const WakeTurbulenceSettings& turbulence);
  /// Records the state at time t [s] (kept when a sample period has passed since the last).
  void Record(double t, const Vec3& position, const Vec3& thrust_axis, double thrust);
  /// Mean wake velocity [m/s] (world) at `point` at time t: the air there left the rotors
  /// tau earlier, with tau the travel time from the rotor state then (fixed point, two
  /// passes); that state's jet is evaluated. Also returns the local centreline velocity, half
  /// width and axis (for the fluctuations) through the pointers (0 when outside the wake).
  Vec3 MeanVelocity(double t, const Vec3& point, double* centreline = nullptr,
                    double* half_width = nullptr, Vec3* axis = nullptr,
                    double* radius = nullptr) const;
  /// The rotor states MeanVelocity can evaluate (every kept sample; empty before the first).
  [[nodiscard]] const WakeSources& sources() const { return sources_; }

 private:
  struct Sample {
    double t = -1e300;
    Vec3 position = Vec3::Zero();
    Vec3 axis = Vec3::UnitZ();
    double thrust = 0.0;
  };
  [[nodiscard]] const Sample& At(double t) const;
  DownwashSettings dw_;
  WakeTurbulenceSettings turb_;
  std::vector<Sample> ring_;
  int head_ = -1;  // newest
  int size_ = 0;
  WakeSources sources_;  // of the kept samples, renewed at each kept sample
};

/// Turbulent fluctuation of one vehicle's wake as seen by one other vehicle: a unit-variance
/// first-order Gauss-Markov 3-vector (axial, two radial) with the local Eulerian time scale
/// L / U_c, shared by the four rotors of the observing vehicle (coherent over its size,
/// which is below the integral scale once r_half > 0.5 m), scaled to the local intensities.
class WakeFluctuation {
 public:
  WakeFluctuation(const WakeTurbulenceSettings& settings, std::uint64_t seed, int source,
                  int observer);
  /// Advances by dt [s] with the local centreline velocity and half width (no change when
  /// outside the wake: centreline <= 0).
  void Step(double dt, double centreline, double half_width);
  /// Fluctuating velocity [m/s] at radius r from an axis with the local scales.
  [[nodiscard]] Vec3 Velocity(const Vec3& axis, double centreline, double half_width,
                              double radius) const;
  [[nodiscard]] const Vec3& state() const { return g_; }

 private:
  WakeTurbulenceSettings s_;
  Vec3 g_ = Vec3::Zero();
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace fnmpc::sim
