// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <utility>

#include "fnmpc/config/yaml_reader.hpp"
#include "fnmpc/model/vehicle_params.hpp"

namespace fnmpc::config {

/// Battery voltage range a vehicle file must be plausible over [V]: the simulated 4S LiPo's
/// empty and full open-circuit voltages (sim::BatterySettings defaults).
inline constexpr std::pair<double, double> kPlausibleVoltageRange{13.2, 16.8};
/// Full throttle must give at least this multiple of the hover thrust at every voltage.
inline constexpr double kThrustMargin = 1.2;
inline constexpr double kPlausibleGravity = 9.81;  ///< [m/s^2]

/// Throws ConfigError at key 'throttle_polynomial' of `map` (the vehicle file) unless the hover
/// throttle (thrust m g / 4 per rotor) lies in (0, 1) and kThrustMargin times the hover thrust
/// needs less than full throttle, at every voltage of kPlausibleVoltageRange.
void CheckVehiclePlausible(const model::VehicleParams& params, const YamlMap& map);

/// Reads a vehicle file (format: docs/data-formats.md, "Vehicle file"). Every key of
/// the format is required except `bias`; unknown, missing or mistyped keys and
/// non-physical values throw ConfigError naming file, line and key.
model::VehicleParams LoadVehicleFile(const std::string& path);
model::VehicleParams ParseVehicle(YamlMap map);

/// Writes `params` in the same format (bias block only when has_bias). The file is
/// written to a temporary name and renamed, so nothing is half-written on failure.
void SaveVehicleFile(const model::VehicleParams& params, const std::string& path);

}  // namespace fnmpc::config
