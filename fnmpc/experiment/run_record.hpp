// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/experiment/plan_link.hpp"
#include "fnmpc/formation/neighbour_limits.hpp"
#include "fnmpc/sim/world.hpp"

/// What the closed loop of `fnmpc run` records for the run's metrics (run_loop.cpp writes it,
/// run_metrics.cpp reads it).
namespace fnmpc::experiment {

/// What one vehicle did, accumulated at every control step.
struct VehicleRecord {
  std::vector<double> errors;         // follower: mean over neighbours of |dx_j - d_j|, own window
  std::vector<double> flight_errors;  // follower: the same from take-off to touchdown
  double max_altitude = -kInf;        // highest CoM height above the resting height [m]
  double envelope_time = kNaN;        // first time outside the flight envelope [s]
  std::string envelope_reason;
  std::vector<double> steady_errors;
  std::vector<std::vector<double>> nb_errors;  // per neighbour
  std::vector<std::vector<double>> nb_steady;
  std::vector<double> tracking;  // leader |p - p_ref|
  std::vector<double> solver_time, kkt, cost;
  long over_budget = 0, steps = 0, fallbacks = 0, guarded = 0, failures = 0;
  long reinitialisations = 0;
  long landing_site_shifts = 0;   // landing sites moved clear of a vehicle below
  long neighbour_departures = 0;  // neighbours dropped for leaving the formation (at the end)
  // Compensation::kWake: neighbour thrust estimates bounded (steps x neighbours), by
  // formation::ThrustBound (index 0 unused).
  std::array<long, 4> neighbour_thrust_bounded{};
  // Compensation::kObserver on: steps whose attitude offset estimate was cut at its bound,
  // and the last estimate of the NMPC phase (roll, pitch) [rad].
  long attitude_offset_bounded = 0;
  Vec<2> attitude_offset = Vec<2>::Constant(kNaN);
  double failsafe_time = kNaN;
  std::string failsafe_reason;
  double tie_loss_time = kNaN;  // follower landed for want of a tie to the leader [s]
  std::string tie_loss_reason;
  double first_step_time = kNaN;
  double touchdown_vz = kNaN, touchdown_time = kNaN;
  // Closest approach of any other vehicle (true CoM distance) and when, with whom.
  double min_separation = kInf, min_separation_time = kNaN;
  int min_separation_to = -1;
  // First ground contact outside take-off and landing (true CoM within kGroundContactHeight
  // of its resting height in the NMPC phase, or in the take-off after the vehicle had lifted
  // off): time, true vertical speed (the lower of this control step's and the one before) and
  // phase.
  double ground_strike_time = kNaN, ground_strike_vz = kNaN;
  std::string ground_strike_phase;
  double previous_vz = 0.0;   // true v_z at the previous control step [m/s]
  double max_distance = 0.0;  // largest horizontal distance from its start [m]
  double max_thrust_jump_at_switch = kNaN;
  bool motors_off = false;
  // Per control step in the formation window (followers): time, steady flag, errors to the
  // neighbours and the neighbours in the cost (fault report: errors after a kill).
  struct Sample {
    double t;
    bool steady;
    std::array<double, formation::kMaxNeighbours> err;
    int active;
  };
  std::vector<Sample> samples;
};

/// What happened to a vehicle downed by a fault (first ground contact after the fault).
struct DownedLog {
  double impact_time = kNaN, impact_vz = kNaN;
  Vec3 impact_position = Vec3::Constant(kNaN);
};

/// Height above its resting height [m] at which a vehicle's true CoM counts as on the
/// ground (the feet touch): touchdowns and ground strikes.
inline constexpr double kGroundContactHeight = 0.015;
/// A vehicle has lifted off once its CoM rose this far above its resting height [m]; ground
/// contact in the take-off phase after that is a strike.
inline constexpr double kLiftOffHeight = 0.1;

/// Closest approach of two vehicles (true CoM distance at the control steps).
struct PairApproach {
  double min_distance = kInf, min_time = kNaN;
  double first_collision_time = kNaN;  ///< first time below metrics.collision_distance [s]
};

/// Index of the pair (i, j), i < j, among n vehicles' pairs (row by row).
inline std::size_t PairIndex(int i, int j, int n) {
  return static_cast<std::size_t>(i) * static_cast<std::size_t>(n) -
         static_cast<std::size_t>(i) * static_cast<std::size_t>(i + 1) / 2 +
         static_cast<std::size_t>(j - i - 1);
}

/// The whole run.
struct RunRecord {
  double duration = 0.0;  ///< simulated time asked for [s]
  std::vector<VehicleRecord> vehicles;
  std::vector<DownedLog> downed;
  std::vector<char> controlled;  ///< the vehicle has a controller (not a hand-moved leader)
  std::vector<sim::TrueState> final_state;            ///< at the end of the loop
  std::vector<sim::AutopilotStatus> final_autopilot;  ///< at the end of the loop
  std::vector<std::int64_t> estimator_rejections;     ///< at the end, per controlled vehicle
  double min_separation = kInf;                       ///< true CoM distance of any two vehicles [m]
  double min_separation_time = kNaN;                  ///< when [s]
  int min_separation_pair[2] = {-1, -1};              ///< between these two
  std::vector<PairApproach> pairs;                    ///< per pair (PairIndex)
  long injected_failures = 0;  ///< forced solver fallbacks (faults.solver_failures)
  std::vector<long> dropped;   ///< per faults.sensor_dropouts window
  long measurements = 0, outliers = 0;
  bool link = false;          ///< cooperative mode: plans went over the simulated link
  LinkStatistics link_stats;  ///< its messages
  std::string stopped;        ///< why the loop ended early ("interrupted"), empty: it did not
  std::string sim_error;      ///< the simulator's instability report
};

}  // namespace fnmpc::experiment
