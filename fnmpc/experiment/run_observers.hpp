// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <string>
#include <vector>

#include "fnmpc/experiment/closed_loop.hpp"
#include "fnmpc/experiment/run_log.hpp"
#include "fnmpc/experiment/run_record.hpp"

/// The observers of `fnmpc run`'s closed loop: each measures one thing from the truth into
/// the RunRecord (or logs it) and never acts on the loop.
namespace fnmpc::experiment {

/// A vehicle downed by a fault (controller killed, motors off): its first ground contact,
/// checked every physics step for the vertical speed at contact (RunRecord::downed).
class ImpactObserver : public ClosedLoopObserver {
 public:
  explicit ImpactObserver(RunRecord* record) : rec_(record) {}
  void PhysicsStep(const ClosedLoop& loop, double t) override;

 private:
  RunRecord* rec_;
  std::vector<double> prev_vz_;
};

/// The closest approach of every pair, each vehicle and the run, and the first time a pair
/// came closer than metrics.collision_distance (true CoM distances at the control steps).
class SeparationObserver : public ClosedLoopObserver {
 public:
  explicit SeparationObserver(RunRecord* record) : rec_(record) {}
  void ControlStepBegin(const ClosedLoop& loop, const ControlStep& step) override;

 private:
  RunRecord* rec_;
};

/// What each controller did (solver statistics, recoveries, failsafes, tie losses) and how
/// each vehicle met the ground (touchdown, ground strikes, motors off); reads the impacts of
/// the ImpactObserver, which must come before it.
class FlightRecordObserver : public ClosedLoopObserver {
 public:
  explicit FlightRecordObserver(RunRecord* record) : rec_(record) {}
  void CommandsSent(const ClosedLoop& loop, const ControlStep& step) override;

 private:
  RunRecord* rec_;
  std::vector<formation::ControlOutput> prev_;  // each vehicle's last flown NMPC-step output
};

/// The flight envelope from the truth: altitude above the ground and horizontal distance from
/// the start; the first excursion is kept.
class EnvelopeObserver : public ClosedLoopObserver {
 public:
  explicit EnvelopeObserver(RunRecord* record) : rec_(record) {}
  void VehicleStep(const ClosedLoop& loop, const ControlStep& step, int i) override;

 private:
  RunRecord* rec_;
};

/// One vehicle's formation errors of the current control step (what the CSV row shows).
struct FormationErrorSample {
  std::array<Vec3, formation::kMaxNeighbours> relative, estimated_relative;
  std::array<double, formation::kMaxNeighbours> errors;
  double formation_error = kNaN;
  double tracking = kNaN;  ///< leader: |p - p_ref|
  bool steady = false;     ///< in its formation window, settled
};

/// Formation errors from the truth ((p_j - p_i) in the target frame minus d_j, every
/// neighbour) of the followers and the leader's tracking error, over each vehicle's own
/// window (trajectory start to its landing), its flight and the steady state.
class FormationErrorObserver : public ClosedLoopObserver {
 public:
  FormationErrorObserver(RunRecord* record, int vehicles)
      : rec_(record), current_(static_cast<std::size_t>(vehicles)) {}
  void VehicleStep(const ClosedLoop& loop, const ControlStep& step, int i) override;
  /// Vehicle i's errors at the current control step.
  [[nodiscard]] const FormationErrorSample& current(int i) const {
    return current_[static_cast<std::size_t>(i)];
  }

 private:
  RunRecord* rec_;
  std::vector<FormationErrorSample> current_;
};

/// <dir>/<vehicle>.csv, one row per control step (run_log.hpp); the formation errors come
/// from `errors`, which must come before it.
class CsvLogObserver : public ClosedLoopObserver {
 public:
  CsvLogObserver(const config::ScenarioConfig& scenario, const std::string& dir,
                 const FormationErrorObserver* errors);
  void VehicleStep(const ClosedLoop& loop, const ControlStep& step, int i) override;
  void Finish(const ClosedLoop& loop) override;

 private:
  const FormationErrorObserver* errors_;
  std::vector<VehicleCsvLog> csv_;
};

/// Progress on stderr every 5 s of simulated time, and the loop's events.
class ProgressObserver : public ClosedLoopObserver {
 public:
  explicit ProgressObserver(std::string label) : label_(std::move(label)) {}
  void ControlStepEnd(const ClosedLoop& loop, const ControlStep& step) override;
  void Finish(const ClosedLoop& loop) override;
  void Event(double t, const std::string& what) const;

 private:
  std::string label_;
  double next_ = 0.0;
};

}  // namespace fnmpc::experiment
