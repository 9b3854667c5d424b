// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <fmt/format.h>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/estimation/vehicle_ekf.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/sim/world.hpp"

/// The files `fnmpc run` writes while it flies: one CSV log per vehicle and, with reality on,
/// the true plant of each vehicle.
namespace fnmpc::experiment {

/// Header line of the per-vehicle CSV log (`<vehicle>.csv`) that `fnmpc run` writes and
/// `fnmpc report` reads; shared with the ROS bag converter so both write the same columns.
inline constexpr const char* kVehicleLogCsvHeader =
    "t,phase,x,y,z,vx,vy,vz,roll,pitch,yaw,est_x,est_y,est_z,est_vx,est_vy,est_vz,"
    "est_roll,est_pitch,est_yaw,cmd_thrust,cmd_throttle,cmd_roll,cmd_pitch,cmd_yaw,"
    "nmpc_thrust,nmpc_roll,nmpc_pitch,ref_x,ref_y,ref_z,tracking_error,"
    "rel0_x,rel0_y,rel0_z,est_rel0_x,est_rel0_y,est_rel0_z,err0,"
    "rel1_x,rel1_y,rel1_z,est_rel1_x,est_rel1_y,est_rel1_z,err1,formation_error,"
    "steady,cost,kkt,solver_time,sqp_iterations,qp_iterations,"
    "fallback,status,guarded,estimator_rejections,voltage,voltage_measured,"
    "recovery,recovery_reason,active_neighbours,aero_fx,aero_fy,aero_fz,"
    "est_fx,est_fy,est_fz\n";

/// One row of the log: one vehicle at one control step.
struct VehicleLogRow {
  double t = 0.0;
  std::string_view phase;  ///< the controller's phase, or "killed"
  const sim::TrueState* truth = nullptr;
  const estimation::VehicleEstimate* estimate = nullptr;
  const formation::ControlOutput* output = nullptr;
  Vec3 leader_ref = Vec3::Constant(kNaN);
  double tracking = kNaN;  ///< leader |p - p_ref|, NaN for followers
  const std::array<Vec3, formation::kMaxNeighbours>* relative = nullptr;
  const std::array<Vec3, formation::kMaxNeighbours>* estimated_relative = nullptr;
  const std::array<double, formation::kMaxNeighbours>* errors = nullptr;
  double formation_error = kNaN;
  bool steady = false;
  std::int64_t estimator_rejections = 0;
  /// The own estimator's external force m d ({n}, the controller's model mass) [N].
  Vec3 estimated_force = Vec3::Constant(kNaN);
};

/// One vehicle's CSV log (kVehicleLogCsvHeader's columns; the first two neighbours).
class VehicleCsvLog {
 public:
  /// Creates `path` (through CheckedFile) and writes the header.
  explicit VehicleCsvLog(const std::string& path);
  void Write(const VehicleLogRow& r);
  /// Renames the complete file into place.
  void Finish();

 private:
  std::unique_ptr<config::CheckedFile> file_;
  fmt::memory_buffer row_;  // one CSV row, reused
};

/// With the scenario's reality on: `plant-<vehicle>.yaml` in `dir` for every vehicle, the true
/// plant it flies (the controllers keep their vehicle files).
void WritePlantFiles(const config::ScenarioConfig& sc, const sim::WorldConfig& world,
                     const std::string& dir);

}  // namespace fnmpc::experiment
