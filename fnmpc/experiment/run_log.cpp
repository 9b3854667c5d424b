// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/run_log.hpp"

#include <iterator>
#include <stdexcept>

#include "fnmpc/config/vehicle_yaml.hpp"

namespace fnmpc::experiment {

VehicleCsvLog::VehicleCsvLog(const std::string& path)
    : file_(std::make_unique<config::CheckedFile>(path)) {
  file_->Write(kVehicleLogCsvHeader);
}

void VehicleCsvLog::Write(const VehicleLogRow& r) {
  const sim::TrueState& x = *r.truth;
  const estimation::VehicleEstimate& e = *r.estimate;
  const formation::ControlOutput& out = *r.output;
  const auto& rel = *r.relative;
  const auto& est_rel = *r.estimated_relative;
  const auto& err = *r.errors;
  row_.clear();
  fmt::format_to(
      std::back_inserter(row_),
      "{:.3f},{},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
      "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
      "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
      "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
      "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},"
      "{:d},{:.6g},{:.6g},{:.6g},{},{},{:d},{},{:d},{},{:.4f},{:.4f},{},{},{},"
      "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f}\n",
      r.t, r.phase, x.position.x(), x.position.y(), x.position.z(), x.velocity.x(), x.velocity.y(),
      x.velocity.z(), x.euler.x(), x.euler.y(), x.euler.z(), e.position.x(), e.position.y(),
      e.position.z(), e.velocity.x(), e.velocity.y(), e.velocity.z(), e.euler.x(), e.euler.y(),
      e.euler.z(), out.thrust, out.throttle, out.roll, out.pitch, out.yaw, out.nmpc_thrust,
      out.nmpc_roll, out.nmpc_pitch, r.leader_ref.x(), r.leader_ref.y(), r.leader_ref.z(),
      r.tracking, rel[0].x(), rel[0].y(), rel[0].z(), est_rel[0].x(), est_rel[0].y(),
      est_rel[0].z(), err[0], rel[1].x(), rel[1].y(), rel[1].z(), est_rel[1].x(), est_rel[1].y(),
      est_rel[1].z(), err[1], r.formation_error, r.steady ? 1 : 0, out.cost, out.kkt,
      out.solver_time, out.sqp_iterations, out.qp_iterations, out.fallback ? 1 : 0,
      rti::ToString(out.status), out.guarded ? 1 : 0, r.estimator_rejections, x.voltage,
      out.voltage, formation::ToString(out.recovery), formation::ToString(out.recovery_reason),
      out.active_neighbours, x.aero_force.x(), x.aero_force.y(), x.aero_force.z(),
      r.estimated_force.x(), r.estimated_force.y(), r.estimated_force.z());
  file_->Write(std::string_view(row_.data(), row_.size()));
}

void VehicleCsvLog::Finish() { file_->Finish(); }

void WritePlantFiles(const config::ScenarioConfig& sc, const sim::WorldConfig& world,
                     const std::string& dir) {
  for (std::size_t i = 0; i < sc.vehicles.size(); ++i) {
    const std::string path = config::PathInside(dir, "plant-" + sc.vehicles[i].name + ".yaml");
    try {
      config::SaveVehicleFile(world.vehicles[i].params, path);
    } catch (const std::exception& e) {
      throw std::runtime_error("cannot write " + path + ": " + e.what());
    }
  }
}

}  // namespace fnmpc::experiment
