// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string_view>
#include <vector>

#include "fnmpc/core/types.hpp"

namespace fnmpc::formation {

/// The shapes a formation can be generated in (docs/scenarios.md "formation").
enum class FormationShape { kWedge, kLine, kGrid, kCircle };

/// "wedge", "line", "grid", "circle"; false when `name` is none of them.
bool ParseFormationShape(std::string_view name, FormationShape* shape);

/// What a generated formation looks like. Vehicle 0 is the leader.
struct FormationSpec {
  FormationShape shape = FormationShape::kWedge;
  int count = 3;               ///< vehicles, the leader included (>= 2)
  double spacing = 2.5;        ///< distance between rows and between vehicles in a row [m]
  int ties = 2;                ///< formation ties per follower (1 to kMaxNeighbours)
  int columns = 0;             ///< grid only: vehicles per row (0: ceil(sqrt(count)))
  Vec3 origin = Vec3::Zero();  ///< the leader's start (x, y; z 0: on the ground)
};

/// One formation tie: follower i keeps `desired` = p_neighbour - p_self.
struct FormationTie {
  int neighbour = 0;  ///< index into the generated vehicles
  Vec3 desired = Vec3::Zero();
};

struct FormationSlot {
  Vec3 start = Vec3::Zero();  ///< start position (z 0) [m]
  int depth = 0;              ///< graph depth: fewest ties from the leader (leader 0)
  std::vector<FormationTie> ties;
};

/// Graph depth of every vehicle: the fewest formation ties from `leader` (0), following
/// neighbours[i] (the vehicles i keeps offsets to); -1 when no chain of ties reaches it.
std::vector<int> TieDepths(const std::vector<std::vector<int>>& neighbours, int leader);

/// Places the vehicles of `spec` and ties them. The leader (slot 0) is at `origin`, the
/// formation extends behind it (-x), and slots are numbered front to back. Slots are ranked
/// (wedge and line: row; grid: row + column from the leader's corner; circle: leader 0, ring
/// 1). A follower's first tie is its nearest slot of a lower rank, so a chain of ties leads
/// to the leader; its further ties are its nearest slots of lower or equal rank, never one
/// behind it (equal distances: the lower slot first); with fewer candidates than `ties` it
/// gets as many as exist. The desired offsets are the start geometry. Throws
/// std::invalid_argument on a bad spec.
std::vector<FormationSlot> GenerateFormation(const FormationSpec& spec);

}  // namespace fnmpc::formation
