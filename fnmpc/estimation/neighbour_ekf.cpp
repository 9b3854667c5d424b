// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/estimation/neighbour_ekf.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/estimation/ekf_math.hpp"

namespace fnmpc::estimation {
namespace {

using Idx = NeighbourStateIndex;
constexpr int kN = Idx::kSize;

void Require(bool ok, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string("[NeighbourEkfConfig] ") + field + " " + what +
                                ", got " + std::to_string(value));
  }
}

// d h_{range, bearing, elevation} / d d_B, d_B the offset in the observer body frame.
Mat3 SphericalJacobian(const Vec3& d) {
  const double rho2 = d.x() * d.x() + d.y() * d.y();
  const double rho = std::sqrt(rho2);
  const double r2 = rho2 + d.z() * d.z();
  const double r = std::sqrt(r2);
  Mat3 J;
  J.row(0) = d.transpose() / r;
  J.row(1) << -d.y() / rho2, d.x() / rho2, 0.0;
  J.row(2) << -d.x() * d.z() / (rho * r2), -d.y() * d.z() / (rho * r2), rho / r2;
  return J;
}

}  // namespace

void NeighbourEkfConfig::Validate() const {
  Require(max_lag >= 0.0 && std::isfinite(max_lag), "max_lag", max_lag, "must be >= 0");
  Require(buffer_capacity == 0 || buffer_capacity >= 2, "buffer_capacity", buffer_capacity,
          "must be 0 (derived) or >= 2");
  Require(own_velocity_rate_hz > 0.0 && std::isfinite(own_velocity_rate_hz), "own_velocity_rate_hz",
          own_velocity_rate_hz, "must be finite and > 0");
  Require(accel_noise > 0.0, "accel_noise", accel_noise, "must be > 0");
  Require(hover_accel_noise >= 0.0 && hover_accel_noise < accel_noise, "hover_accel_noise",
          hover_accel_noise, "must be >= 0 (0: one model) and < accel_noise");
  Require(hover_sojourn > 0.0 && std::isfinite(hover_sojourn), "hover_sojourn", hover_sojourn,
          "must be finite and > 0");
  Require(manoeuvre_sojourn > 0.0 && std::isfinite(manoeuvre_sojourn), "manoeuvre_sojourn",
          manoeuvre_sojourn, "must be finite and > 0");
  Require(yaw_accel_noise > 0.0, "yaw_accel_noise", yaw_accel_noise, "must be > 0");
  Require(own_velocity_noise >= 0.0, "own_velocity_noise", own_velocity_noise, "must be >= 0");
  Require(initial_velocity_std > 0.0, "initial_velocity_std", initial_velocity_std, "must be > 0");
  Require(initial_yaw_rate_std > 0.0, "initial_yaw_rate_std", initial_yaw_rate_std, "must be > 0");
  Require(gate_probability > 0.0 && gate_probability < 1.0, "gate_probability", gate_probability,
          "must be in (0, 1)");
  Require(max_consecutive_gated >= 1, "max_consecutive_gated", max_consecutive_gated,
          "must be >= 1");
  const SensorSpec& r = sensors.relative;
  Require((r.noise.array() > 0.0).all(), "sensors.relative.noise", r.noise.minCoeff(),
          "must be > 0");
  Require(r.noise2.x() > 0.0, "sensors.relative.noise2[0]", r.noise2.x(), "must be > 0");
  Require(r.range_noise_growth >= 0.0, "sensors.relative.range_noise_growth", r.range_noise_growth,
          "must be >= 0");
  Require(relative_update == RelativeUpdate::kCartesian ||
              relative_update == RelativeUpdate::kSpherical,
          "relative_update", static_cast<double>(relative_update), "must be a RelativeUpdate");
  Require(max_position_std > 0.0, "max_position_std", max_position_std, "must be > 0 (kInf: off)");
  Require(max_velocity_std > 0.0, "max_velocity_std", max_velocity_std, "must be > 0 (kInf: off)");
  Require(max_yaw_std > 0.0, "max_yaw_std", max_yaw_std, "must be > 0 (kInf: off)");
  Require(max_staleness > 0.0, "max_staleness", max_staleness, "must be > 0 (kInf: off)");
  Require(max_extrapolation >= 0.0 && std::isfinite(max_extrapolation), "max_extrapolation",
          max_extrapolation, "must be finite and >= 0");
  Require(max_time_jump > 0.0 && std::isfinite(max_time_jump), "max_time_jump", max_time_jump,
          "must be finite and > 0");
  Require(time_jump_reset_count >= 1, "time_jump_reset_count", time_jump_reset_count,
          "must be >= 1");
}

int NeighbourEkfConfig::BufferCapacity() const {
  if (buffer_capacity > 0) return buffer_capacity;
  const double relative = sensors.relative.enabled ? sensors.relative.rate_hz : 0.0;
  return ReplayCapacity(max_lag, {relative, own_velocity_rate_hz});
}

void RelativeToCartesian(const RelativeObservation& o, const Vec3& own_euler,
                         const Mat3& own_euler_cov, const SensorSpec& spec, Vec<4>* z,
                         Mat<4, 4>* R) {
  const double r = o.range;
  const double cb = std::cos(o.bearing), sb = std::sin(o.bearing);
  const double ce = std::cos(o.elevation), se = std::sin(o.elevation);
  const Vec3 d(r * ce * cb, r * ce * sb, r * se);  // offset in the observer's body frame
  Mat3 Rot;
  std::array<Mat3, 3> dR;
  RotationZyxPartials(own_euler, &Rot, &dR);
  z->head<3>() = Rot * d;
  (*z)(3) = WrapAngle(own_euler.z() + o.relative_yaw);
  // d / d(range, bearing, elevation): the bearing column r cos(el) (-sin b, cos b, 0) vanishes
  // at +-90 deg, where the bearing carries no information; nothing divides by it.
  const Vec3 azimuth(-sb, cb, 0.0);
  Mat<4, 4> Gz = Mat<4, 4>::Zero();
  Gz.block<3, 1>(0, 0) = Rot * Vec3(ce * cb, ce * sb, se);
  Gz.block<3, 1>(0, 1) = Rot * (r * ce * azimuth);
  Gz.block<3, 1>(0, 2) = Rot * Vec3(-r * se * cb, -r * se * sb, r * ce);
  Gz(3, 3) = 1.0;
  Mat<4, 3> Ge = Mat<4, 3>::Zero();
  for (int i = 0; i < 3; ++i) Ge.block<3, 1>(0, i) = dR[static_cast<std::size_t>(i)] * d;
  Ge(3, 2) = 1.0;
  const double sr = spec.noise.x() * (1.0 + spec.range_noise_growth * r);
  const double vb = spec.noise.y() * spec.noise.y(), ve = spec.noise.z() * spec.noise.z();
  const Vec<4> var(sr * sr, vb, ve, spec.noise2.x() * spec.noise2.x());
  *R = Gz * var.asDiagonal() * Gz.transpose() + Ge * own_euler_cov * Ge.transpose();
  // Second order: the azimuthal offset r cos(el + e_n) sin(b_n) has variance
  // r^2 (cos^2 el + sin^2 el sigma_e^2) sigma_b^2; the linear part has only the first term.
  const Vec3 a = Rot * azimuth;
  R->topLeftCorner<3, 3>() += (r * r * vb * ve * se * se) * (a * a.transpose());
  Symmetrize<4>(R);
}

Vec<4> RelativeMeasurementModel(const NeighbourStateVec& x, const Vec3& own_euler) {
  const Vec3 d = RotationZyx(own_euler.x(), own_euler.y(), own_euler.z()).transpose() *
                 x.segment<3>(Idx::kRelPos);
  const double r = d.norm();
  return {r, std::atan2(d.y(), d.x()), std::asin(d.z() / r),
          WrapAngle(x(Idx::kYaw) - own_euler.z())};
}

Mat<4, NeighbourStateIndex::kSize> RelativeMeasurementJacobian(const NeighbourStateVec& x,
                                                               const Vec3& own_euler) {
  const Mat3 R = RotationZyx(own_euler.x(), own_euler.y(), own_euler.z());
  const Vec3 d = R.transpose() * x.segment<3>(Idx::kRelPos);
  Mat<4, kN> H = Mat<4, kN>::Zero();
  H.block<3, 3>(0, Idx::kRelPos) = SphericalJacobian(d) * R.transpose();
  H(3, Idx::kYaw) = 1.0;
  return H;
}

Mat<4, 3> RelativeMeasurementOwnAttitudeJacobian(const NeighbourStateVec& x,
                                                 const Vec3& own_euler) {
  Mat3 R;
  std::array<Mat3, 3> dR;
  RotationZyxPartials(own_euler, &R, &dR);
  const Vec3 dx = x.segment<3>(Idx::kRelPos);
  Mat3 dd;
  for (int i = 0; i < 3; ++i) dd.col(i) = dR[static_cast<std::size_t>(i)].transpose() * dx;
  Mat<4, 3> J = Mat<4, 3>::Zero();
  J.topRows<3>() = SphericalJacobian(R.transpose() * dx) * dd;
  J(3, 2) = -1.0;
  return J;
}

NeighbourEkf::NeighbourEkf(const NeighbourEkfConfig& config)
    : config_(config), buffer_((config.Validate(), config.BufferCapacity()), config.max_lag) {
  gate_ = Chi2Quantile(config_.gate_probability, 4);
  s_.x.setConstant(kNaN);
}

EkfCounters NeighbourEkf::counters() const {
  EkfCounters c = counters_;
  c.replays = buffer_.replays();
  c.buffer_overflows = buffer_.overflows();
  c.gate_resets = s_.gate_resets;
  return c;
}

double NeighbourEkf::hover_probability() const {
  return s_.initialized && multiple_model() ? s_.mu[kHover] : kNaN;
}

NeighbourStateVec NeighbourEkf::state() const {
  return s_.initialized ? s_.x : NeighbourStateVec::Constant(kNaN);
}

NeighbourEkf::State NeighbourEkf::PredictedCopy(double t, const Vec3& own_velocity,
                                                bool* capped) const {
  State st = s_;
  *capped = false;
  if (!std::isfinite(t) || !own_velocity.allFinite()) return st;
  double target = t;
  if (t - st.time > config_.max_extrapolation) {
    target = st.time + config_.max_extrapolation;
    *capped = true;
  }
  Predict(target, own_velocity, &st);
  return st;
}

NeighbourStateVec NeighbourEkf::StateAt(double t, const Vec3& own_velocity) const {
  if (!s_.initialized) return NeighbourStateVec::Constant(kNaN);
  bool capped = false;
  return PredictedCopy(t, own_velocity, &capped).x;
}

NeighbourEstimate NeighbourEkf::EstimateAt(double t, const Vec3& own_velocity) const {
  NeighbourEstimate out;
  if (!s_.initialized) return out;
  bool capped = false;
  const State st = PredictedCopy(t, own_velocity, &capped);
  EstimateHealth& h = out.health;
  h.flags = 0;
  const double tq = std::isfinite(t) ? std::max(t, st.time) : t;
  h.extrapolation = tq - st.time;
  h.position_std = std::sqrt(st.P.diagonal().segment<3>(Idx::kRelPos).maxCoeff());
  h.velocity_std = std::sqrt(st.P.diagonal().segment<3>(Idx::kVel).maxCoeff());
  h.attitude_std = std::sqrt(st.P(Idx::kYaw, Idx::kYaw));
  const auto rel = static_cast<std::size_t>(SensorKind::kRelative);
  h.staleness[rel] = tq - st.last_fused;
  if (!std::isfinite(tq) || !own_velocity.allFinite() || !st.x.allFinite() || !st.P.allFinite()) {
    h.Set(HealthFlag::kNonFinite);
  }
  if (!(h.position_std <= config_.max_position_std)) h.Set(HealthFlag::kPositionUncertain);
  if (!(h.velocity_std <= config_.max_velocity_std)) h.Set(HealthFlag::kVelocityUncertain);
  if (!(h.attitude_std <= config_.max_yaw_std)) h.Set(HealthFlag::kAttitudeUncertain);
  if (std::isfinite(config_.max_staleness) && !(h.staleness[rel] <= config_.max_staleness)) {
    h.stale_kinds |= 1u << static_cast<unsigned>(SensorKind::kRelative);
    h.Set(HealthFlag::kStale);
  }
  if (capped) h.Set(HealthFlag::kExtrapolationLimit);
  out.valid = h.ok();
  out.time = st.time;
  out.x = st.x;
  out.covariance = st.P;
  return out;
}

void NeighbourEkf::Retarget(int target) {
  config_.target = target;
  buffer_.Clear();
  time_jump_.Reset();
  const std::int64_t gate_resets = s_.gate_resets;
  s_ = State{};
  s_.x.setConstant(kNaN);
  s_.gate_resets = gate_resets;
}

bool NeighbourEkf::TimeJumpRejected(double t) {
  const TimeJumpGuard::Verdict v =
      time_jump_.Check(t, s_.time, config_.max_time_jump, config_.time_jump_reset_count);
  if (v != TimeJumpGuard::Verdict::kReanchor) return v == TimeJumpGuard::Verdict::kReject;
  // The clock really moved on: forget the neighbour; the next measurement re-initialises it.
  ++counters_.time_resets;
  buffer_.Clear();
  s_.initialized = false;
  s_.x.setConstant(kNaN);
  s_.time = kNaN;
  s_.own_velocity.setConstant(kNaN);
  s_.consecutive_gated = 0;
  s_.last_fused = kNaN;
  return false;
}

EkfStatus NeighbourEkf::PredictTo(double t, const Vec3& own_velocity) {
  if (!std::isfinite(t) || !own_velocity.allFinite()) {
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
  e.own_velocity = own_velocity;
  const EkfStatus st = buffer_.Submit(
      e, &s_, [this](const Event& ev, State* s) { return Apply(ev, s); },
      [this](const Event& ev, EkfStatus from, EkfStatus to) {
        if (ev.order == 1) counters_.Move(SensorKind::kRelative, from, to);
      });
  if (st == EkfStatus::kAccepted) {
    ++counters_.commands;
  } else {
    ++counters_.commands_rejected;
  }
  return st;
}

EkfStatus NeighbourEkf::Process(const Measurement& m, const Vec3& own_euler,
                                const Vec3& own_velocity, const Mat3* own_euler_cov) {
  const auto finish = [&](EkfStatus st) {
    counters_.Add(SensorKind::kRelative, st);
    return st;
  };
  if (m.kind != SensorKind::kRelative || !config_.sensors.relative.enabled ||
      (config_.observer >= 0 && m.vehicle != config_.observer) ||
      (config_.target >= 0 && m.relative.target != config_.target)) {
    return finish(EkfStatus::kRejectedInvalid);
  }
  const RelativeObservation& o = m.relative;
  if (!std::isfinite(m.stamp) || !std::isfinite(o.range) || !std::isfinite(o.bearing) ||
      !std::isfinite(o.elevation) || !std::isfinite(o.relative_yaw) || !own_euler.allFinite() ||
      !own_velocity.allFinite() || (own_euler_cov != nullptr && !own_euler_cov->allFinite())) {
    return finish(EkfStatus::kRejectedNonFinite);
  }
  if (!(o.range > 0.0) || std::abs(o.elevation) > 0.5 * M_PI) {
    return finish(EkfStatus::kRejectedInvalid);
  }
  if (TimeJumpRejected(m.stamp)) return finish(EkfStatus::kRejectedTimeJump);
  Event e;
  e.stamp = m.stamp;
  e.order = 1;
  e.m = m;
  e.own_euler = own_euler;
  e.own_velocity = own_velocity;
  if (own_euler_cov != nullptr) e.own_euler_cov = *own_euler_cov;
  return finish(buffer_.Submit(
      e, &s_, [this](const Event& ev, State* s) { return Apply(ev, s); },
      [this](const Event& ev, EkfStatus from, EkfStatus to) {
        if (ev.order == 1) counters_.Move(SensorKind::kRelative, from, to);
      }));
}

NeighbourStateCov NeighbourEkf::ProcessNoise(double h, double accel_noise) const {
  NeighbourStateCov Q = NeighbourStateCov::Zero();
  const double qa = accel_noise * accel_noise;
  const double qy = config_.yaw_accel_noise * config_.yaw_accel_noise;
  const double qo = config_.own_velocity_noise * config_.own_velocity_noise;
  for (int i = 0; i < 3; ++i) {
    Q(Idx::kRelPos + i, Idx::kRelPos + i) = qa * h * h * h / 3.0 + qo * h;
    Q(Idx::kRelPos + i, Idx::kVel + i) = qa * h * h / 2.0;
    Q(Idx::kVel + i, Idx::kRelPos + i) = qa * h * h / 2.0;
    Q(Idx::kVel + i, Idx::kVel + i) = qa * h;
  }
  Q(Idx::kYaw, Idx::kYaw) = qy * h * h * h / 3.0;
  Q(Idx::kYaw, Idx::kYawRate) = qy * h * h / 2.0;
  Q(Idx::kYawRate, Idx::kYaw) = qy * h * h / 2.0;
  Q(Idx::kYawRate, Idx::kYawRate) = qy * h;
  return Q;
}

void NeighbourEkf::Combine(State* s) {
  // Moment matching: x = sum mu_m x_m, P = sum mu_m (P_m + (x_m - x)(x_m - x)'); yaws are
  // mixed as offsets from the manoeuvring mode's (wrapped), never across the +-pi seam.
  const Mode& ref = s->mode[kManoeuvre];
  if (!(s->mu[kHover] > 0.0)) {
    s->x = ref.x;
    s->P = ref.P;
    return;
  }
  const auto offset = [&](const NeighbourStateVec& x) {
    NeighbourStateVec d = x - ref.x;
    d(Idx::kYaw) = WrapAngle(d(Idx::kYaw));
    return d;
  };
  NeighbourStateVec mean = NeighbourStateVec::Zero();
  for (int m = 0; m < kModes; ++m) mean += s->mu[m] * offset(s->mode[m].x);
  NeighbourStateCov P = NeighbourStateCov::Zero();
  for (int m = 0; m < kModes; ++m) {
    const NeighbourStateVec d = offset(s->mode[m].x) - mean;
    P += s->mu[m] * (s->mode[m].P + d * d.transpose());
  }
  s->x = ref.x + mean;
  s->x(Idx::kYaw) = WrapAngle(s->x(Idx::kYaw));
  s->P = P;
  Symmetrize<kN>(&s->P);
}

void NeighbourEkf::Predict(double t, const Vec3& own_velocity, State* s) const {
  const Vec3 v_prev = s->own_velocity.allFinite() ? s->own_velocity : own_velocity;
  if (!s->initialized || !(t > s->time)) {
    if (!s->initialized || !std::isfinite(s->time) || t >= s->time) {
      s->time = std::isfinite(s->time) ? std::max(s->time, t) : t;
      s->own_velocity = own_velocity;
    }
    return;
  }
  const double h = t - s->time;
  if (multiple_model()) {
    // Mixing (IMM step 1) with the mode switches of a continuous-time Markov chain over h:
    // leaving mode i with probability 1 - exp(-h / sojourn_i).
    const double leave[kModes] = {1.0 - std::exp(-h / config_.hover_sojourn),
                                  1.0 - std::exp(-h / config_.manoeuvre_sojourn)};
    Mat<kModes, kModes> pi;  // pi(i, j): from i to j
    pi << 1.0 - leave[0], leave[0], leave[1], 1.0 - leave[1];
    const Vec<kModes> c = pi.transpose() * s->mu;
    std::array<Mode, kModes> mixed{};
    for (int j = 0; j < kModes; ++j) {
      const Mode& ref = s->mode[j];
      NeighbourStateVec mean = NeighbourStateVec::Zero();
      std::array<NeighbourStateVec, kModes> d{};
      for (int i = 0; i < kModes; ++i) {
        d[i] = s->mode[i].x - ref.x;
        d[i](Idx::kYaw) = WrapAngle(d[i](Idx::kYaw));
        mean += (pi(i, j) * s->mu[i] / c[j]) * d[i];
      }
      mixed[j].x = ref.x + mean;
      mixed[j].P.setZero();
      for (int i = 0; i < kModes; ++i) {
        const NeighbourStateVec e = d[i] - mean;
        mixed[j].P += (pi(i, j) * s->mu[i] / c[j]) * (s->mode[i].P + e * e.transpose());
      }
    }
    s->mode = mixed;
    s->mu = c;
  }
  const Vec3 v_avg = 0.5 * (v_prev + own_velocity);
  NeighbourStateCov F = NeighbourStateCov::Identity();
  F.block<3, 3>(Idx::kRelPos, Idx::kVel) = Mat3::Identity() * h;
  F(Idx::kYaw, Idx::kYawRate) = h;
  for (int m = multiple_model() ? 0 : kManoeuvre; m < kModes; ++m) {
    Mode& mode = s->mode[m];
    mode.x.segment<3>(Idx::kRelPos) += h * (mode.x.segment<3>(Idx::kVel) - v_avg);
    mode.x(Idx::kYaw) = WrapAngle(mode.x(Idx::kYaw) + h * mode.x(Idx::kYawRate));
    mode.P = F * mode.P * F.transpose() +
             ProcessNoise(h, m == kHover ? config_.hover_accel_noise : config_.accel_noise);
    Symmetrize<kN>(&mode.P);
  }
  Combine(s);
  s->time = t;
  s->own_velocity = own_velocity;
}

Mat<4, 4> NeighbourEkf::NoiseCovariance(const Event& e, const NeighbourStateVec& x) const {
  const SensorSpec& spec = config_.sensors.relative;
  const double range = x.segment<3>(Idx::kRelPos).norm();
  const double sr = spec.noise.x() * (1.0 + spec.range_noise_growth * range);
  Mat<4, 4> R = Mat<4, 4>::Zero();
  R.diagonal() << sr * sr, spec.noise.y() * spec.noise.y(), spec.noise.z() * spec.noise.z(),
      spec.noise2.x() * spec.noise2.x();
  if (!e.own_euler_cov.isZero(0.0)) {
    const Mat<4, 3> J = RelativeMeasurementOwnAttitudeJacobian(x, e.own_euler);
    R += J * e.own_euler_cov * J.transpose();
  }
  return R;
}

void NeighbourEkf::InitFromMeasurement(const Event& e, State* s) const {
  Vec<4> z;
  Mat<4, 4> P4;
  RelativeToCartesian(e.m.relative, e.own_euler, e.own_euler_cov, config_.sensors.relative, &z,
                      &P4);
  const bool keep_motion = s->initialized;  // re-initialisation after repeated gating
  const Vec3 v = s->x.segment<3>(Idx::kVel);
  const double wz = s->x(Idx::kYawRate);
  const Mat3 Pv = s->P.block<3, 3>(Idx::kVel, Idx::kVel);
  const double Pw = s->P(Idx::kYawRate, Idx::kYawRate);
  s->x.setZero();
  s->x.segment<3>(Idx::kRelPos) = z.head<3>();
  s->x(Idx::kYaw) = z(3);
  // Covariance of (dx, psi_j): that of the converted measurement.
  s->P.setZero();
  s->P.topLeftCorner<3, 3>() = P4.topLeftCorner<3, 3>();
  s->P.block<3, 1>(Idx::kRelPos, Idx::kYaw) = P4.block<3, 1>(0, 3);
  s->P.block<1, 3>(Idx::kYaw, Idx::kRelPos) = P4.block<1, 3>(3, 0);
  s->P(Idx::kYaw, Idx::kYaw) = P4(3, 3);
  if (keep_motion) {
    s->x.segment<3>(Idx::kVel) = v;
    s->x(Idx::kYawRate) = wz;
    s->P.block<3, 3>(Idx::kVel, Idx::kVel) = Pv;
    s->P(Idx::kYawRate, Idx::kYawRate) = Pw;
  } else {
    s->P.block<3, 3>(Idx::kVel, Idx::kVel) =
        Mat3::Identity() * config_.initial_velocity_std * config_.initial_velocity_std;
    s->P(Idx::kYawRate, Idx::kYawRate) =
        config_.initial_yaw_rate_std * config_.initial_yaw_rate_std;
  }
  Symmetrize<kN>(&s->P);
  // Every mode starts from this estimate, the mode probabilities from the chain's
  // stationary distribution (sojourn times' shares).
  for (Mode& m : s->mode) {
    m.x = s->x;
    m.P = s->P;
  }
  if (multiple_model()) {
    const double sum = config_.hover_sojourn + config_.manoeuvre_sojourn;
    s->mu << config_.hover_sojourn / sum, config_.manoeuvre_sojourn / sum;
  } else {
    s->mu << 0.0, 1.0;
  }
  s->initialized = true;
  s->time = e.stamp;
  s->own_velocity = e.own_velocity;
  s->consecutive_gated = 0;
  s->last_fused = e.stamp;
}

EkfStatus NeighbourEkf::UpdateSpherical(const Event& e, const Mode& prior, Mode* m,
                                        UpdateResult* r) const {
  const RelativeObservation& o = e.m.relative;
  const Vec<4> h = RelativeMeasurementModel(prior.x, e.own_euler);
  const Vec<4> y(o.range - h(0), WrapAngle(o.bearing - h(1)), o.elevation - h(2),
                 WrapAngle(o.relative_yaw - h(3)));
  const Mat<4, kN> H = RelativeMeasurementJacobian(prior.x, e.own_euler);
  *r = KalmanUpdate<kN, 4>(y, H, NoiseCovariance(e, prior.x), gate_, &m->x, &m->P);
  return r->status;
}

EkfStatus NeighbourEkf::UpdateCartesian(const Vec<4>& z, const Mat<4, 4>& R, const Mode& prior,
                                        Mode* m, UpdateResult* r) const {
  Vec<4> y;
  y.head<3>() = z.head<3>() - prior.x.segment<3>(Idx::kRelPos);
  y(3) = WrapAngle(z(3) - prior.x(Idx::kYaw));
  Mat<4, kN> H = Mat<4, kN>::Zero();
  H.block<3, 3>(0, Idx::kRelPos).setIdentity();
  H(3, Idx::kYaw) = 1.0;
  *r = KalmanUpdate<kN, 4>(y, H, R, gate_, &m->x, &m->P);
  return r->status;
}

// Every mode's update; IMM step 3: mode probabilities times the Gaussian likelihoods of the
// innovations, N(y; 0, S) ~ exp(-(nis + log det S) / 2). The measurement is gated when every
// mode gates it; a mode that gates it alone keeps its prediction and loses weight.
EkfStatus NeighbourEkf::Update(const Event& e, State* s) const {
  std::array<Mode, kModes> updated = s->mode;
  std::array<UpdateResult, kModes> r{};
  const int first = multiple_model() ? 0 : kManoeuvre;
  bool any_accepted = false;
  const bool cartesian = config_.relative_update == RelativeUpdate::kCartesian;
  Vec<4> z;
  Mat<4, 4> R;
  if (cartesian) {
    RelativeToCartesian(e.m.relative, e.own_euler, e.own_euler_cov, config_.sensors.relative, &z,
                        &R);
  }
  for (int m = first; m < kModes; ++m) {
    const EkfStatus st = cartesian ? UpdateCartesian(z, R, s->mode[m], &updated[m], &r[m])
                                   : UpdateSpherical(e, s->mode[m], &updated[m], &r[m]);
    if (st == EkfStatus::kNumericalError) return st;
    any_accepted = any_accepted || st == EkfStatus::kAccepted;
  }
  if (!any_accepted) return EkfStatus::kRejectedGated;
  if (multiple_model()) {
    double best = -kInf;
    for (int m = 0; m < kModes; ++m) best = std::max(best, -0.5 * (r[m].nis + r[m].log_det_s));
    Vec<kModes> w;
    for (int m = 0; m < kModes; ++m) {
      w[m] = s->mu[m] * std::exp(-0.5 * (r[m].nis + r[m].log_det_s) - best);
    }
    const double sum = w.sum();
    if (!(sum > 0.0) || !std::isfinite(sum)) return EkfStatus::kNumericalError;
    // A floor keeps either mode recoverable (no probability decays to exactly zero).
    constexpr double kMinProbability = 1e-6;
    s->mu = (w / sum).cwiseMax(kMinProbability);
    s->mu /= s->mu.sum();
  }
  for (Mode& m : updated) m.x(Idx::kYaw) = WrapAngle(m.x(Idx::kYaw));
  s->mode = updated;
  Combine(s);
  return EkfStatus::kAccepted;
}

EkfStatus NeighbourEkf::Apply(const Event& e, State* s) const {
  if (e.order == 0) {
    Predict(e.stamp, e.own_velocity, s);
    return EkfStatus::kAccepted;
  }
  if (!s->initialized) {
    InitFromMeasurement(e, s);
    return EkfStatus::kAccepted;
  }
  Predict(e.stamp, e.own_velocity, s);
  const EkfStatus status = Update(e, s);
  if (status == EkfStatus::kAccepted) {
    s->consecutive_gated = 0;
    s->x(Idx::kYaw) = WrapAngle(s->x(Idx::kYaw));
    s->last_fused = e.stamp;
  } else if (status == EkfStatus::kRejectedGated &&
             ++s->consecutive_gated >= config_.max_consecutive_gated) {
    InitFromMeasurement(e, s);
    ++s->gate_resets;
    return EkfStatus::kAccepted;
  }
  return status;
}

}  // namespace fnmpc::estimation
