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
  sub->add_option("file", *path, "vehicle YAML (docs/data-formats.md)")->required();
  registry.push_back({sub, [path] {
                        // LoadVehicleFile checks plausibility (config::CheckVehiclePlausible).
                        const auto p = config::LoadVehicleFile(*path);
                        const auto [v_lo, v_hi] = config::kPlausibleVoltageRange;
                        const double hover = p.mass * config::kPlausibleGravity / 4.0;
                        fmt::print(
                            "{}: ok (mass {} kg, hover throttle {:.3f} at {:.1f} V, {:.3f} at "
                            "{:.1f} V)\n",
                            *path, p.mass, p.throttle.Throttle(hover, v_lo), v_lo,
                            p.throttle.Throttle(hover, v_hi), v_hi);
                        return 0;
                      }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app
