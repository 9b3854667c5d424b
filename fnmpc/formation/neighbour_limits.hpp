// SPDX-License-Identifier: BSD-3-Clause
#pragma once

namespace fnmpc::formation {

/// Most formation neighbours of one follower. The reduced OCP's size does not depend on the
/// count (the neighbours enter as their mean, see FollowerCore in nmpc_core.cpp);
/// the bound only sizes the controller's fixed per-step arrays (no allocation in flight).
inline constexpr int kMaxNeighbours = 8;

}  // namespace fnmpc::formation
