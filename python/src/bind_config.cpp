// SPDX-License-Identifier: BSD-3-Clause
// Vehicle, sensor and scenario files (fnmpc/config). A config::ConfigError becomes the
// Python exception fnmpc.ConfigError (a ValueError) with the attributes file, line, column
// and key parsed from its "file:line:column: key 'a.b': what" message.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <string>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/config/sensors_yaml.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"
#include "python/src/bindings.hpp"

namespace py = pybind11;

namespace fnmpc::python {
namespace {

/// Sets file/line/column/key on the Python exception object `err` from `message`.
void AnnotateConfigError(const std::string& message, py::object& err) {
  const config::ErrorPlace place = config::ParseErrorPlace(message);
  py::object none = py::none();
  err.attr("file") = none;
  err.attr("line") = none;
  err.attr("column") = none;
  err.attr("key") = none;
  if (place.placed) {
    err.attr("file") = place.file;
    err.attr("line") = place.line;
    err.attr("column") = place.column;
  } else if (const auto colon = message.find(": "); colon != std::string::npos) {
    err.attr("file") = message.substr(0, colon);  // "path: cannot open file"
  }
  if (!place.key.empty()) err.attr("key") = place.key;
}

void BindVehicle(py::module_& m) {
  py::class_<model::VehicleParams>(m, "VehicleParams",
                                   "Physical and identified parameters of one vehicle "
                                   "(vehicle file, docs/vehicles.md). SI units.")
      .def(py::init<>())
      .def_readwrite("mass", &model::VehicleParams::mass, "[kg]")
      .def_readwrite("inertia", &model::VehicleParams::inertia,
                     "body principal inertia (3,) [kg m^2]")
      .def_readwrite("thrust_constant", &model::VehicleParams::thrust_constant, "[N / rpm^2]")
      .def_readwrite("torque_constant", &model::VehicleParams::torque_constant, "[N m / rpm^2]")
      .def_property(
          "throttle_coefficients",
          [](const model::VehicleParams& p) { return Eigen::Matrix4d(p.throttle.c); },
          [](model::VehicleParams& p, const Eigen::Matrix4d& c) { p.throttle.c = c; },
          "(4, 4) thrust-throttle-voltage polynomial, c[i, j] multiplies f^i V^j")
      .def_readwrite("attitude_time_constant", &model::VehicleParams::attitude_time_constant,
                     "tau (roll, pitch, yaw) [s]")
      .def_readwrite("attitude_gain", &model::VehicleParams::attitude_gain,
                     "k (roll, pitch, yaw) [-]")
      .def_readwrite("attitude_kp", &model::VehicleParams::attitude_kp)
      .def_readwrite("attitude_kd", &model::VehicleParams::attitude_kd)
      .def_readwrite("arm_length", &model::VehicleParams::arm_length, "[m]")
      .def("validate", &model::VehicleParams::Validate,
           "Raises ValueError naming the field on an inconsistent value.");
  m.def("load_vehicle", &config::LoadVehicleFile, py::arg("path"),
        "Reads a vehicle file (config/vehicles/*.yaml). Raises ConfigError with file, line "
        "and key on a bad file.");
  m.def("save_vehicle", &config::SaveVehicleFile, py::arg("params"), py::arg("path"),
        "Writes a vehicle file that load_vehicle reads back.");
}

void BindSensors(py::module_& m) {
  py::class_<SensorSpec>(m, "SensorSpec", "Rate, latency, noise and dropout of one sensor.")
      .def(py::init<>())
      .def_readwrite("enabled", &SensorSpec::enabled)
      .def_readwrite("rate_hz", &SensorSpec::rate_hz, "[Hz]")
      .def_readwrite("latency_s", &SensorSpec::latency_s, "[s]")
      .def_readwrite("dropout_probability", &SensorSpec::dropout_probability, "[0, 1)")
      .def_readwrite("noise", &SensorSpec::noise, "(3,) first noise channel (see sensors.hpp)")
      .def_readwrite("noise2", &SensorSpec::noise2, "(3,) second noise channel")
      .def_readwrite("range_noise_growth", &SensorSpec::range_noise_growth, "[1/m]")
      .def_readwrite("max_range", &SensorSpec::max_range, "[m]")
      .def_readwrite("field_of_view", &SensorSpec::field_of_view, "full cone angle [rad]");
  py::class_<SensorsConfig>(m, "SensorsConfig", "Every sensor of one vehicle (sensors file).")
      .def(py::init<>())
      .def_readwrite("mocap", &SensorsConfig::mocap)
      .def_readwrite("imu", &SensorsConfig::imu)
      .def_readwrite("optical_flow", &SensorsConfig::optical_flow)
      .def_readwrite("compass", &SensorsConfig::compass)
      .def_readwrite("battery", &SensorsConfig::battery)
      .def_readwrite("relative", &SensorsConfig::relative);
  m.def("load_sensors", &config::LoadSensorsFile, py::arg("path"),
        "Reads a sensors file (config/sensors/*.yaml). Raises ConfigError with file, line "
        "and key on a bad file.");
}

void BindScenario(py::module_& m) {
  using config::ScenarioConfig;
  using config::ScenarioVehicle;
  py::class_<ScenarioVehicle>(m, "ScenarioVehicle", "One vehicle of a scenario.")
      .def_readonly("name", &ScenarioVehicle::name)
      .def_readonly("leader", &ScenarioVehicle::leader)
      .def_readonly("start", &ScenarioVehicle::start, "start position (3,) [m]")
      .def_readonly("yaw", &ScenarioVehicle::yaw, "[rad]")
      .def_readonly("params", &ScenarioVehicle::params)
      .def_readonly("sensors", &ScenarioVehicle::sensors)
      .def_property_readonly(
          "neighbours",
          [](const ScenarioVehicle& v) {
            py::list out;
            for (const auto& n : v.neighbours) out.append(py::make_tuple(n.vehicle, n.desired));
            return out;
          },
          "follower: list of (neighbour name, desired offset (3,) [m])");
  py::class_<ScenarioConfig>(m, "Scenario",
                             "A formation scenario (docs/scenarios.md). Changes made here "
                             "apply to run() and World.from_scenario().")
      .def_readwrite("name", &ScenarioConfig::name)
      .def_readonly("description", &ScenarioConfig::description)
      .def_readonly("file", &ScenarioConfig::file, "path it was read from")
      .def_readwrite("duration", &ScenarioConfig::duration, "simulated time [s]")
      .def_readwrite("seed", &ScenarioConfig::seed)
      .def_readwrite("downwash", &ScenarioConfig::downwash, "wake (downwash) model on")
      .def_readwrite("battery_sag", &ScenarioConfig::battery_sag)
      .def_readonly("vehicles", &ScenarioConfig::vehicles)
      .def_readonly("leader", &ScenarioConfig::leader, "index of the leader")
      .def_property_readonly(
          "sample_time", [](const ScenarioConfig& s) { return s.rti.sample_time; }, "Ts [s]")
      .def_property_readonly(
          "horizon", [](const ScenarioConfig& s) { return s.rti.horizon; }, "N")
      .def_readonly("landing_time", &ScenarioConfig::landing_time, "[s]")
      .def_readonly("warnings", &ScenarioConfig::warnings,
                    "plausibility warnings of the file (fnmpc run prints them)")
      .def(
          "shortened",
          [](const ScenarioConfig& s, double duration) {
            config::CheckDurationFlag(s, duration);
            return experiment::Shortened(s, duration);
          },
          py::arg("duration"),
          "A copy shortened to `duration` [s] (as `fnmpc run --duration`): the landing moves "
          "earlier by the time cut, keeping the scenario's landing allowance, every vehicle's "
          "landing time moves with it and the leader keeps the legs it finishes by then "
          "(docs/scenarios.md, \"Shortened runs\").")
      .def("__repr__", [](const ScenarioConfig& s) {
        return "<fnmpc.Scenario '" + s.name + "', " + std::to_string(s.vehicles.size()) +
               " vehicles, " + std::to_string(s.duration) + " s>";
      });
  m.def("load_scenario", &config::LoadScenarioFile, py::arg("path"),
        "Reads a scenario file (config/scenarios/*.yaml) with its vehicle and sensors "
        "files. Raises ConfigError with file, line and key on a bad file.");
  m.def(
      "parse_scenario",
      [](const std::string& text, const std::string& name) {
        return config::ParseScenario(config::YamlMap::LoadString(text, name));
      },
      py::arg("text"), py::arg("name") = "<string>",
      "Parses scenario YAML text; relative file paths resolve against the working "
      "directory. Raises ConfigError (file = `name`).");
}

}  // namespace

void BindConfig(py::module_& m) {
  static py::exception<config::ConfigError> config_error(m, "ConfigError", PyExc_ValueError);
  config_error.attr("__doc__") =
      "A bad configuration file. Attributes: file, line, column (1-based, None when "
      "unknown) and key (the dotted YAML key, None when not about a key).";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const config::ConfigError& e) {
      const py::object type = config_error;  // py::exception's own operator() raises
      py::object err = type(e.what());
      AnnotateConfigError(e.what(), err);
      PyErr_SetObject(config_error.ptr(), err.ptr());
    }
  });
  BindVehicle(m);
  BindSensors(m);
  BindScenario(m);
}

}  // namespace fnmpc::python
