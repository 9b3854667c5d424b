// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/sim/cell_list.hpp"
#include "fnmpc/sim/wake.hpp"
#include "fnmpc/sim/world_settings.hpp"
#include "fnmpc/sim/world_vehicle.hpp"

/// The aerodynamic pass of sim::World (docs/simulator.md "Wind", "Downwash", "Reality"):
/// per rotor point the air of the wind and of the other vehicles' wakes (steady jets, or
/// with reality.wake the advected wakes with their fluctuations), quadratic drag on it and,
/// with reality.rotor_aerodynamics, the rotor's thrust in its actual inflow, ground effect
/// and rotor drag. One pass for the ideal and the reality plant.
namespace fnmpc::sim::detail {

class AeroPass {
 public:
  /// Allocates the wake histories and fluctuations (reality.wake) for `n` vehicles.
  AeroPass(const WorldConfig& config, int n);

  /// Whether the pass acts at all (wind, downwash or rotor aerodynamics on).
  [[nodiscard]] bool active() const;
  /// Whether the wakes keep a history (reality.wake): Record is needed each step.
  [[nodiscard]] bool records_wakes() const { return !wakes_.empty(); }

  /// Once per step before the per-vehicle calls: which wakes can reach each vehicle
  /// (WorldConfig::aero_culling; every other vehicle's when off). A wake is dropped for a
  /// vehicle only when no point of that vehicle (rotors and centre of mass) lies inside the
  /// jet's extent (WakeHorizontalReach) from any rotor state the wake is evaluated from: its
  /// contribution there is exactly zero, so culling changes no result. The candidates come
  /// from a cell list of this step's positions.
  void Prepare(const std::vector<Kinematics>& kin);

  /// The wakes vehicle i evaluates this step (ascending vehicle indices).
  [[nodiscard]] const std::vector<int>& sources(int i) const { return sources_[i]; }

  /// Records vehicle i's rotor state at time t [s] for its advected wake.
  void Record(int i, double t, const Vec3& position, const Vec3& thrust_axis, double thrust);

  /// Advances the wake fluctuations seen by `observer` over one physics step (reality.wake
  /// with the downwash): each observer's own streams, any order of observers.
  void StepFluctuations(int observer, double t, const std::vector<Kinematics>& kin);

  /// Vehicle i's aerodynamic wrench (v.aero_force, v.aero_torque, world frame) at time t [s]
  /// in the uniform air `wind_air` [m/s] (zero when the wind is off); `total_thrust` holds
  /// every vehicle's rotor thrust [N] this step. Reads only the other vehicles' kinematics
  /// and thrust: any order of vehicles.
  void VehicleWrench(int i, double t, const Vec3& wind_air, const std::vector<Kinematics>& kin,
                     const std::vector<double>& total_thrust, Vehicle& v) const;

 private:
  /// Air velocity [m/s] of the other vehicles' wakes at `point` as seen by vehicle i: the
  /// steady jets, or with reality.wake the advected mean plus the fluctuation.
  [[nodiscard]] Vec3 WakeAir(int i, double t, const Vec3& point, const std::vector<Kinematics>& kin,
                             const std::vector<double>& total_thrust) const;

  const WorldConfig& config_;
  int n_ = 0;
  std::vector<double> arm_;                // each vehicle's arm length (rotor reach) [m]
  std::vector<std::vector<int>> sources_;  // per vehicle, the wakes it evaluates this step
  CellList cells_;
  std::vector<Vec3> positions_;               // scratch
  std::vector<int> near_;                     // scratch
  std::vector<WakeHistory> wakes_;            // reality.wake: one per vehicle
  std::vector<WakeFluctuation> fluctuation_;  // reality.wake: [source * n + observer]
};

}  // namespace fnmpc::sim::detail
