// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/estimation/vehicle_ekf.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/core/assert.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/estimation/ekf_math.hpp"

namespace fnmpc::estimation {
namespace {

using Idx = VehicleStateIndex;
constexpr int kN = Idx::kSize;
// Take-off evidence slots.
constexpr int kEvidenceHeight = 0;
constexpr int kEvidenceFlow = 1;
constexpr int kEvidenceImu = 2;
constexpr int kEvidenceThrust = 3;

void Require(bool ok, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string("[VehicleEkfConfig] ") + field + " " + what + ", got " +
                                std::to_string(value));
  }
}

// cos(theta) bounded away from zero (|theta| <= 1.5 rad equivalent): the Euler-rate matrix
// stays finite beyond the attitude envelope, which the health flags (max_pitch < pi/2) mark.
double GuardedCos(double theta) {
  constexpr double kMinCos = 0.0707372016677029;  // cos(1.5)
  const double c = std::cos(theta);
  return std::abs(c) >= kMinCos ? c : std::copysign(kMinCos, c);
}

// Euler-rate matrix: euler' = T(phi, theta) * omega_body.
Mat3 EulerRateMatrix(double phi, double theta) {
  const double cf = std::cos(phi), sf = std::sin(phi), ct = GuardedCos(theta),
               tt = std::sin(theta) / ct;
  Mat3 T;
  T << 1.0, sf * tt, cf * tt, 0.0, cf, -sf, 0.0, sf / ct, cf / ct;
  return T;
}

Vec3 EffectiveRefs(const Vec3& refs, const model::VehicleParams& v) {
  return {refs.x() + v.bias.roll, refs.y() + v.bias.pitch, refs.z()};
}

// P = F P F' + Q with F = I + A h + (A h)^2 / 2. Every motion model moves only position,
// velocity and attitude: the rows of A below them are zero, so F is [F_top; 0 I] and
// F P F' = [F_top P F_top', F_top P_right; (F_top P_right)', P_lower]: 9-row products
// instead of three 18 x 18 x 18 ones.
void PropagateCovariance(const VehicleStateCov& A, double h, const VehicleStateCov& Q,
                         VehicleStateCov* P) {
  constexpr int kTop = Idx::kAccelBias;
  constexpr int kLow = kN - kTop;
  FNMPC_ASSERT(A.bottomRows<kLow>().isZero(0.0));
  const Mat<kTop, kN> Ah = A.topRows<kTop>() * h;
  Mat<kTop, kN> F = Ah + 0.5 * Ah.leftCols<kTop>() * Ah;
  F.leftCols<kTop>().diagonal().array() += 1.0;
  const Mat<kTop, kN> FP = F * (*P);
  P->topLeftCorner<kTop, kTop>() = FP * F.transpose();
  P->topRightCorner<kTop, kLow>() = FP.rightCols<kLow>();
  P->bottomLeftCorner<kLow, kTop>() = FP.rightCols<kLow>().transpose();
  *P += Q;
  Symmetrize<kN>(P);
}

}  // namespace

void VehicleEkfConfig::Validate() const {
  Require(max_lag >= 0.0 && std::isfinite(max_lag), "max_lag", max_lag, "must be >= 0");
  Require(buffer_capacity == 0 || buffer_capacity >= 2, "buffer_capacity", buffer_capacity,
          "must be 0 (derived) or >= 2");
  Require(command_rate_hz > 0.0 && std::isfinite(command_rate_hz), "command_rate_hz",
          command_rate_hz, "must be finite and > 0");
  Require(max_predict_dt > 0.0, "max_predict_dt", max_predict_dt, "must be > 0");
  Require(imu_timeout > 0.0, "imu_timeout", imu_timeout, "must be > 0");
  Require(command_timeout > 0.0, "command_timeout", command_timeout, "must be > 0");
  Require(accel_bias_noise >= 0.0, "accel_bias_noise", accel_bias_noise, "must be >= 0");
  Require(gyro_bias_noise >= 0.0, "gyro_bias_noise", gyro_bias_noise, "must be >= 0");
  Require(fallback_accel_noise > 0.0, "fallback_accel_noise", fallback_accel_noise, "must be > 0");
  Require(command_accel_noise > 0.0, "command_accel_noise", command_accel_noise, "must be > 0");
  Require(command_attitude_noise > 0.0, "command_attitude_noise", command_attitude_noise,
          "must be > 0");
  Require(landed_position_noise > 0.0, "landed_position_noise", landed_position_noise,
          "must be > 0");
  Require(landed_attitude_noise > 0.0, "landed_attitude_noise", landed_attitude_noise,
          "must be > 0");
  Require(zupt_std > 0.0, "zupt_std", zupt_std, "must be > 0");
  Require(landed_accel_std > 0.0 && std::isfinite(landed_accel_std), "landed_accel_std",
          landed_accel_std, "must be finite and > 0");
  Require(landed_gyro_std > 0.0 && std::isfinite(landed_gyro_std), "landed_gyro_std",
          landed_gyro_std, "must be finite and > 0");
  Require(disturbance_noise >= 0.0 && std::isfinite(disturbance_noise), "disturbance_noise",
          disturbance_noise, "must be finite and >= 0");
  Require(initial_disturbance_std > 0.0 && std::isfinite(initial_disturbance_std),
          "initial_disturbance_std", initial_disturbance_std, "must be finite and > 0");
  Require(initial_velocity_std > 0.0, "initial_velocity_std", initial_velocity_std, "must be > 0");
  Require(initial_accel_bias_std > 0.0, "initial_accel_bias_std", initial_accel_bias_std,
          "must be > 0");
  Require(initial_gyro_bias_std > 0.0, "initial_gyro_bias_std", initial_gyro_bias_std,
          "must be > 0");
  Require(gate_probability > 0.0 && gate_probability < 1.0, "gate_probability", gate_probability,
          "must be in (0, 1)");
  Require(max_consecutive_gated >= 1, "max_consecutive_gated", max_consecutive_gated,
          "must be >= 1");
  Require(max_specific_force > 0.0, "max_specific_force", max_specific_force, "must be > 0");
  Require(max_angular_rate > 0.0, "max_angular_rate", max_angular_rate, "must be > 0");
  Require(takeoff_height > land_height, "takeoff_height", takeoff_height,
          "must exceed land_height (hysteresis)");
  Require(takeoff_speed > land_speed, "takeoff_speed", takeoff_speed,
          "must exceed land_speed (hysteresis)");
  Require(takeoff_accel > 0.0, "takeoff_accel", takeoff_accel, "must be > 0");
  Require(takeoff_thrust_ratio > 0.0, "takeoff_thrust_ratio", takeoff_thrust_ratio, "must be > 0");
  Require(takeoff_hold >= 0.0, "takeoff_hold", takeoff_hold, "must be >= 0");
  Require(land_hold >= 0.0, "land_hold", land_hold, "must be >= 0");
  Require(land_thrust_ratio > 0.0, "land_thrust_ratio", land_thrust_ratio, "must be > 0");
  Require(takeoff_position_std >= 0.0, "takeoff_position_std", takeoff_position_std,
          "must be >= 0");
  Require(takeoff_velocity_std >= 0.0, "takeoff_velocity_std", takeoff_velocity_std,
          "must be >= 0");
  Require(std::isfinite(ground_height), "ground_height", ground_height, "must be finite");
  Require(max_position_std > 0.0, "max_position_std", max_position_std, "must be > 0 (kInf: off)");
  Require(max_velocity_std > 0.0, "max_velocity_std", max_velocity_std, "must be > 0 (kInf: off)");
  Require(max_attitude_std > 0.0, "max_attitude_std", max_attitude_std, "must be > 0 (kInf: off)");
  Require(max_pitch > 0.0 && max_pitch < 0.5 * M_PI, "max_pitch", max_pitch,
          "must be in (0, pi/2)");
  for (double v : max_staleness) {
    Require(v > 0.0, "max_staleness", v, "entries must be > 0 (kInf: not monitored)");
  }
  Require(max_extrapolation >= 0.0 && std::isfinite(max_extrapolation), "max_extrapolation",
          max_extrapolation, "must be finite and >= 0");
  Require(max_time_jump > 0.0 && std::isfinite(max_time_jump), "max_time_jump", max_time_jump,
          "must be finite and > 0");
  Require(std::max(max_time_jump, max_extrapolation) / max_predict_dt <= 1e5, "max_time_jump",
          std::max(max_time_jump, max_extrapolation),
          "and max_extrapolation must be <= 1e5 * max_predict_dt (sub-step cap)");
  Require(time_jump_reset_count >= 1, "time_jump_reset_count", time_jump_reset_count,
          "must be >= 1");
  Require(reset_position_std >= 0.0 && std::isfinite(reset_position_std), "reset_position_std",
          reset_position_std, "must be finite and >= 0");
  Require(reset_attitude_std >= 0.0 && std::isfinite(reset_attitude_std), "reset_attitude_std",
          reset_attitude_std, "must be finite and >= 0");
  const auto check_sensor = [](const SensorSpec& s, const char* name, bool noise2) {
    if (!s.enabled) return;
    Require(s.rate_hz > 0.0, name, s.rate_hz, "rate_hz must be > 0");
    Require((s.noise.array() > 0.0).all(), name, s.noise.minCoeff(), "noise must be > 0");
    if (noise2) {
      Require((s.noise2.array() > 0.0).all(), name, s.noise2.minCoeff(), "noise2 must be > 0");
    }
  };
  check_sensor(sensors.mocap, "sensors.mocap", true);
  check_sensor(sensors.imu, "sensors.imu", true);
  check_sensor(sensors.optical_flow, "sensors.optical_flow", false);
  if (sensors.compass.enabled) {
    Require(sensors.compass.noise.x() > 0.0, "sensors.compass", sensors.compass.noise.x(),
            "noise[0] must be > 0");
  }
}

VehicleStateVec ImuFlow(const VehicleStateVec& x, const Vec3& accel, const Vec3& gyro) {
  const Vec3 e = x.segment<3>(Idx::kEuler);
  const Mat3 R = RotationZyx(e.x(), e.y(), e.z());
  VehicleStateVec f = VehicleStateVec::Zero();
  f.segment<3>(Idx::kPos) = x.segment<3>(Idx::kVel);
  f.segment<3>(Idx::kVel) = R * (accel - x.segment<3>(Idx::kAccelBias)) - Vec3(0.0, 0.0, kGravity);
  f.segment<3>(Idx::kEuler) = EulerRateMatrix(e.x(), e.y()) * (gyro - x.segment<3>(Idx::kGyroBias));
  return f;
}

VehicleStateCov ImuFlowJacobian(const VehicleStateVec& x, const Vec3& accel, const Vec3& gyro) {
  const Vec3 e = x.segment<3>(Idx::kEuler);
  Mat3 R;
  std::array<Mat3, 3> dR;
  RotationZyxPartials(e, &R, &dR);
  const Vec3 a = accel - x.segment<3>(Idx::kAccelBias);
  const Vec3 w = gyro - x.segment<3>(Idx::kGyroBias);
  VehicleStateCov A = VehicleStateCov::Zero();
  A.block<3, 3>(Idx::kPos, Idx::kVel).setIdentity();
  for (int i = 0; i < 3; ++i) A.block<3, 1>(Idx::kVel, Idx::kEuler + i) = dR[i] * a;
  A.block<3, 3>(Idx::kVel, Idx::kAccelBias) = -R;
  const double cf = std::cos(e.x()), sf = std::sin(e.x()), ct = GuardedCos(e.y()),
               st = std::sin(e.y()), tt = st / ct;
  Mat3 dT_dphi, dT_dtheta;
  dT_dphi << 0.0, cf * tt, -sf * tt, 0.0, -sf, -cf, 0.0, cf / ct, -sf / ct;
  dT_dtheta << 0.0, sf / (ct * ct), cf / (ct * ct), 0.0, 0.0, 0.0, 0.0, sf * st / (ct * ct),
      cf * st / (ct * ct);
  A.block<3, 1>(Idx::kEuler, Idx::kEuler) = dT_dphi * w;
  A.block<3, 1>(Idx::kEuler, Idx::kEuler + 1) = dT_dtheta * w;
  A.block<3, 3>(Idx::kEuler, Idx::kGyroBias) = -EulerRateMatrix(e.x(), e.y());
  return A;
}

VehicleStateVec CommandFlow(const VehicleStateVec& x, double thrust, const Vec3& refs,
                            const model::VehicleParams& vehicle) {
  const Vec3 e = x.segment<3>(Idx::kEuler);
  const Vec3 r = EffectiveRefs(refs, vehicle);
  const Vec3& k = vehicle.attitude_gain;
  const Vec3& tau = vehicle.attitude_time_constant;
  VehicleStateVec f = VehicleStateVec::Zero();
  f.segment<3>(Idx::kPos) = x.segment<3>(Idx::kVel);
  f.segment<3>(Idx::kVel) =
      BodyZ(e.x(), e.y(), e.z()) * (thrust * vehicle.bias.thrust_scale / vehicle.mass) -
      Vec3(0.0, 0.0, kGravity) + x.segment<3>(Idx::kDisturbance);
  f(Idx::kEuler) = (k.x() * r.x() - e.x()) / tau.x();
  f(Idx::kEuler + 1) = (k.y() * r.y() - e.y()) / tau.y();
  f(Idx::kEuler + 2) = WrapAngle(k.z() * r.z() - e.z()) / tau.z();
  return f;
}

VehicleStateCov CommandFlowJacobian(const VehicleStateVec& x, double thrust, const Vec3& /*refs*/,
                                    const model::VehicleParams& vehicle) {
  const Vec3 e = x.segment<3>(Idx::kEuler);
  VehicleStateCov A = VehicleStateCov::Zero();
  A.block<3, 3>(Idx::kPos, Idx::kVel).setIdentity();
  A.block<3, 3>(Idx::kVel, Idx::kEuler) =
      BodyZJacobian(e.x(), e.y(), e.z()) * (thrust * vehicle.bias.thrust_scale / vehicle.mass);
  A.block<3, 3>(Idx::kVel, Idx::kDisturbance).setIdentity();
  for (int i = 0; i < 3; ++i) {
    A(Idx::kEuler + i, Idx::kEuler + i) = -1.0 / vehicle.attitude_time_constant(i);
  }
  return A;
}

Vec3 UnexplainedAcceleration(const VehicleStateVec& x, const Vec3& accel, double thrust,
                             const model::VehicleParams& vehicle) {
  const Vec3 e = x.segment<3>(Idx::kEuler);
  return RotationZyx(e.x(), e.y(), e.z()) * (accel - x.segment<3>(Idx::kAccelBias)) -
         BodyZ(e.x(), e.y(), e.z()) * (thrust * vehicle.bias.thrust_scale / vehicle.mass);
}

Vec3 LandedAccel(const VehicleStateVec& x) {
  const double phi = x(Idx::kEuler), theta = x(Idx::kEuler + 1);
  return kGravity * Vec3(-std::sin(theta), std::cos(theta) * std::sin(phi),
                         std::cos(theta) * std::cos(phi)) +
         x.segment<3>(Idx::kAccelBias);
}

Mat<3, VehicleStateIndex::kSize> LandedAccelJacobian(const VehicleStateVec& x) {
  const double cf = std::cos(x(Idx::kEuler)), sf = std::sin(x(Idx::kEuler));
  const double ct = std::cos(x(Idx::kEuler + 1)), st = std::sin(x(Idx::kEuler + 1));
  Mat<3, kN> H = Mat<3, kN>::Zero();
  H.block<3, 1>(0, Idx::kEuler) = kGravity * Vec3(0.0, ct * cf, -ct * sf);
  H.block<3, 1>(0, Idx::kEuler + 1) = kGravity * Vec3(-ct, -st * sf, -st * cf);
  H.block<3, 3>(0, Idx::kAccelBias).setIdentity();
  return H;
}

int VehicleEkfConfig::BufferCapacity() const {
  if (buffer_capacity > 0) return buffer_capacity;
  const auto rate = [](const SensorSpec& s) { return s.enabled ? s.rate_hz : 0.0; };
  return ReplayCapacity(max_lag,
                        {rate(sensors.mocap), rate(sensors.imu), rate(sensors.optical_flow),
                         rate(sensors.compass), command_rate_hz});
}

VehicleEkf::VehicleEkf(const VehicleEkfConfig& config, const model::VehicleParams& vehicle)
    : config_(config),
      vehicle_(vehicle),
      buffer_((config.Validate(), config.BufferCapacity()), config.max_lag) {
  vehicle_.Validate();
  for (int d = 1; d <= 6; ++d)
    gate_[static_cast<std::size_t>(d)] = Chi2Quantile(config_.gate_probability, d);
}

EkfCounters VehicleEkf::counters() const {
  EkfCounters c = counters_;
  c.replays = buffer_.replays();
  c.buffer_overflows = buffer_.overflows();
  c.gate_resets = s_.gate_resets;
  c.mode_switches = s_.mode_switches;
  return c;
}

void VehicleEkf::InitState(double t, const Vec3& position, const Vec3& euler, State* s) const {
  const SensorsConfig& sc = config_.sensors;
  s->initialized = true;
  s->time = t;
  s->x.setZero();
  s->x.segment<3>(Idx::kPos) = position;
  s->x.segment<3>(Idx::kEuler) = euler;
  s->x(Idx::kEuler + 2) = WrapAngle(euler.z());
  s->P.setZero();
  s->P.diagonal().segment<3>(Idx::kPos) = sc.mocap.noise.array().square();
  s->P.diagonal().segment<3>(Idx::kVel).setConstant(config_.initial_velocity_std *
                                                    config_.initial_velocity_std);
  s->P.diagonal().segment<3>(Idx::kEuler) = sc.mocap.noise2.array().square();
  s->P.diagonal()
      .segment<3>(Idx::kAccelBias)
      .setConstant(config_.initial_accel_bias_std * config_.initial_accel_bias_std);
  s->P.diagonal()
      .segment<3>(Idx::kGyroBias)
      .setConstant(config_.initial_gyro_bias_std * config_.initial_gyro_bias_std);
  ResetDisturbance(s);
  s->mode = config_.initial_mode;
  s->ground_z = s->mode == VehicleMode::kLanded ? position.z() : config_.ground_height;
  s->origin = position;
  s->takeoff_evidence = {};
  s->takeoff_since = kNaN;
  s->land_since = kNaN;
  s->consecutive_gated = {};
  s->last_fused.fill(kNaN);
}

void VehicleEkf::ResetDisturbance(State* s) const {
  s->x.segment<3>(Idx::kDisturbance).setZero();
  s->P.middleRows<3>(Idx::kDisturbance).setZero();
  s->P.middleCols<3>(Idx::kDisturbance).setZero();
  s->P.diagonal()
      .segment<3>(Idx::kDisturbance)
      .setConstant(config_.initial_disturbance_std * config_.initial_disturbance_std);
}

void VehicleEkf::Initialize(double t, const Vec3& position, const Vec3& euler) {
  ++revision_;
  if (!std::isfinite(t) || !position.allFinite() || !euler.allFinite()) {
    throw std::invalid_argument("[VehicleEkf] Initialize needs a finite time and pose, got t=" +
                                std::to_string(t));
  }
  buffer_.Clear();
  time_jump_.Reset();
  InitState(t, position, euler, &s_);
}

bool VehicleEkf::TimeJumpRejected(double t) {
  const TimeJumpGuard::Verdict v =
      time_jump_.Check(t, s_.time, config_.max_time_jump, config_.time_jump_reset_count);
  if (v != TimeJumpGuard::Verdict::kReanchor) return v == TimeJumpGuard::Verdict::kReject;
  // The clock really moved on: re-anchor at t without integrating the gap. The state is
  // kept; velocity, position and attitude variances are raised to cover the unknown gap.
  ++counters_.time_resets;
  buffer_.Clear();
  if (s_.initialized) {
    const double pv = config_.reset_position_std * config_.reset_position_std;
    const double vv = config_.initial_velocity_std * config_.initial_velocity_std;
    const double ev = config_.reset_attitude_std * config_.reset_attitude_std;
    for (int i = 0; i < 3; ++i) {
      s_.P(Idx::kPos + i, Idx::kPos + i) += pv;
      s_.P(Idx::kVel + i, Idx::kVel + i) = std::max(s_.P(Idx::kVel + i, Idx::kVel + i), vv);
      s_.P(Idx::kEuler + i, Idx::kEuler + i) += ev;
    }
    s_.takeoff_since = kNaN;
    s_.land_since = kNaN;
  }
  s_.time = t;
  return false;
}

bool VehicleEkf::CommandFresh(double t, const State& s) const {
  return std::isfinite(s.command_stamp) && t - s.command_stamp <= config_.command_timeout;
}

EkfStatus VehicleEkf::SetCommand(double t, double thrust, double roll_ref, double pitch_ref,
                                 double yaw_ref, const Vec3& known_acceleration) {
  ++revision_;
  if (!std::isfinite(t) || !std::isfinite(thrust) || !std::isfinite(roll_ref) ||
      !std::isfinite(pitch_ref) || !std::isfinite(yaw_ref) || !known_acceleration.allFinite()) {
    ++counters_.commands_rejected;
    return EkfStatus::kRejectedNonFinite;
  }
  if (TimeJumpRejected(t)) {
    ++counters_.commands_rejected;
    return EkfStatus::kRejectedTimeJump;
  }
  Event e;
  e.stamp = t;
  e.order = 0;
  e.is_command = true;
  e.command = {thrust, roll_ref, pitch_ref, yaw_ref, known_acceleration};
  const EkfStatus st = buffer_.Submit(
      e, &s_, [this](const Event& ev, State* s) { return Apply(ev, s); },
      [this](const Event& ev, EkfStatus from, EkfStatus to) {
        if (!ev.is_command) counters_.Move(ev.m.kind, from, to);
      });
  if (st == EkfStatus::kAccepted) {
    ++counters_.commands;
  } else {
    ++counters_.commands_rejected;
  }
  return st;
}

EkfStatus VehicleEkf::Process(const Measurement& m) {
  ++revision_;
  const int kind = static_cast<int>(m.kind);
  if (kind < 0 || kind >= kNumSensorKinds) return EkfStatus::kRejectedInvalid;
  const auto finish = [&](EkfStatus st) {
    counters_.Add(m.kind, st);
    return st;
  };
  if (config_.vehicle >= 0 && m.vehicle != config_.vehicle) {
    return finish(EkfStatus::kRejectedInvalid);
  }
  const SensorsConfig& sc = config_.sensors;
  bool finite = std::isfinite(m.stamp);
  switch (m.kind) {
    case SensorKind::kMocapPose:
      if (!sc.mocap.enabled) return finish(EkfStatus::kRejectedInvalid);
      finite = finite && m.position.allFinite() && m.euler.allFinite();
      break;
    case SensorKind::kImu:
      if (!sc.imu.enabled) return finish(EkfStatus::kRejectedInvalid);
      finite = finite && m.accel.allFinite() && m.gyro.allFinite();
      if (finite && (m.accel.norm() > config_.max_specific_force ||
                     m.gyro.norm() > config_.max_angular_rate)) {
        return finish(EkfStatus::kRejectedInvalid);
      }
      break;
    case SensorKind::kOpticalFlow:
      if (!sc.optical_flow.enabled) return finish(EkfStatus::kRejectedInvalid);
      finite = finite && m.velocity.allFinite();
      break;
    case SensorKind::kCompass:
      if (!sc.compass.enabled) return finish(EkfStatus::kRejectedInvalid);
      finite = finite && std::isfinite(m.yaw);
      break;
    default:
      return finish(EkfStatus::kIgnored);
  }
  if (!finite) return finish(EkfStatus::kRejectedNonFinite);
  if (TimeJumpRejected(m.stamp)) return finish(EkfStatus::kRejectedTimeJump);
  Event e;
  e.stamp = m.stamp;
  e.order = 1 + kind;
  e.m = m;
  const EkfStatus st = buffer_.Submit(
      e, &s_, [this](const Event& ev, State* s) { return Apply(ev, s); },
      [this](const Event& ev, EkfStatus from, EkfStatus to) {
        if (!ev.is_command) counters_.Move(ev.m.kind, from, to);
      });
  return finish(st);
}

EkfStatus VehicleEkf::Apply(const Event& e, State* s) const {
  if (!e.is_command) return ApplyMeasurement(e.m, s);
  if (s->initialized) {
    Predict(e.stamp, s);
  } else {
    s->time = e.stamp;
  }
  s->command = e.command;
  s->command_stamp = e.stamp;
  if (s->initialized && s->mode == VehicleMode::kLanded) {
    const double ratio = e.command.thrust * vehicle_.bias.thrust_scale / (vehicle_.mass * kGravity);
    UpdateTakeoffEvidence(kEvidenceThrust, ratio > config_.takeoff_thrust_ratio, e.stamp, s);
  } else if (s->initialized) {
    CheckLanding(e.stamp, s);
  }
  return EkfStatus::kAccepted;
}

template <int M>
EkfStatus VehicleEkf::Update(SensorKind kind, const Vec<M>& y, const Mat<M, kN>& H,
                             const Mat<M, M>& R, State* s) const {
  int& consecutive = s->consecutive_gated[static_cast<std::size_t>(kind)];
  UpdateResult r = KalmanUpdate<kN, M>(y, H, R, gate_[M], &s->x, &s->P);
  if (r.status == EkfStatus::kRejectedGated) {
    if (++consecutive < config_.max_consecutive_gated) return r.status;
    // Persistent disagreement: the filter, not the sensor, is likely wrong. Re-inflate the
    // measured states by the innovation and fuse without the gate.
    s->P += H.transpose() * y.array().square().matrix().asDiagonal() * H;
    ++s->gate_resets;
    r = KalmanUpdate<kN, M>(y, H, R, kInf, &s->x, &s->P);
  }
  if (r.status == EkfStatus::kAccepted) {
    consecutive = 0;
    s->x(Idx::kEuler + 2) = WrapAngle(s->x(Idx::kEuler + 2));
  }
  return r.status;
}

EkfStatus VehicleEkf::ApplyMeasurement(const Measurement& m, State* s) const {
  const SensorsConfig& sc = config_.sensors;
  if (!s->initialized) {
    if (m.kind == SensorKind::kMocapPose) {
      InitState(m.stamp, m.position, m.euler, s);
      s->last_fused[static_cast<std::size_t>(m.kind)] = m.stamp;
      return EkfStatus::kAccepted;
    }
    s->time = m.stamp;
    return EkfStatus::kNotInitialized;
  }
  Predict(m.stamp, s);
  const bool landed = s->mode == VehicleMode::kLanded;
  EkfStatus status = EkfStatus::kAccepted;
  switch (m.kind) {
    case SensorKind::kImu: {
      s->imu_accel = m.accel;
      s->imu_gyro = m.gyro;
      s->imu_stamp = m.stamp;
      if (landed) {
        const Vec3 e = s->x.segment<3>(Idx::kEuler);
        const Vec3 a_world =
            RotationZyx(e.x(), e.y(), e.z()) * (m.accel - s->x.segment<3>(Idx::kAccelBias)) -
            Vec3(0.0, 0.0, kGravity);
        UpdateTakeoffEvidence(kEvidenceImu, a_world.norm() > config_.takeoff_accel, m.stamp, s);
      }
      if (s->mode == VehicleMode::kLanded) {
        // The resting model's error bounds the IMU's std from below: with the sensor's noise
        // alone, a near-ideal IMU fused the settling at placement as a bias and then gated
        // every later sample (docs/estimation.md, "Landed").
        const Mat3 Ra =
            sc.imu.noise.cwiseMax(config_.landed_accel_std).array().square().matrix().asDiagonal();
        const Mat3 Rg =
            sc.imu.noise2.cwiseMax(config_.landed_gyro_std).array().square().matrix().asDiagonal();
        const EkfStatus sa =
            Update<3>(m.kind, m.accel - LandedAccel(s->x), LandedAccelJacobian(s->x), Ra, s);
        Mat<3, kN> Hg = Mat<3, kN>::Zero();
        Hg.block<3, 3>(0, Idx::kGyroBias).setIdentity();
        const EkfStatus sg = Update<3>(m.kind, m.gyro - s->x.segment<3>(Idx::kGyroBias), Hg, Rg, s);
        // Zero-velocity pseudo-measurement (no gate: it is a model constraint).
        Mat<3, kN> Hv = Mat<3, kN>::Zero();
        Hv.block<3, 3>(0, Idx::kVel).setIdentity();
        const Mat3 Rv = Mat3::Identity() * (config_.zupt_std * config_.zupt_std);
        const Vec3 yv = -s->x.segment<3>(Idx::kVel);
        KalmanUpdate<kN, 3>(yv, Hv, Rv, kInf, &s->x, &s->P);
        status = sa != EkfStatus::kAccepted ? sa : sg;
      } else if (config_.motion_model != MotionModel::kImu) {
        status = EkfStatus::kIgnored;
      } else if (CommandFresh(m.stamp, *s)) {
        UpdateDisturbance(m, s);
      }
      break;
    }
    case SensorKind::kMocapPose: {
      if (landed) {
        UpdateTakeoffEvidence(kEvidenceHeight,
                              m.position.z() - s->ground_z > config_.takeoff_height, m.stamp, s);
      }
      Vec<6> y;
      y.head<3>() = m.position - s->x.segment<3>(Idx::kPos);
      y.tail<3>() = m.euler - s->x.segment<3>(Idx::kEuler);
      y(5) = WrapAngle(y(5));
      Mat<6, kN> H = Mat<6, kN>::Zero();
      H.block<3, 3>(0, Idx::kPos).setIdentity();
      H.block<3, 3>(3, Idx::kEuler).setIdentity();
      Vec<6> var;
      var.head<3>() = sc.mocap.noise.array().square();
      var.tail<3>() = sc.mocap.noise2.array().square();
      status = Update<6>(m.kind, y, H, var.asDiagonal().toDenseMatrix(), s);
      break;
    }
    case SensorKind::kOpticalFlow: {
      if (landed) {
        UpdateTakeoffEvidence(kEvidenceFlow, m.velocity.norm() > config_.takeoff_speed, m.stamp, s);
      }
      Mat<3, kN> H = Mat<3, kN>::Zero();
      H.block<3, 3>(0, Idx::kVel).setIdentity();
      const Mat3 R = sc.optical_flow.noise.array().square().matrix().asDiagonal();
      status = Update<3>(m.kind, m.velocity - s->x.segment<3>(Idx::kVel), H, R, s);
      break;
    }
    case SensorKind::kCompass: {
      Vec<1> y(WrapAngle(m.yaw - s->x(Idx::kEuler + 2)));
      Mat<1, kN> H = Mat<1, kN>::Zero();
      H(0, Idx::kEuler + 2) = 1.0;
      const Mat<1, 1> R(sc.compass.noise.x() * sc.compass.noise.x());
      status = Update<1>(m.kind, y, H, R, s);
      break;
    }
    default:
      return EkfStatus::kIgnored;
  }
  // Fresh for the health check: fused, or valid but not needed in this mode; the IMU is an
  // input even when its landed updates are gated.
  if (status == EkfStatus::kAccepted || status == EkfStatus::kIgnored ||
      m.kind == SensorKind::kImu) {
    s->last_fused[static_cast<std::size_t>(m.kind)] = m.stamp;
  }
  if (s->mode == VehicleMode::kLanded) {
    s->ground_z = s->x(Idx::kPos + 2);
  } else {
    CheckLanding(m.stamp, s);
  }
  return status;
}

// IMU pseudo-measurement of d: 0 = UnexplainedAcceleration(x) - d + noise. Only the d
// columns of H are kept (attitude and accelerometer bias taken as known): d stays
// uncorrelated with the other states in the IMU model, which then do not depend on d. Noise per
// sample: the IMU's white noise plus the thrust model's error density at the IMU rate (the
// command is held between control steps, the motors lag it). No gate: a model constraint
// like the ZUPT; a failed update (non-finite) leaves the state as it was.
void VehicleEkf::UpdateDisturbance(const Measurement& m, State* s) const {
  const SensorsConfig& sc = config_.sensors;
  const Vec3 y = UnexplainedAcceleration(s->x, m.accel, s->command.thrust, vehicle_) -
                 s->command.known_acceleration - s->x.segment<3>(Idx::kDisturbance);
  const double model_var =
      config_.command_accel_noise * config_.command_accel_noise * sc.imu.rate_hz;
  const Mat3 R = (sc.imu.noise.array().square() + model_var).matrix().asDiagonal();
  if (s->P.block<Idx::kDisturbance, 3>(0, Idx::kDisturbance).isZero(0.0)) {
    // d uncorrelated with the rest (always so with the IMU model, see above): the gain is
    // zero outside d, and the update is that of d alone (d, Pd untouched if it fails).
    Vec3 d = s->x.segment<3>(Idx::kDisturbance);
    Mat3 Pd = s->P.block<3, 3>(Idx::kDisturbance, Idx::kDisturbance);
    KalmanUpdate<3, 3>(y, Mat3::Identity(), R, kInf, &d, &Pd);
    s->x.segment<3>(Idx::kDisturbance) = d;
    s->P.block<3, 3>(Idx::kDisturbance, Idx::kDisturbance) = Pd;
    return;
  }
  Mat<3, kN> H = Mat<3, kN>::Zero();
  H.block<3, 3>(0, Idx::kDisturbance).setIdentity();
  KalmanUpdate<kN, 3>(y, H, R, kInf, &s->x, &s->P);
}

void VehicleEkf::UpdateTakeoffEvidence(int index, bool evidence, double t, State* s) const {
  if (!config_.auto_mode_switch || s->mode != VehicleMode::kLanded) return;
  s->takeoff_evidence[static_cast<std::size_t>(index)] = evidence;
  bool any = false;
  for (bool b : s->takeoff_evidence) any = any || b;
  if (!any) {
    s->takeoff_since = kNaN;
    return;
  }
  if (!std::isfinite(s->takeoff_since)) s->takeoff_since = t;
  if (t - s->takeoff_since >= config_.takeoff_hold) SwitchMode(VehicleMode::kFlying, s);
}

void VehicleEkf::CheckLanding(double t, State* s) const {
  if (!config_.auto_mode_switch || s->mode != VehicleMode::kFlying) return;
  bool low = s->x(Idx::kPos + 2) - s->ground_z < config_.land_height &&
             s->x.segment<3>(Idx::kVel).norm() < config_.land_speed;
  if (low && CommandFresh(t, *s)) {
    low = s->command.thrust * vehicle_.bias.thrust_scale <
          config_.land_thrust_ratio * vehicle_.mass * kGravity;
  }
  if (!low) {
    s->land_since = kNaN;
    return;
  }
  if (!std::isfinite(s->land_since)) s->land_since = t;
  if (t - s->land_since >= config_.land_hold) SwitchMode(VehicleMode::kLanded, s);
}

void VehicleEkf::SwitchMode(VehicleMode mode, State* s) const {
  s->mode = mode;
  ++s->mode_switches;
  s->takeoff_evidence = {};
  s->takeoff_since = kNaN;
  s->land_since = kNaN;
  if (mode == VehicleMode::kFlying) {
    ResetDisturbance(s);  // the ground's reaction is not carried into the flight
    const double pv = config_.takeoff_position_std * config_.takeoff_position_std;
    const double vv = config_.takeoff_velocity_std * config_.takeoff_velocity_std;
    for (int i = 0; i < 3; ++i) {
      s->P(Idx::kPos + i, Idx::kPos + i) += pv;
      s->P(Idx::kVel + i, Idx::kVel + i) += vv;
    }
  } else {
    s->ground_z = s->x(Idx::kPos + 2);
  }
}

void VehicleEkf::Predict(double t, State* s) const {
  if (!(t > s->time)) return;
  const double dt = t - s->time;
  // Callers keep dt within max(max_time_jump, max_extrapolation) (events beyond are rejected,
  // Estimate caps its target); the cap here only bounds the work, computed before the int
  // cast so that no stamp (1e300) can overflow it.
  const double max_steps = std::ceil(std::max(config_.max_time_jump, config_.max_extrapolation) /
                                     config_.max_predict_dt);
  double steps = std::ceil(dt / config_.max_predict_dt - 1e-9);
  if (!(steps <= max_steps)) steps = max_steps;
  const int n = std::max(1, static_cast<int>(steps));
  const double h = dt / n;
  for (int i = 0; i < n; ++i) {
    PredictStep(h, s);
    s->time += h;
  }
  s->time = t;
}

void VehicleEkf::PredictStep(double h, State* s) const {
  const SensorsConfig& sc = config_.sensors;
  VehicleStateCov Q = VehicleStateCov::Zero();
  const double qba = config_.accel_bias_noise * config_.accel_bias_noise * h;
  const double qbg = config_.gyro_bias_noise * config_.gyro_bias_noise * h;
  Q.diagonal().segment<3>(Idx::kAccelBias).setConstant(qba);
  Q.diagonal().segment<3>(Idx::kGyroBias).setConstant(qbg);
  const double qd = config_.disturbance_noise * config_.disturbance_noise * h;
  if (s->mode == VehicleMode::kLanded) {
    // d is not observed on the ground (held; reset at take-off): no process noise.
    const double qp = config_.landed_position_noise * config_.landed_position_noise * h;
    const double qe = config_.landed_attitude_noise * config_.landed_attitude_noise * h;
    Q.diagonal().segment<3>(Idx::kPos).setConstant(qp);
    Q.diagonal().segment<3>(Idx::kVel).setConstant(qp);
    Q.diagonal().segment<3>(Idx::kEuler).setConstant(qe);
    s->P += Q;
    Symmetrize<kN>(&s->P);
    return;
  }
  // White acceleration noise q [(m/s^2)^2 / Hz] on v, integrated into p.
  const auto add_accel_noise = [&](double q) {
    for (int i = 0; i < 3; ++i) {
      Q(Idx::kPos + i, Idx::kPos + i) += q * h * h * h / 3.0;
      Q(Idx::kPos + i, Idx::kVel + i) += q * h * h / 2.0;
      Q(Idx::kVel + i, Idx::kPos + i) += q * h * h / 2.0;
      Q(Idx::kVel + i, Idx::kVel + i) += q * h;
    }
  };
  Q.diagonal().segment<3>(Idx::kDisturbance).setConstant(qd);
  VehicleStateCov A;
  VehicleStateVec x_mid, x_new;
  const bool imu_ok = config_.motion_model == MotionModel::kImu && std::isfinite(s->imu_stamp) &&
                      s->time - s->imu_stamp <= config_.imu_timeout;
  if (imu_ok) {
    A = ImuFlowJacobian(s->x, s->imu_accel, s->imu_gyro);
    x_mid = s->x + 0.5 * h * ImuFlow(s->x, s->imu_accel, s->imu_gyro);
    x_new = s->x + h * ImuFlow(x_mid, s->imu_accel, s->imu_gyro);
    // Per-sample white noise sigma at the IMU rate is a density sigma^2 / rate.
    const Vec3 qa = sc.imu.noise.array().square() / sc.imu.rate_hz;
    const Vec3 qg = sc.imu.noise2.array().square() / sc.imu.rate_hz;
    add_accel_noise(qa.mean());
    const Vec3 e = s->x.segment<3>(Idx::kEuler);
    const Mat3 T = EulerRateMatrix(e.x(), e.y());
    Q.block<3, 3>(Idx::kEuler, Idx::kEuler) += T * qg.asDiagonal() * T.transpose() * h;
  } else if (config_.motion_model == MotionModel::kCommand) {
    double thrust = vehicle_.mass * kGravity / vehicle_.bias.thrust_scale;
    VehicleStateVec known = VehicleStateVec::Zero();  // SetCommand's known acceleration on v'
    const Vec3 e = s->x.segment<3>(Idx::kEuler);
    // Without a fresh command: hover thrust and hold the current attitude.
    Vec3 refs(e.x() / vehicle_.attitude_gain.x() - vehicle_.bias.roll,
              e.y() / vehicle_.attitude_gain.y() - vehicle_.bias.pitch,
              e.z() / vehicle_.attitude_gain.z());
    if (CommandFresh(s->time, *s)) {
      thrust = s->command.thrust;
      refs = Vec3(s->command.roll, s->command.pitch, s->command.yaw);
      known.segment<3>(Idx::kVel) = s->command.known_acceleration;
    }
    A = CommandFlowJacobian(s->x, thrust, refs, vehicle_);
    x_mid = s->x + 0.5 * h * (CommandFlow(s->x, thrust, refs, vehicle_) + known);
    x_new = s->x + h * (CommandFlow(x_mid, thrust, refs, vehicle_) + known);
    add_accel_noise(config_.command_accel_noise * config_.command_accel_noise);
    Q.diagonal().segment<3>(Idx::kEuler).array() +=
        config_.command_attitude_noise * config_.command_attitude_noise * h;
  } else {
    // IMU missing or stale: constant velocity with a large acceleration noise.
    A.setZero();
    A.block<3, 3>(Idx::kPos, Idx::kVel).setIdentity();
    x_new = s->x;
    x_new.segment<3>(Idx::kPos) += h * s->x.segment<3>(Idx::kVel);
    add_accel_noise(config_.fallback_accel_noise * config_.fallback_accel_noise);
    Q.diagonal().segment<3>(Idx::kEuler).array() +=
        config_.command_attitude_noise * config_.command_attitude_noise * h;
  }
  s->x = x_new;
  s->x(Idx::kEuler + 2) = WrapAngle(s->x(Idx::kEuler + 2));
  PropagateCovariance(A, h, Q, &s->P);
}

void VehicleEkf::FillHealth(const State& st, double t_query, EstimateHealth* h) const {
  h->flags = 0;
  h->stale_kinds = 0;
  h->extrapolation = t_query - st.time;
  const auto max_std = [&](int first) {
    return std::sqrt(st.P.diagonal().segment<3>(first).maxCoeff());
  };
  h->position_std = max_std(Idx::kPos);
  h->velocity_std = max_std(Idx::kVel);
  h->attitude_std = max_std(Idx::kEuler);
  if (!std::isfinite(t_query) || !st.x.allFinite() || !st.P.allFinite()) {
    h->Set(HealthFlag::kNonFinite);
  }
  const bool absolute_fix =
      std::isfinite(st.last_fused[static_cast<std::size_t>(SensorKind::kMocapPose)]);
  if (absolute_fix && !(h->position_std <= config_.max_position_std)) {
    h->Set(HealthFlag::kPositionUncertain);
  }
  if (!(h->velocity_std <= config_.max_velocity_std)) h->Set(HealthFlag::kVelocityUncertain);
  if (!(h->attitude_std <= config_.max_attitude_std)) h->Set(HealthFlag::kAttitudeUncertain);
  if (!(std::abs(st.x(Idx::kEuler + 1)) <= config_.max_pitch)) {
    h->Set(HealthFlag::kAttitudeEnvelope);
  }
  for (int k = 0; k < kNumSensorKinds; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const double last = st.last_fused[i];
    h->staleness[i] = std::isfinite(last) ? t_query - last : kInf;
    const bool monitored = std::isfinite(config_.max_staleness[i]) &&
                           (std::isfinite(last) || !config_.stale_after_first_fix);
    if (monitored && !(h->staleness[i] <= config_.max_staleness[i])) {
      h->stale_kinds |= 1u << static_cast<unsigned>(k);
      h->Set(HealthFlag::kStale);
    }
  }
}

VehicleEstimate VehicleEkf::Estimate(double t) const {
  VehicleEstimate out;
  if (!s_.initialized) return out;
  State st = s_;
  bool extrapolation_limit = false;
  if (std::isfinite(t)) {
    double target = t;
    if (t - st.time > config_.max_extrapolation) {
      target = st.time + config_.max_extrapolation;
      extrapolation_limit = true;
    }
    Predict(target, &st);
  }
  FillHealth(st, std::isfinite(t) ? std::max(t, st.time) : t, &out.health);
  if (extrapolation_limit) out.health.Set(HealthFlag::kExtrapolationLimit);
  out.valid = out.health.ok();
  out.time = st.time;
  out.mode = st.mode;
  out.x = st.x;
  out.covariance = st.P;
  out.position = st.x.segment<3>(Idx::kPos);
  out.position_mpc = out.position - st.origin;
  out.velocity = st.x.segment<3>(Idx::kVel);
  out.euler = st.x.segment<3>(Idx::kEuler);
  out.accel_bias = st.x.segment<3>(Idx::kAccelBias);
  out.gyro_bias = st.x.segment<3>(Idx::kGyroBias);
  out.disturbance = st.x.segment<3>(Idx::kDisturbance);
  return out;
}

}  // namespace fnmpc::estimation
