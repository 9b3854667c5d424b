// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>

#include "fnmpc/core/types.hpp"

/// A follower's estimate of a neighbour's acceleration and the neighbour prediction that uses
/// it (string stability down the graph, docs/results.md "Scale").
///
/// Why: with each follower regulating a constant offset to neighbours predicted at constant
/// velocity, a leader manoeuvre reaches row i only through row i-1's position and velocity
/// errors, which a constant-spacing predecessor-following loop amplifies from row to row
/// whatever its gains (Seiler, Pant, Hedrick, "Disturbance propagation in vehicle strings",
/// IEEE TAC 49(10), 2004). Feeding the predecessor's acceleration forward is what makes
/// cooperative adaptive cruise control string-stable at short spacings (Naus, Vugts, Ploeg,
/// van de Molengraft, Steinbuch, "String-stable CACC design and experimental validation: a
/// frequency-domain approach", IEEE TVT 59(9), 2010); without a radio link the predecessor's
/// acceleration can be estimated from the on-board relative sensing and still recovers most of
/// that benefit (Ploeg, Semsar-Kazerooni, Lijster, van de Wouw, Nijmeijer, "Graceful
/// degradation of cooperative adaptive cruise control", IEEE T-ITS 16(1), 2015). Here the
/// estimate is the filtered derivative of the neighbour filter's velocity, and the prediction
/// lets it decay as the mean of Singer's first-order Markov manoeuvre model (Singer,
/// "Estimating optimal tracking filter performance for manned maneuvering targets", IEEE TAES
/// 6(4), 1970): a manoeuvre seen now is assumed to fade over the decay time, not to last for
/// the whole horizon.
namespace fnmpc::formation {

/// First-order low-pass filtered derivative of an estimated velocity, sampled at the control
/// steps: a <- a + dt / (tau + dt) * ((v - v_prev) / dt - a). Restarts (a = 0) after a
/// non-finite sample, a time step that is not positive or a gap longer than max_gap.
class AccelerationEstimate {
 public:
  AccelerationEstimate() = default;
  /// filter_time: tau [s] (>= 0); max_gap: longest step still differentiated [s].
  AccelerationEstimate(double filter_time, double max_gap)
      : filter_time_(filter_time), max_gap_(max_gap) {}

  /// The estimate after the velocity v [m/s] at time t [s]; zero (and a restart) when v is
  /// not finite.
  const Vec3& Update(double t, const Vec3& v) {
    if (!v.allFinite() || !std::isfinite(t)) {
      Reset();
      return a_;
    }
    const double dt = t - t_prev_;
    if (std::isfinite(t_prev_) && dt > 0.0 && dt <= max_gap_) {
      const Vec3 derivative = (v - v_prev_) / dt;
      a_ += dt / (filter_time_ + dt) * (derivative - a_);
    } else {
      a_.setZero();
    }
    t_prev_ = t;
    v_prev_ = v;
    return a_;
  }
  void Reset() {
    a_.setZero();
    t_prev_ = kNaN;
    v_prev_.setConstant(kNaN);
  }
  [[nodiscard]] const Vec3& value() const { return a_; }

 private:
  double filter_time_ = 0.1, max_gap_ = 0.2;
  double t_prev_ = kNaN;
  Vec3 v_prev_ = Vec3::Constant(kNaN);
  Vec3 a_ = Vec3::Zero();
};

/// Mean prediction of a neighbour at time t ahead [s] from its relative position rel [m],
/// velocity vel [m/s] and acceleration acc [m/s^2] now, the acceleration decaying as
/// exp(-t / decay) (Singer's model): a(t) = acc e^{-t/T}, v(t) = vel + acc T (1 - e^{-t/T}),
/// r(t) = rel + vel t + acc T (t - T (1 - e^{-t/T})). decay = 0: constant velocity (acc
/// ignored); decay = kInf: constant acceleration.
inline void DecayingAccelerationPrediction(const Vec3& rel, const Vec3& vel, const Vec3& acc,
                                           double decay, double t, Vec3* rel_t, Vec3* vel_t) {
  *rel_t = rel + t * vel;
  *vel_t = vel;
  if (!(decay > 0.0) || t <= 0.0) return;
  double dv = 0.0, dr = 0.0;  // the factors of acc in v(t) - vel and in r(t) - rel - vel t
  if (std::isinf(decay)) {
    dv = t;
    dr = 0.5 * t * t;
  } else {
    const double fade = -std::expm1(-t / decay);  // 1 - e^{-t/T}, exact for small t / T
    dv = decay * fade;
    dr = decay * (t - decay * fade);
  }
  *vel_t += dv * acc;
  *rel_t += dr * acc;
}

/// The neighbour filter's mixed mean acceleration [m/s^2]: the estimate `acc` (the filtered
/// derivative of the mixed velocity) times the manoeuvring mode's probability, the hover mode's
/// mean acceleration being zero (interacting multiple model, NeighbourEkf); a NaN
/// hover_probability (one model, or estimates given from outside) leaves `acc` as it is.
inline Vec3 MixedAcceleration(double hover_probability, const Vec3& acc) {
  return std::isfinite(hover_probability) ? (1.0 - hover_probability) * acc : acc;
}

}  // namespace fnmpc::formation
