// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>
#include <cmath>

#include "fnmpc/core/types.hpp"

/// Offset-free attitude: an estimate of the constant roll and pitch
/// offset by which a vehicle's attitude loop misses its model, and the reference that cancels
/// it.
///
/// Why: the NMPC predicts angle' = (k ref - angle) / tau (model::QuadrotorModel). An autopilot
/// with a level-calibration bias b (or a biased own attitude estimate) settles at k (ref + b)
/// instead: a constant attitude error that the external-acceleration observer d does not see,
/// because d is evaluated at the *measured* attitude (docs/estimation.md). The vehicle then
/// holds a position offset of its own. The offset enters at the plant's input, so it is
/// estimated there, from the measured attitude and the references actually sent, through the
/// model's own discrete attitude map (exact for a held reference):
///   angle_{k+1} = a angle_k + (1 - a) (k ref_k + o),   a = exp(-dt / tau),
/// r = (angle_{k+1} - a angle_k) / (1 - a) - k ref_k, low-passed into o_hat (time constant
/// filter_time). Sending ref - o_hat / k makes the plant the NMPC's model again, so the OCP is
/// unchanged (input disturbance model of offset-free MPC: Pannocchia and Rawlings,
/// "Disturbance models for offset-free model-predictive control", AIChE J. 49(2), 2003).
/// The residual of a second-order true loop is not zero during a manoeuvre but averages out
/// over filter_time; in a hold it is exactly k b.
namespace fnmpc::formation {

class AttitudeOffset {
 public:
  AttitudeOffset() = default;
  /// tau, gain: the model's roll and pitch time constants [s] and gains [-] (> 0);
  /// filter_time: low-pass time constant of o_hat [s] (> 0); max_offset: |o_hat| bound [rad]
  /// (>= 0); max_gap: longest step still used [s].
  AttitudeOffset(const Vec<2>& tau, const Vec<2>& gain, double filter_time, double max_offset,
                 double max_gap)
      : tau_(tau),
        gain_(gain),
        filter_time_(filter_time),
        max_offset_(max_offset),
        max_gap_(max_gap) {}

  /// Forgets everything: o_hat = 0 (the model's own assumption).
  void Reset() {
    offset_.setZero();
    bounded_ = false;
    t_prev_ = kNaN;
    angle_prev_.setConstant(kNaN);
    sent_.setConstant(kNaN);
    observed_ = false;
  }

  /// The measured (roll, pitch) [rad] at time t [s], the reference sent at the previous call
  /// (Sent) having been held since. A non-finite sample, a step that is not positive or longer
  /// than max_gap, or no reference sent since the last sample updates nothing (the next sample
  /// starts again); o_hat stays finite and within +-max_offset (bounded() says when it was
  /// cut).
  void Observe(double t, const Vec<2>& angle) {
    const double dt = t - t_prev_;
    if (angle.allFinite() && std::isfinite(t) && angle_prev_.allFinite() && sent_.allFinite() &&
        dt > 0.0 && dt <= max_gap_) {
      const double w = 1.0 - std::exp(-dt / filter_time_);
      for (int i = 0; i < 2; ++i) {
        const double a = std::exp(-dt / tau_[i]);
        const double r = (angle[i] - a * angle_prev_[i]) / (1.0 - a) - gain_[i] * sent_[i];
        if (!std::isfinite(r)) continue;
        offset_[i] += w * (r - offset_[i]);
      }
      bounded_ = false;
      for (int i = 0; i < 2; ++i) {
        if (std::abs(offset_[i]) > max_offset_) {
          offset_[i] = std::clamp(offset_[i], -max_offset_, max_offset_);
          bounded_ = true;
        }
      }
    }
    t_prev_ = std::isfinite(t) && angle.allFinite() ? t : kNaN;
    angle_prev_ = angle;
    sent_.setConstant(kNaN);
    observed_ = true;
  }

  /// The (roll, pitch) reference [rad] sent after the last Observe, held until the next. A
  /// second reference before the next Observe makes the interval unusable (the held value is
  /// not known).
  void Sent(const Vec<2>& ref) {
    if (observed_) {
      sent_ = ref;
    } else {
      sent_.setConstant(kNaN);
    }
    observed_ = false;
  }

  /// o_hat: the attitude offset [rad] (angle units), finite, |o_hat_i| <= max_offset.
  [[nodiscard]] const Vec<2>& offset() const { return offset_; }
  /// o_hat / k: what to subtract from the NMPC's reference [rad].
  [[nodiscard]] Vec<2> reference_offset() const { return offset_.cwiseQuotient(gain_); }
  /// Whether the last update cut o_hat at +-max_offset.
  [[nodiscard]] bool bounded() const { return bounded_; }

 private:
  Vec<2> tau_ = Vec<2>::Constant(0.1);
  Vec<2> gain_ = Vec<2>::Ones();
  double filter_time_ = 2.0;
  double max_offset_ = 0.0;
  double max_gap_ = 0.2;
  Vec<2> offset_ = Vec<2>::Zero();
  bool bounded_ = false;
  double t_prev_ = kNaN;
  Vec<2> angle_prev_ = Vec<2>::Constant(kNaN);
  Vec<2> sent_ = Vec<2>::Constant(kNaN);
  bool observed_ = false;
};

}  // namespace fnmpc::formation
