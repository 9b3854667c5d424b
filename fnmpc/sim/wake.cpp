// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/wake.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fnmpc::sim {

namespace {

void RequirePositive(double v, const char* name) {
  if (!(v > 0.0) || !std::isfinite(v)) {
    throw std::invalid_argument(std::string("[WakeTurbulenceSettings] ") + name +
                                " must be finite and > 0, got " + std::to_string(v));
  }
}

/// K = v_h sqrt(4 ln2 A / pi): U_c = K / r_half away from the rotors.
double JetConstant(const DownwashSettings& s, double thrust) {
  const double area = 4.0 * M_PI * s.rotor_radius * s.rotor_radius;
  return HoverInducedVelocity(s, thrust) * std::sqrt(4.0 * M_LN2 * area / M_PI);
}

}  // namespace

void WakeTurbulenceSettings::Validate() const {
  if (!(axial_intensity >= 0.0 && radial_intensity >= 0.0 && axial_intensity < 1.0 &&
        radial_intensity < 1.0)) {
    throw std::invalid_argument("[WakeTurbulenceSettings] intensities must be in [0, 1)");
  }
  RequirePositive(intensity_half_width, "intensity_half_width");
  RequirePositive(integral_length, "integral_length");
  RequirePositive(history, "history");
  RequirePositive(sample_period, "sample_period");
  if (history / sample_period > 1e5) {
    throw std::invalid_argument("[WakeTurbulenceSettings] history / sample_period above 1e5");
  }
}

double WakeHalfWidth(const DownwashSettings& s, double dist) {
  return s.wake_radius + s.spreading_rate * std::max(0.0, dist);
}

double WakeCentrelineVelocity(const DownwashSettings& s, double thrust, double dist) {
  const double v_h = HoverInducedVelocity(s, thrust);
  if (v_h <= 0.0) return 0.0;
  return std::min(s.exit_velocity_factor * v_h, JetConstant(s, thrust) / WakeHalfWidth(s, dist));
}

double WakeTravelTime(const DownwashSettings& s, double thrust, double dist) {
  const double v_h = HoverInducedVelocity(s, thrust);
  if (v_h <= 0.0 || dist <= 0.0) return dist <= 0.0 ? 0.0 : kInf;
  const double k = JetConstant(s, thrust);
  const double cap = s.exit_velocity_factor * v_h;
  const double r0 = s.wake_radius, rate = s.spreading_rate;
  // Capped (constant cap) up to s_cap where K / r_half(s_cap) = cap, then dt = r_half ds / K.
  const double s_cap = std::clamp((k / cap - r0) / rate, 0.0, dist);
  auto uncapped = [&](double a, double b) {
    return (r0 * (b - a) + 0.5 * rate * (b * b - a * a)) / k;
  };
  return s_cap / cap + uncapped(s_cap, dist);
}

void WakeSources::Add(const Vec3& position, const Vec3& thrust_axis) {
  lo = lo.cwiseMin(position);
  hi = hi.cwiseMax(position);
  min_axis_z = std::min(min_axis_z, thrust_axis.z());
}

double WakeHorizontalReach(const DownwashSettings& s, const WakeSources& sources, double lowest_z) {
  if (!(sources.hi.z() >= sources.lo.z())) return 0.0;  // no source
  const double cos_tilt = std::min(1.0, sources.min_axis_z);
  const double sin_tilt = std::sqrt(std::max(0.0, 1.0 - cos_tilt * cos_tilt));
  const double c = s.cutoff_half_widths;
  const double denominator = cos_tilt - c * s.spreading_rate * sin_tilt;
  if (!(denominator > 0.0)) return kInf;
  const double depth = std::max(0.0, sources.hi.z() - lowest_z + c * s.wake_radius * sin_tilt);
  const double deepest = depth / denominator;
  return deepest * sin_tilt + c * (s.wake_radius + s.spreading_rate * deepest);
}

double WakeTop(const DownwashSettings& s, const WakeSources& sources) {
  const double cos_tilt = std::min(1.0, sources.min_axis_z);
  const double sin_tilt = std::sqrt(std::max(0.0, 1.0 - cos_tilt * cos_tilt));
  return sources.hi.z() + s.cutoff_half_widths * s.wake_radius * sin_tilt;
}

WakeHistory::WakeHistory(const DownwashSettings& downwash, const WakeTurbulenceSettings& turb)
    : dw_(downwash), turb_(turb) {
  turb_.Validate();
  ring_.resize(static_cast<std::size_t>(std::ceil(turb_.history / turb_.sample_period)) + 2);
}

void WakeHistory::Record(double t, const Vec3& position, const Vec3& thrust_axis, double thrust) {
  if (size_ > 0 && t < ring_[head_].t + turb_.sample_period - 1e-9) return;
  head_ = (head_ + 1) % static_cast<int>(ring_.size());
  ring_[head_] = {t, position, thrust_axis, thrust};
  size_ = std::min(size_ + 1, static_cast<int>(ring_.size()));
  const int n = static_cast<int>(ring_.size());
  sources_ = WakeSources{};
  for (int k = 0; k < size_; ++k) {
    const Sample& x = ring_[(head_ - k + n) % n];
    sources_.Add(x.position, x.axis);
  }
}

const WakeHistory::Sample& WakeHistory::At(double t) const {
  // Newest sample not after t (the oldest kept one when t is older still).
  const int n = static_cast<int>(ring_.size());
  const int back = static_cast<int>(std::floor((ring_[head_].t - t) / turb_.sample_period + 1e-9));
  const int k = std::clamp(back, 0, size_ - 1);
  return ring_[(head_ - k + n) % n];
}

Vec3 WakeHistory::MeanVelocity(double t, const Vec3& point, double* centreline, double* half_width,
                               Vec3* axis, double* radius) const {
  if (centreline) *centreline = 0.0;
  if (half_width) *half_width = dw_.wake_radius;
  if (axis) *axis = Vec3::UnitZ();
  if (radius) *radius = 0.0;
  if (size_ == 0) return Vec3::Zero();
  // The air at `point` left the rotors tau ago: two fixed-point passes from tau = 0.
  const Sample* s = &ring_[head_];
  for (int pass = 0; pass < 2; ++pass) {
    const double dist = -(point - s->position).dot(s->axis);
    if (dist <= 0.0) break;
    s = &At(t - WakeTravelTime(dw_, s->thrust, dist));
  }
  const Vec3 d = point - s->position;
  const double dist = -d.dot(s->axis);
  if (dist <= 0.0 || s->thrust <= 0.0) return Vec3::Zero();
  const double r = (d + dist * s->axis).norm();
  const double hw = WakeHalfWidth(dw_, dist);
  if (r > dw_.cutoff_half_widths * hw) return Vec3::Zero();
  if (centreline) *centreline = WakeCentrelineVelocity(dw_, s->thrust, dist);
  if (half_width) *half_width = hw;
  if (axis) *axis = s->axis;
  if (radius) *radius = r;
  return DownwashVelocity(dw_, s->position, s->axis, s->thrust, point);
}

WakeFluctuation::WakeFluctuation(const WakeTurbulenceSettings& settings, std::uint64_t seed,
                                 int source, int observer)
    : s_(settings) {
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    static_cast<std::uint32_t>(source), static_cast<std::uint32_t>(observer),
                    0x3A4Eu};
  rng_.seed(seq);
  g_ = Vec3(normal_(rng_), normal_(rng_), normal_(rng_));  // stationary start
}

void WakeFluctuation::Step(double dt, double centreline, double half_width) {
  if (!(centreline > 0.0)) return;
  const double tau = s_.integral_length * half_width / centreline;
  const double phi = std::exp(-dt / tau);
  const double sd = std::sqrt(1.0 - phi * phi);
  for (int a = 0; a < 3; ++a) g_[a] = phi * g_[a] + sd * normal_(rng_);
}

Vec3 WakeFluctuation::Velocity(const Vec3& axis, double centreline, double half_width,
                               double radius) const {
  if (!(centreline > 0.0)) return Vec3::Zero();
  const double eta = radius / (s_.intensity_half_width * half_width);
  const double scale = centreline * std::exp(-M_LN2 * eta * eta);
  // Two radial directions perpendicular to the axis.
  const Vec3 e1 = axis.unitOrthogonal();
  const Vec3 e2 = axis.cross(e1);
  return scale * (s_.axial_intensity * g_.x() * (-axis) + s_.radial_intensity * g_.y() * e1 +
                  s_.radial_intensity * g_.z() * e2);
}

}  // namespace fnmpc::sim
