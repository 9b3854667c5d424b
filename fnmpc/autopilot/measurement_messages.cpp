// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/autopilot/measurement_messages.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <variant>

#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/mavlink/frame_conversions.hpp"

namespace fnmpc::autopilot {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
// HIGHRES_IMU_UPDATED_FLAGS: xacc..zacc, xgyro..zgyro.
constexpr std::uint16_t kImuAccelGyro = 0x3F;

bool Usec(double stamp, std::uint64_t* out) {
  if (!(stamp >= 0.0 && stamp < 1e12)) return false;
  *out = static_cast<std::uint64_t>(std::llround(stamp * 1e6));
  return true;
}

float F(double v) { return static_cast<float>(v); }
Vec3 V(float x, float y, float z) { return {x, y, z}; }

}  // namespace

bool ToMessage(const Measurement& m, mavlink::Message* out) {
  std::uint64_t t = 0;
  if (!Usec(m.stamp, &t)) return false;
  switch (m.kind) {
    case SensorKind::kImu: {
      if (!m.accel.allFinite() || !m.gyro.allFinite()) return false;
      mavlink::HighresImu imu;
      imu.time_usec = t;
      const Vec3 a = mavlink::FluToFrd(m.accel), w = mavlink::FluToFrd(m.gyro);
      imu.xacc = F(a.x());
      imu.yacc = F(a.y());
      imu.zacc = F(a.z());
      imu.xgyro = F(w.x());
      imu.ygyro = F(w.y());
      imu.zgyro = F(w.z());
      imu.fields_updated = kImuAccelGyro;
      *out = imu;
      return true;
    }
    case SensorKind::kMocapPose: {
      if (!m.position.allFinite() || !m.euler.allFinite()) return false;
      mavlink::Odometry o;
      o.time_usec = t;
      const Vec3 p = mavlink::EnuToNed(m.position);
      o.x = F(p.x());
      o.y = F(p.y());
      o.z = F(p.z());
      const Eigen::Quaterniond q(RotationZyx(m.euler.x(), m.euler.y(), m.euler.z()));
      o.q = mavlink::QuaternionToWxyz(mavlink::EnuFluToNedFrd(q).normalized());
      o.vx = o.vy = o.vz = kNaNf;
      o.rollspeed = o.pitchspeed = o.yawspeed = kNaNf;
      o.pose_covariance[0] = kNaNf;
      o.velocity_covariance[0] = kNaNf;
      o.frame_id = mav::kFrameLocalNed;
      o.child_frame_id = mav::kFrameBodyFrd;
      o.estimator_type = mav::kEstimatorMocap;
      *out = o;
      return true;
    }
    case SensorKind::kOpticalFlow: {
      if (!m.velocity.allFinite()) return false;
      mavlink::Odometry o;
      o.time_usec = t;
      o.x = o.y = o.z = kNaNf;
      o.q = {kNaNf, kNaNf, kNaNf, kNaNf};
      const Vec3 v = mavlink::EnuToNed(m.velocity);
      o.vx = F(v.x());
      o.vy = F(v.y());
      o.vz = F(v.z());
      o.rollspeed = o.pitchspeed = o.yawspeed = kNaNf;
      o.pose_covariance[0] = kNaNf;
      o.velocity_covariance[0] = kNaNf;
      o.frame_id = mav::kFrameLocalNed;
      o.child_frame_id = mav::kFrameLocalNed;  // velocity in the world frame
      o.estimator_type = mav::kEstimatorVio;
      *out = o;
      return true;
    }
    case SensorKind::kBattery: {
      if (!(m.voltage >= 0.0 && m.voltage < 65.5)) return false;
      mavlink::SysStatus s;
      s.onboard_control_sensors_present = mav::kSensorBattery;
      s.onboard_control_sensors_enabled = mav::kSensorBattery;
      s.onboard_control_sensors_health = mav::kSensorBattery;
      s.voltage_battery = static_cast<std::uint16_t>(std::lround(m.voltage * 1000.0));
      s.current_battery = -1;
      s.battery_remaining = -1;
      *out = s;
      return true;
    }
    case SensorKind::kRelative: {
      const RelativeObservation& r = m.relative;
      if (r.target < 0 || r.target > 254 || !std::isfinite(r.range) || !std::isfinite(r.bearing) ||
          !std::isfinite(r.elevation) || !std::isfinite(r.relative_yaw)) {
        return false;
      }
      mavlink::FnmpcRelativeObservation o;
      o.time_usec = t;
      o.range = F(r.range);
      o.bearing = F(r.bearing);
      o.elevation = F(r.elevation);
      o.relative_yaw = F(r.relative_yaw);
      o.target_system = SystemIdOf(r.target);
      *out = o;
      return true;
    }
    case SensorKind::kCompass: {
      // The heading alone: roll, pitch and the rates are not measured.
      if (!std::isfinite(m.yaw) || !(m.stamp < 4294967.0)) return false;
      mavlink::Attitude a;
      a.time_boot_ms = static_cast<std::uint32_t>(std::llround(m.stamp * 1e3));
      a.roll = a.pitch = kNaNf;
      a.yaw = F(mavlink::EulerEnuFluToNedFrd(Vec3(0.0, 0.0, m.yaw)).z());
      a.rollspeed = a.pitchspeed = a.yawspeed = kNaNf;
      *out = a;
      return true;
    }
  }
  return false;
}

bool FromMessage(const mavlink::Message& message, int vehicle, double time_offset, double now,
                 Measurement* out) {
  Measurement m;
  m.vehicle = vehicle;
  m.arrival = now;
  if (const auto* imu = std::get_if<mavlink::HighresImu>(&message)) {
    if ((imu->fields_updated & kImuAccelGyro) != kImuAccelGyro) return false;
    m.kind = SensorKind::kImu;
    m.stamp = static_cast<double>(imu->time_usec) * 1e-6 + time_offset;
    m.accel = mavlink::FrdToFlu(V(imu->xacc, imu->yacc, imu->zacc));
    m.gyro = mavlink::FrdToFlu(V(imu->xgyro, imu->ygyro, imu->zgyro));
    if (!m.accel.allFinite() || !m.gyro.allFinite()) return false;
  } else if (const auto* o = std::get_if<mavlink::Odometry>(&message)) {
    if (o->frame_id != mav::kFrameLocalNed) return false;
    m.stamp = static_cast<double>(o->time_usec) * 1e-6 + time_offset;
    if (o->estimator_type == mav::kEstimatorMocap && o->child_frame_id == mav::kFrameBodyFrd) {
      const Eigen::Quaterniond q = mavlink::QuaternionFromWxyz(o->q);
      if (!std::isfinite(q.norm()) || q.norm() < 0.5) return false;
      m.kind = SensorKind::kMocapPose;
      m.position = mavlink::NedToEnu(V(o->x, o->y, o->z));
      m.euler = EulerZyx(mavlink::NedFrdToEnuFlu(q.normalized()).toRotationMatrix());
      if (!m.position.allFinite()) return false;
    } else if (o->estimator_type == mav::kEstimatorVio &&
               o->child_frame_id == mav::kFrameLocalNed) {
      m.kind = SensorKind::kOpticalFlow;
      m.velocity = mavlink::NedToEnu(V(o->vx, o->vy, o->vz));
      if (!m.velocity.allFinite()) return false;
    } else {
      return false;
    }
  } else if (const auto* a = std::get_if<mavlink::Attitude>(&message)) {
    if (!std::isfinite(a->yaw)) return false;
    m.kind = SensorKind::kCompass;
    m.stamp = static_cast<double>(a->time_boot_ms) * 1e-3 + time_offset;
    m.yaw = mavlink::EulerNedFrdToEnuFlu(Vec3(0.0, 0.0, a->yaw)).z();
  } else if (const auto* s = std::get_if<mavlink::SysStatus>(&message)) {
    if ((s->onboard_control_sensors_present & mav::kSensorBattery) == 0 ||
        s->voltage_battery == UINT16_MAX) {
      return false;
    }
    m.kind = SensorKind::kBattery;
    m.stamp = now;
    m.voltage = s->voltage_battery * 1e-3;
  } else if (const auto* r = std::get_if<mavlink::FnmpcRelativeObservation>(&message)) {
    m.kind = SensorKind::kRelative;
    m.stamp = static_cast<double>(r->time_usec) * 1e-6 + time_offset;
    m.relative.target = VehicleOf(r->target_system);
    m.relative.range = r->range;
    m.relative.bearing = r->bearing;
    m.relative.elevation = r->elevation;
    m.relative.relative_yaw = r->relative_yaw;
    if (m.relative.target < 0) return false;
  } else {
    return false;
  }
  *out = m;
  return true;
}

void ClockMap::Observe(double remote, double local) {
  if (!std::isfinite(remote) || !std::isfinite(local)) return;
  if (count_ > 0 && remote < last_remote_ - reset_after_) {
    count_ = 0;  // the remote clock restarted
    ++resets_;
  }
  last_remote_ = remote;
  if (count_ == 0) {
    samples_[0] = {remote, local};
    count_ = 1;
    bucket_start_ = remote;
    rate_ = 1.0;
    Fit();
    return;
  }
  Sample& open = samples_[count_ - 1];
  if (remote - bucket_start_ >= bucket_) {
    // Close the open bucket (the oldest closed one goes when all are in use) and open one.
    if (count_ == kBuckets + 1) {
      std::copy(samples_.begin() + 1, samples_.end(), samples_.begin());
      --count_;
    }
    samples_[count_++] = {remote, local};
    bucket_start_ = remote;
  } else if (local - rate_ * remote < open.local - rate_ * open.remote) {
    open = {remote, local};  // less delayed than the bucket's best so far
  } else {
    return;
  }
  Fit();
}

void ClockMap::Fit() {
  // Rate: least-squares slope through the buckets' minima once two buckets are closed.
  double rate = 1.0;
  if (count_ >= 3) {
    double mr = 0.0, ml = 0.0;
    for (int i = 0; i < count_; ++i) {
      mr += samples_[i].remote;
      ml += samples_[i].local;
    }
    mr /= count_;
    ml /= count_;
    double srr = 0.0, srl = 0.0;
    for (int i = 0; i < count_; ++i) {
      srr += (samples_[i].remote - mr) * (samples_[i].remote - mr);
      srl += (samples_[i].remote - mr) * (samples_[i].local - ml);
    }
    const double fitted = srr > 0.0 ? srl / srr : 1.0;
    if (fitted >= 0.5 && fitted <= 2.0) rate = fitted;
  }
  rate_ = rate;
  // Offset: the line with that slope under every minimum (the least delay).
  remote0_ = samples_[count_ - 1].remote;
  double lowest = kInf;
  for (int i = 0; i < count_; ++i) {
    lowest = std::min(lowest, samples_[i].local - rate_ * (samples_[i].remote - remote0_));
  }
  local0_ = lowest;
}

}  // namespace fnmpc::autopilot
