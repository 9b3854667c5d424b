// SPDX-License-Identifier: BSD-3-Clause
// The identification pipeline of `fnmpc sysid` (docs/sysid.md): propulsion (thrust stand),
// inertia (bifilar pendulum), attitude model and autopilot PD gains, the model selection, each
// a stage that fails on its own. It takes loaded data and returns the vehicle, the report's
// stages, tables and summary: reading the campaign's files and writing the report stay with
// the caller (apps/fnmpc/sysid.cpp).
#pragma once

#include <array>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnmpc/model/vehicle_params.hpp"
#include "fnmpc/sysid/attitude_fit.hpp"
#include "fnmpc/sysid/propulsion.hpp"
#include "fnmpc/sysid/stage_report.hpp"

namespace fnmpc::sysid {

/// A data set of the campaign, or why it could not be loaded (the stage that needs it fails
/// with that reason).
template <class T>
struct Loaded {
  std::optional<T> data;
  std::string error;
  [[nodiscard]] const T& Get() const {
    if (!data) throw std::runtime_error(error);
    return *data;
  }
};

/// One pendulum swing: time [s] and angle [rad].
struct PendulumSwing {
  std::vector<double> t, angle;
};

/// The attitude steps: time [s], references and angles of roll, pitch, yaw [rad].
struct AttitudeSteps {
  std::vector<double> t;
  std::array<std::vector<double>, 3> ref, angle;
};

/// What the identification is given: the campaign's constants and its data sets.
struct IdentificationData {
  double mass = 0.0, arm_length = 0.0;              ///< [kg], [m]
  double wire_separation = 0.0, wire_length = 0.0;  ///< bifilar pendulum [m]
  Loaded<BenchData> bench;
  std::array<Loaded<PendulumSwing>, 3> pendulum;  ///< about x, y, z
  Loaded<AttitudeSteps> attitude_steps;
};

struct IdentificationSettings {
  AttitudeLoopSettings loop;
  std::string tau_convention = "auto";  ///< auto, lag or residence (docs/sysid.md)
  std::string attitude_steps_name;      ///< named in the gap warning
};

/// A table of the report: file name, header, columns.
struct ReportTable {
  std::string file;
  std::vector<std::string> header;
  std::vector<std::vector<double>> columns;
};

struct Identification {
  model::VehicleParams vehicle;       ///< what was identified (complete when every stage ran)
  std::vector<std::string> have;      ///< its top-level keys in the vehicle file
  nlohmann::json summary;             ///< summary.json's identification part
  std::vector<StageReport> stages;    ///< propulsion, inertia, attitude model, PD gains
  std::vector<ReportTable> tables;    ///< the fits beside the data, in the order made
  std::vector<std::string> warnings;  ///< summary.json's warnings
  std::vector<std::string> notices;   ///< lines for stderr (gaps, failed stages)
  PropulsionFit propulsion;
  std::array<FirstOrderFit, 3> first_order;
  std::array<PdFit, 3> pd;
};

/// Runs the stages on `data`. Never throws for a stage's failure: the stage says why.
Identification IdentifyVehicle(const IdentificationData& data,
                               const IdentificationSettings& settings);

}  // namespace fnmpc::sysid
