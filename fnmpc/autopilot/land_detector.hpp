// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"

/// The land detectors an onboard computer meets when it asks a multicopter autopilot to
/// disarm, as the emulated autopilot plays them. Both refuse a disarm until they have seen
/// the vehicle on the ground with its motors at idle for a while, so a session must keep
/// streaming idle thrust after touchdown.
///
/// PX4 (src/modules/land_detector/MulticopterLandDetector.cpp, LandDetector.cpp): three stages,
/// each entered when its conditions held for its trigger time and left at once when they fail.
///   ground contact (0.35 s): thrust <= MPC_THR_MIN + 0.3 (MPC_THR_HOVER - MPC_THR_MIN),
///                            |v_z| <= LNDMC_Z_VEL_MAX, |v_xy| <= LNDMC_XY_VEL_MAX
///   maybe landed  (0.25 s):  ground contact and, without climb-rate control (offboard
///                            attitude), thrust <= MPC_MANTHR_MIN + 0.01, and the roll/pitch
///                            rate <= LNDMC_ROT_MAX
///   landed        (0.30 s):  maybe landed
/// An armed vehicle starts landed (the detector holds every stage while disarmed); it has
/// taken off once a stage drops. Commander (src/modules/commander/Commander.cpp,
/// Commander::disarm) accepts a disarm that is not forced only when landed or maybe landed
/// ("Disarming denied: not landed", ACK TEMPORARILY_REJECTED), and disarms by itself
/// COM_DISARM_LAND after landed once it has taken off since arming, COM_DISARM_PRFLT after
/// arming when it never took off.
///
/// ArduPilot Copter (ArduCopter/land_detector.cpp, config.h): land_complete when the motors are
/// at their lower limit (throttle at its minimum), the earth-frame acceleration less gravity,
/// low-pass filtered at LAND_DETECTOR_ACCEL_LPF_CUTOFF (1 Hz), is at most
/// LAND_DETECTOR_ACCEL_MAX (1 m/s^2) and the descent rate below 1 m/s, for
/// LAND_DETECTOR_TRIGGER_SEC (1 s). A disarm by command while not land_complete is refused
/// (ACK FAILED).
namespace fnmpc::autopilot {

/// The parameters of both detectors (named after the autopilots' parameters and constants).
struct LandDetectorSettings {
  double thr_min = 0.12;           ///< PX4 MPC_THR_MIN
  double thr_hover = 0.5;          ///< PX4 MPC_THR_HOVER
  double manthr_min = 0.08;        ///< PX4 MPC_MANTHR_MIN
  double z_vel_max = 0.25;         ///< PX4 LNDMC_Z_VEL_MAX [m/s]
  double xy_vel_max = 1.5;         ///< PX4 LNDMC_XY_VEL_MAX [m/s]
  double rot_max_deg = 20.0;       ///< PX4 LNDMC_ROT_MAX [deg/s]
  double disarm_land = 2.0;        ///< PX4 COM_DISARM_LAND [s] (<= 0: never by itself)
  double disarm_preflight = 10.0;  ///< PX4 COM_DISARM_PRFLT [s] (<= 0: never by itself)
  /// ArduPilot: throttle at or below this counts as the motors' lower limit (the attitude
  /// controller's minimum output in GUIDED_NOGPS with thrust; 0 is the minimum).
  double lower_limit_thrust = 0.01;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("thr_min", &thr_min, NonNegative().AtMost(1.0, ""), "PX4 MPC_THR_MIN");
    a->Visit("thr_hover", &thr_hover, Positive().AtMost(1.0, ""), "PX4 MPC_THR_HOVER");
    a->Visit("manthr_min", &manthr_min, NonNegative().AtMost(1.0, ""), "PX4 MPC_MANTHR_MIN");
    a->Visit("z_vel_max", &z_vel_max, Positive().AtMost(10.0, "m/s"), "[m/s] PX4 LNDMC_Z_VEL_MAX");
    a->Visit("xy_vel_max", &xy_vel_max, Positive().AtMost(20.0, "m/s"),
             "[m/s] PX4 LNDMC_XY_VEL_MAX");
    a->Visit("rot_max_deg", &rot_max_deg, Positive().AtMost(360.0, "deg/s"),
             "[deg/s] PX4 LNDMC_ROT_MAX");
    a->Visit("disarm_land", &disarm_land, Finite(),
             "[s] PX4 COM_DISARM_LAND: disarm this long after landed (<= 0: never)");
    a->Visit("disarm_preflight", &disarm_preflight, Finite(),
             "[s] PX4 COM_DISARM_PRFLT: disarm this long after arming without take-off");
    a->Visit("lower_limit_thrust", &lower_limit_thrust, NonNegative().AtMost(1.0, ""),
             "ArduPilot: thrust counted as the motors' lower limit");
  }
};

/// What the detector sees of the vehicle at one step.
struct LandDetectorInput {
  double thrust = kNaN;           ///< the normalised thrust the autopilot flies
  double vertical_speed = 0.0;    ///< [m/s], up positive
  double horizontal_speed = 0.0;  ///< [m/s]
  double tilt_rate = 0.0;         ///< norm of the roll and pitch rates [rad/s]
  double acceleration = 0.0;      ///< norm of the earth-frame acceleration less gravity
};

class LandDetector {
 public:
  LandDetector(AutopilotKind kind, const LandDetectorSettings& settings);

  /// One step at `now` [s] of an armed vehicle.
  void Update(double now, const LandDetectorInput& in);
  /// Armed at `now`: landed, not yet taken off.
  void Reset(double now);

  /// A disarm by command would be accepted now (PX4: landed or maybe landed; ArduPilot:
  /// land_complete).
  [[nodiscard]] bool disarm_allowed() const;
  /// PX4: landed for COM_DISARM_LAND after a take-off, or COM_DISARM_PRFLT after arming
  /// without one; the autopilot disarms by itself. Never for ArduPilot.
  [[nodiscard]] bool auto_disarm_due(double now) const;
  [[nodiscard]] bool landed() const { return landed_; }

 private:
  /// Holds a condition's state true only after it was true for `trigger` [s].
  struct Hysteresis {
    double since = kNaN;  // the condition holds since (-inf: held before arming)
    bool state = false;
    void Update(double now, bool condition, double trigger);
  };

  AutopilotKind kind_;
  LandDetectorSettings settings_;
  Hysteresis ground_contact_, maybe_landed_, landed_stage_, land_complete_;
  bool landed_ = false;
  bool taken_off_ = false;
  double armed_at_ = kNaN;
  double landed_since_ = kNaN;
  double filtered_accel_ = 0.0;
  double last_time_ = kNaN;
};

}  // namespace fnmpc::autopilot
