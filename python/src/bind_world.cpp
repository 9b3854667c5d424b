// SPDX-License-Identifier: BSD-3-Clause
// The simulator world (fnmpc/sim/world.hpp) for a controller written in Python: build it
// from a scenario, step it, read the true states and the sensor measurements, send
// attitude/thrust commands or throttles.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "fnmpc/experiment/scenario_runner.hpp"
#include "fnmpc/sim/world.hpp"
#include "python/src/bindings.hpp"

namespace py = pybind11;

namespace fnmpc::python {

/// One measurement as a flat record: the numpy structured dtype of World.pop_measurements().
struct MeasurementRecord {
  char kind[16];  // "mocap", "imu", "optical_flow", "compass", "battery", "relative"
  std::int32_t vehicle;
  double stamp, arrival;
  double position[3], euler[3], accel[3], gyro[3], velocity[3];
  double yaw, voltage;
  std::int32_t target;
  double range, bearing, elevation, relative_yaw;
};

namespace {

void CheckVehicle(const sim::World& w, int i) {
  if (i < 0 || i >= w.num_vehicles()) {
    throw std::out_of_range("vehicle " + std::to_string(i) + " outside 0.." +
                            std::to_string(w.num_vehicles() - 1));
  }
}

void Copy3(const Vec3& v, double* out) {
  for (int k = 0; k < 3; ++k) out[k] = v[k];
}

MeasurementRecord ToRecord(const Measurement& m) {
  MeasurementRecord r{};
  const std::string_view kind = ToString(m.kind);
  kind.copy(r.kind, sizeof(r.kind) - 1);
  r.vehicle = m.vehicle;
  r.stamp = m.stamp;
  r.arrival = m.arrival;
  Copy3(m.position, r.position);
  Copy3(m.euler, r.euler);
  Copy3(m.accel, r.accel);
  Copy3(m.gyro, r.gyro);
  Copy3(m.velocity, r.velocity);
  r.yaw = m.yaw;
  r.voltage = m.voltage;
  r.target = m.relative.target;
  r.range = m.relative.range;
  r.bearing = m.relative.bearing;
  r.elevation = m.relative.elevation;
  r.relative_yaw = m.relative.relative_yaw;
  return r;
}

py::dict StateDict(const sim::TrueState& s) {
  py::dict d;
  d["position"] = s.position;
  d["velocity"] = s.velocity;
  d["euler"] = s.euler;
  d["body_rates"] = s.body_rates;
  d["acceleration"] = s.acceleration;
  d["rotor_rpm"] = s.rotor_rpm;
  d["throttle"] = s.throttle;
  d["thrust"] = s.thrust;
  d["voltage"] = s.voltage;
  d["soc"] = s.soc;
  d["current"] = s.current;
  d["aero_force"] = s.aero_force;
  d["aero_torque"] = s.aero_torque;
  return d;
}

}  // namespace

void BindWorld(py::module_& m) {
  PYBIND11_NUMPY_DTYPE(MeasurementRecord, kind, vehicle, stamp, arrival, position, euler, accel,
                       gyro, velocity, yaw, voltage, target, range, bearing, elevation,
                       relative_yaw);
  py::class_<sim::WorldConfig>(m, "WorldConfig",
                               "Everything a World is built from; make one with "
                               "world_config(scenario, seed) and adjust it.")
      .def_readwrite("physics_dt", &sim::WorldConfig::physics_dt, "MuJoCo time step [s]")
      .def_readwrite("autopilot_rate_hz", &sim::WorldConfig::autopilot_rate_hz, "[Hz]")
      .def_readwrite("gravity", &sim::WorldConfig::gravity, "[m/s^2]")
      .def_readwrite("ground", &sim::WorldConfig::ground)
      .def_readwrite("visual_geometry", &sim::WorldConfig::visual_geometry)
      .def_readwrite("drag_coefficient", &sim::WorldConfig::drag_coefficient,
                     "body-axis quadratic drag (3,) [N s^2/m^2]")
      .def_readwrite("seed", &sim::WorldConfig::seed)
      .def_property(
          "downwash", [](const sim::WorldConfig& c) { return c.downwash.enabled; },
          [](sim::WorldConfig& c, bool on) { c.downwash.enabled = on; }, "wake model on")
      .def_property_readonly("num_vehicles", [](const sim::WorldConfig& c) {
        return static_cast<int>(c.vehicles.size());
      });
  m.def(
      "world_config",
      [](const config::ScenarioConfig& sc, py::object seed) {
        return experiment::WorldConfigFor(sc,
                                          seed.is_none() ? sc.seed : seed.cast<std::uint64_t>());
      },
      py::arg("scenario"), py::arg("seed") = py::none(),
      "The world `fnmpc run` flies `scenario` in: every vehicle resting at its start, noise "
      "seeded from `seed` (default: the scenario's).");

  py::class_<sim::World>(m, "World",
                         "Multi-quadrotor MuJoCo world (docs/simulator.md): 1 ms physics, an "
                         "emulated autopilot per vehicle, every sensor with its rate, latency "
                         "and noise. Frames: world ENU z up, Euler ZYX (roll, pitch, yaw).")
      .def(py::init<const sim::WorldConfig&>(), py::arg("config"))
      .def_static(
          "from_scenario",
          [](const config::ScenarioConfig& sc, py::object seed) {
            return std::make_unique<sim::World>(experiment::WorldConfigFor(
                sc, seed.is_none() ? sc.seed : seed.cast<std::uint64_t>()));
          },
          py::arg("scenario"), py::arg("seed") = py::none(), "World(world_config(scenario, seed)).")
      .def_property_readonly("time", &sim::World::time, "simulation time [s]")
      .def_property_readonly("physics_dt", &sim::World::physics_dt, "[s]")
      .def_property_readonly("num_vehicles", &sim::World::num_vehicles)
      .def("step", &sim::World::Step, py::arg("duration"),
           "Advances round(duration / physics_dt) physics steps [s].")
      .def("step_once", &sim::World::StepOnce, "Advances one physics step.")
      .def(
          "set_command",
          [](sim::World& w, int i, double thrust, double roll, double pitch, double yaw,
             double throttle) {
            CheckVehicle(w, i);
            if (!std::isfinite(thrust) || !std::isfinite(roll) || !std::isfinite(pitch) ||
                !std::isfinite(yaw)) {
              throw std::invalid_argument("set_command: non-finite command");
            }
            w.SetCommand(i, sim::AttitudeCommand{thrust, roll, pitch, yaw, throttle});
          },
          py::arg("vehicle"), py::arg("thrust"), py::arg("roll"), py::arg("pitch"), py::arg("yaw"),
          py::arg("throttle") = kNaN,
          "Autopilot reference of `vehicle`: total thrust [N] and absolute roll, pitch, yaw "
          "[rad]; a finite `throttle` in [0, 1] replaces the thrust.")
      .def(
          "set_throttles",
          [](sim::World& w, int i, const Eigen::Vector4d& t) {
            CheckVehicle(w, i);
            w.SetThrottles(i, t);
          },
          py::arg("vehicle"), py::arg("throttles"),
          "Bypasses the autopilot: four rotor throttles (clamped to [0, 1]).")
      .def(
          "kill_motors",
          [](sim::World& w, int i) {
            CheckVehicle(w, i);
            w.KillMotors(i);
          },
          py::arg("vehicle"))
      .def(
          "set_pose",
          [](sim::World& w, int i, const Vec3& p, const Vec3& e) {
            CheckVehicle(w, i);
            w.SetPose(i, p, e);
          },
          py::arg("vehicle"), py::arg("position"), py::arg("euler"),
          "Teleports `vehicle` with zero velocity.")
      .def(
          "true_state",
          [](const sim::World& w, int i) {
            CheckVehicle(w, i);
            return StateDict(w.GetTrueState(i));
          },
          py::arg("vehicle"),
          "Ground truth of `vehicle`: dict of position, velocity, euler, body_rates, "
          "acceleration (3,), rotor_rpm, throttle (4,), thrust, voltage, soc, current, "
          "aero_force, aero_torque.")
      .def(
          "positions",
          [](const sim::World& w) {
            Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> out(w.num_vehicles(), 3);
            for (int i = 0; i < w.num_vehicles(); ++i)
              out.row(i) = w.GetTrueState(i).position.transpose();
            return out;
          },
          "True positions of every vehicle (n, 3) [m].")
      .def(
          "pop_measurements",
          [](sim::World& w) {
            std::vector<MeasurementRecord> records;
            Measurement meas;
            while (w.PopMeasurement(&meas)) records.push_back(ToRecord(meas));
            py::array_t<MeasurementRecord> out(static_cast<py::ssize_t>(records.size()));
            std::copy(records.begin(), records.end(), out.mutable_data());
            return out;
          },
          "Every measurement delivered by now, in arrival order, as a numpy structured "
          "array: kind, vehicle, stamp, arrival, position, euler, accel, gyro, velocity (3), "
          "yaw, voltage, target, range, bearing, elevation, relative_yaw (NaN where the kind "
          "has no such field).");
}

}  // namespace fnmpc::python
