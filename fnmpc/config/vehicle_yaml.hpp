// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

#include "fnmpc/config/yaml_reader.hpp"
#include "fnmpc/model/vehicle_params.hpp"

namespace fnmpc::config {

/// Reads a vehicle file (format: shared/data-formats.md, "Vehicle file"). Every key of
/// the format is required except `bias`; unknown, missing or mistyped keys and
/// non-physical values throw ConfigError naming file, line and key.
model::VehicleParams LoadVehicleFile(const std::string& path);
model::VehicleParams ParseVehicle(YamlMap map);

/// Writes `params` in the same format (bias block only when has_bias). The file is
/// written to a temporary name and renamed, so nothing is half-written on failure.
void SaveVehicleFile(const model::VehicleParams& params, const std::string& path);

}  // namespace fnmpc::config
