// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"

namespace fnmpc::ocp {

/// Diagonal NMPC weights of the quadrotor problems: the benchmark spec's values by default (the
/// benchmark flies these defaults), the controllers' by role (the scenario's
/// `controller.weights.leader` / `.follower` map onto this struct through Serialize, which
/// documents each field). fnmpc/ocp/quadrotor_ocp.hpp maps them onto the problems' residual
/// rows. Leader rows: position, velocity; follower rows: relative position and relative
/// velocity per neighbour.
struct NmpcWeights {
  Vec3 position{20, 20, 30};
  Vec3 velocity{2, 2, 2};
  double attitude = 1.0;
  double thrust = 0.05;
  double attitude_ref = 5.0;
  double terminal_factor = 5.0;
  double thrust_rate = 0.0;
  double attitude_ref_rate = 0.0;
  double collision = 1000.0;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("position", &position, NonNegativeEntries(),
             "[1/m²] leader p − p_ref; follower dx_j − d_j");
    a->Visit("velocity", &velocity, NonNegativeEntries(),
             "[s²/m²] leader v − v_ref; follower v_j − v");
    a->Visit("attitude", &attitude, NonNegative(), "[1/rad²] roll and pitch");
    a->Visit("thrust", &thrust, Positive(), "[1/N²] T − m g");
    a->Visit("attitude_ref", &attitude_ref, Positive(), "[1/rad²] roll and pitch references");
    a->Visit("terminal_factor", &terminal_factor, NonNegative(),
             "terminal weights = factor × stage weights");
    a->Visit("thrust_rate", &thrust_rate, NonNegative(),
             "[1/N²] input-rate cost of the reference work: change of the thrust between "
             "consecutive stages and from the command last applied to the first stage; 0: off "
             "(docs/safety.md)");
    a->Visit("attitude_ref_rate", &attitude_ref_rate, NonNegative(),
             "[1/rad²] the same for the roll and pitch references; 0: off");
    a->Visit("collision", &collision, NonNegative(),
             "[1/m²] collision avoidance: weight of the one-sided penalty min(0, |c_o − p| − "
             "r_min)² (r_min: `safety.collision_radius`), stage and terminal");
  }
};

}  // namespace fnmpc::ocp
