// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc check-vehicle FILE`: validates a vehicle file and prints what it holds.
#include <fmt/core.h>

#include <memory>

#include "apps/fnmpc/commands.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"

namespace fnmpc::app {
namespace {

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto path = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand("check-vehicle", "Validate a vehicle YAML file and print it");
  sub->add_option("file", *path, "vehicle YAML (shared/data-formats.md)")->required();
  registry.push_back({sub, [path] {
                        const auto p = config::LoadVehicleFile(*path);
                        fmt::print("{}: ok (mass {} kg, hover throttle at 16.0 V: {:.3f})\n", *path,
                                   p.mass, p.throttle.Throttle(p.mass * 9.81 / 4.0, 16.0));
                        return 0;
                      }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app
