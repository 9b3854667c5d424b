// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/onboard/formation_print.hpp"

#include <fmt/format.h>

#include <map>

#include "fnmpc/formation/formation_shape.hpp"

namespace fnmpc::onboard {

std::vector<int> TieDepths(const config::ScenarioConfig& scenario) {
  std::vector<std::vector<int>> neighbours(scenario.vehicles.size());
  for (std::size_t i = 0; i < neighbours.size(); ++i)
    for (const config::ScenarioNeighbour& nb : scenario.vehicles[i].neighbours)
      neighbours[i].push_back(nb.index);
  return formation::TieDepths(neighbours, scenario.leader);
}

std::string VehiclesYaml(const config::ScenarioConfig& scenario) {
  const std::vector<int> depth = TieDepths(scenario);
  std::string out = "vehicles:\n";
  std::map<int, int> per_depth;
  for (std::size_t i = 0; i < scenario.vehicles.size(); ++i) {
    const config::ScenarioVehicle& v = scenario.vehicles[i];
    ++per_depth[depth[i]];
    out += fmt::format("  - {{name: {}, role: {}, start: [{}, {}]", v.name,
                       v.leader ? "leader" : "follower", v.start.x(), v.start.y());
    if (!v.leader) {
      out += fmt::format(", frame: {}, relative_position_bound: [{}, {}, {}], neighbours: [",
                         v.frame_control ? "c" : "m", v.relative_position_bound.x(),
                         v.relative_position_bound.y(), v.relative_position_bound.z());
      for (std::size_t j = 0; j < v.neighbours.size(); ++j) {
        const config::ScenarioNeighbour& nb = v.neighbours[j];
        out += fmt::format("{}{{vehicle: {}, desired: [{}, {}, {}]}}", j == 0 ? "" : ", ",
                           nb.vehicle, nb.desired.x(), nb.desired.y(), nb.desired.z());
      }
      out += "]";
    }
    out += fmt::format("}}  # depth {}\n", depth[i]);
  }
  out += fmt::format("# {} vehicles;", scenario.vehicles.size());
  for (const auto& [d, count] : per_depth) {
    out += d < 0 ? fmt::format(" {} not tied to the leader", count)
                 : fmt::format(" depth {}: {}", d, count);
  }
  out += "\n";
  return out;
}

}  // namespace fnmpc::onboard
