// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"

namespace fnmpc::formation {

/// Diagonal NMPC weights of the controllers (the benchmark spec's values by default; the
/// scenario's `controller.weights.leader` / `.follower` map onto this struct). Leader rows:
/// position, velocity; follower rows: relative position and relative velocity per neighbour.
struct NmpcWeights {
  Vec3 position{20, 20, 30};     ///< leader p - p_ref, follower dx_j - d_j [1/m^2]
  Vec3 velocity{2, 2, 2};        ///< leader v - v_ref, follower v_j - v [s^2/m^2]
  double attitude = 1.0;         ///< roll and pitch [1/rad^2]
  double thrust = 0.05;          ///< T - m g [1/N^2]
  double attitude_ref = 5.0;     ///< roll and pitch references [1/rad^2]
  double terminal_factor = 5.0;  ///< terminal weights = factor * stage weights
  /// Input-rate cost of the reference work: change of the thrust [1/N^2] and of the roll
  /// and pitch references [1/rad^2] between consecutive stages and from the command last
  /// applied to the first stage. 0 switches a term off.
  double thrust_rate = 0.0;
  double attitude_ref_rate = 0.0;
  /// Collision avoidance: weight of the one-sided penalty min(0, |c_o - p| - r_min)^2
  /// [1/m^2] (r_min: SafetyConfig::collision_radius). Stage and terminal.
  double collision = 1000.0;
};

}  // namespace fnmpc::formation
