// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"

namespace fnmpc::onboard {

/// Graph depth of every vehicle: the fewest formation ties from the leader (0), -1 when no
/// chain of ties reaches the leader.
std::vector<int> TieDepths(const config::ScenarioConfig& scenario);

/// The scenario's vehicles as a `vehicles:` YAML list (one flow mapping per vehicle, its
/// graph depth as a comment), as `fnmpc run --dry-run` prints it: pasted into a scenario
/// instead of its `formation:` block it gives the same vehicles.
std::string VehiclesYaml(const config::ScenarioConfig& scenario);

}  // namespace fnmpc::onboard
