// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/identification.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

#include "fnmpc/sysid/angles.hpp"
#include "fnmpc/sysid/pendulum.hpp"

namespace fnmpc::sysid {

namespace {

// Gaps in the attitude log (docs/sysid.md, "Gaps"): a step longer than this many median
// steps is a gap (a lost row at +-25 % jitter is still one), and the samples up to this long
// after it are left out of the fits (the response depends on what the reference did inside
// the gap until the loop has settled: 5 time constants of the slowest loop seen, 0.1 s).
constexpr double kGapFactor = 1.5;
constexpr double kGapSettle = 0.5;  // [s]
// Model selection (docs/sysid.md): held-out segments of at least this length, and the
// relative held-out RMS difference below which the choice is not made from the data.
constexpr double kMinSegment = 1.0;  // [s]
constexpr double kModelMarginThreshold = 0.05;

// Runs `body` as a stage: an exception marks the stage failed with its message.
template <class F>
void RunStage(Identification* out, StageReport* stage, F&& body) {
  try {
    body();
    stage->ok = true;
  } catch (const std::exception& e) {
    stage->ok = false;
    stage->reason = e.what();
    out->notices.push_back(
        fmt::format("fnmpc: error: sysid stage '{}' failed: {}", stage->name, e.what()));
  }
}

}  // namespace

Identification IdentifyVehicle(const IdentificationData& data,
                               const IdentificationSettings& settings) {
  Identification out;
  model::VehicleParams& v = out.vehicle;
  v.mass = data.mass;
  v.arm_length = data.arm_length;
  std::vector<std::string>& have = out.have;
  have = {"mass", "arm_length"};
  nlohmann::json& j = out.summary;
  j["mass"] = v.mass;

  // Stage 1: propulsion (thrust stand).
  StageReport prop_stage{"propulsion"};
  PropulsionFit prop;
  RunStage(&out, &prop_stage, [&] {
    const BenchData& bench = data.bench.Get();
    prop = FitPropulsion(bench);
    std::vector<double> fit_thr, fit_thrust, fit_torque;
    double thrust_mean = 0.0, torque_mean = 0.0;
    for (std::size_t i = 0; i < bench.throttle.size(); ++i) {
      fit_thr.push_back(prop.throttle.Throttle(bench.thrust[i], bench.voltage[i]));
      fit_thrust.push_back(prop.thrust_constant * bench.rpm[i] * bench.rpm[i]);
      fit_torque.push_back(prop.torque_constant * bench.rpm[i] * bench.rpm[i]);
      thrust_mean += std::abs(bench.thrust[i]) / static_cast<double>(bench.throttle.size());
      torque_mean += std::abs(bench.torque[i]) / static_cast<double>(bench.throttle.size());
    }
    out.tables.push_back({"bench.csv",
                          {"throttle", "voltage", "rpm", "thrust", "torque", "throttle_fit",
                           "thrust_fit", "torque_fit"},
                          {bench.throttle, bench.voltage, bench.rpm, bench.thrust, bench.torque,
                           fit_thr, fit_thrust, fit_torque}});
    auto& s = prop_stage;
    s.Param("thrust_constant", prop.thrust_constant, prop.thrust_constant_std_error, "N/rpm^2");
    s.Param("torque_constant", prop.torque_constant, prop.torque_constant_std_error, "N m/rpm^2");
    s.residuals = {{"thrust_rms", prop.thrust_rms},
                   {"torque_rms", prop.torque_rms},
                   {"throttle_rms", prop.throttle_rms},
                   {"throttle_max_abs", prop.throttle_max_abs},
                   {"throttle_max_abs_envelope", prop.throttle_max_abs_envelope},
                   {"samples", prop.samples},
                   {"polynomial_samples", prop.polynomial_samples}};
    s.Check("T_k > 0", prop.thrust_constant, 0.0, false);
    s.Check("T_q > 0", prop.torque_constant, 0.0, false);
    s.Check("thrust rms / mean thrust", prop.thrust_rms / thrust_mean, 0.05);
    s.Check("torque rms / mean torque", prop.torque_rms / torque_mean, 0.05);
    s.Check("throttle polynomial rms", prop.throttle_rms, 0.01);
    s.Check("throttle polynomial max abs residual, thrust >= 20 % of max",
            prop.throttle_max_abs_envelope, 0.02);
    // The map must be invertible over the bench's thrust and voltage range.
    double fmin = kInf, fmax = 0.0, vmin = kInf, vmax = 0.0;
    for (std::size_t i = 0; i < bench.thrust.size(); ++i) {
      if (!(bench.thrust[i] > 0.0)) continue;
      fmin = std::min(fmin, bench.thrust[i]);
      fmax = std::max(fmax, bench.thrust[i]);
      vmin = std::min(vmin, bench.voltage[i]);
      vmax = std::max(vmax, bench.voltage[i]);
    }
    double min_slope = kInf;
    for (int a = 0; a <= 20; ++a) {
      for (int b = 0; b <= 4; ++b) {
        const double f = fmin + (fmax - fmin) * a / 20.0, volt = vmin + (vmax - vmin) * b / 4.0;
        min_slope = std::min(min_slope, prop.throttle.DThrottleDThrust(f, volt));
      }
    }
    s.Check("min d throttle / d thrust over the bench range", min_slope, 0.0, false);
    v.thrust_constant = prop.thrust_constant;
    v.torque_constant = prop.torque_constant;
    v.throttle = prop.throttle;
    j["thrust_constant"] = prop.thrust_constant;
    j["torque_constant"] = prop.torque_constant;
    j["thrust_rms"] = prop.thrust_rms;
    j["torque_rms"] = prop.torque_rms;
    j["throttle_rms"] = prop.throttle_rms;
    j["throttle_max_abs"] = prop.throttle_max_abs;
    j["bench_samples"] = prop.samples;
    have.insert(have.end(), {"thrust_constant", "torque_constant", "throttle_polynomial"});
  });

  // Stage 2: inertia (bifilar pendulum).
  StageReport inertia_stage{"inertia"};
  RunStage(&out, &inertia_stage, [&] {
    auto& s = inertia_stage;
    for (int a = 0; a < 3; ++a) {
      const PendulumSwing& swing = data.pendulum[a].Get();
      const auto& pt = swing.t;
      const PendulumFit pend = FitPendulum(pt, swing.angle);
      v.inertia[a] =
          BifilarInertia(data.mass, data.wire_separation, data.wire_length, pend.natural_period);
      std::vector<double> fit;
      for (double ti : pt) fit.push_back(pend.Evaluate(ti));
      const std::string ax(1, "xyz"[a]);
      out.tables.push_back(
          {"pendulum_" + ax + ".csv", {"t", "angle", "fit"}, {pt, swing.angle, fit}});
      // I ~ T^2: relative standard error of I = 2 x that of T (the mass and the wire
      // geometry are taken as exact).
      const double se = 2.0 * v.inertia[a] * pend.natural_period_std_error / pend.natural_period;
      s.Param("inertia " + ax, v.inertia[a], se, "kg m^2");
      s.Param("natural period " + ax, pend.natural_period, pend.natural_period_std_error, "s");
      s.residuals["rms_" + ax] = pend.rms;
      s.residuals["noise_sigma_" + ax] = pend.noise_sigma;
      s.Check("fit rms / amplitude " + ax, pend.rms / std::abs(pend.amplitude), 0.2);
      s.Check("relative std error of I " + ax, se / v.inertia[a], 0.01);
      s.Check("decay rate " + ax + " [1/s] >= 0", pend.decay_rate, 0.0, false);
      j["pendulum"][ax] = {{"natural_period", pend.natural_period},
                           {"damped_period", pend.damped_period},
                           {"decay_rate", pend.decay_rate},
                           {"rms", pend.rms},
                           {"inertia", v.inertia[a]}};
    }
    // Principal moments of a rigid body satisfy the triangle inequalities.
    const auto& I = v.inertia;
    s.CheckTrue("triangle inequalities I_x + I_y >= I_z etc.",
                I.x() + I.y() >= I.z() && I.y() + I.z() >= I.x() && I.z() + I.x() >= I.y(),
                fmt::format("[{:.5g}, {:.5g}, {:.5g}]", I.x(), I.y(), I.z()));
    have.push_back("inertia");
  });

  // Stages 3 and 4: attitude model (first order) and autopilot PD gains, per axis.
  StageReport att_stage{"attitude model"};
  StageReport pd_stage{"PD gains"};
  const std::array<std::string, 3> axes{"roll", "pitch", "yaw"};
  std::array<FirstOrderFit, 3> fo;
  std::array<std::vector<double>, 3> refs, angles;
  std::vector<double> t;
  std::vector<Gap> gaps;
  SampleMask use;
  RunStage(&out, &att_stage, [&] {
    const AttitudeSteps& steps = data.attitude_steps.Get();
    t = steps.t;
    auto& s = att_stage;
    gaps = FindGaps(t, kGapFactor);
    use = GapMask(t, gaps, kGapSettle);
    const auto excluded = std::count(use.begin(), use.end(), 0);
    j["gaps"] = {{"count", gaps.size()}, {"factor", kGapFactor},
                 {"settle", kGapSettle}, {"excluded_samples", excluded},
                 {"samples", t.size()},  {"intervals", nlohmann::json::array()}};
    for (const auto& g : gaps) j["gaps"]["intervals"].push_back({g.start, g.end});
    s.residuals["gaps"] = static_cast<double>(gaps.size());
    s.residuals["samples_excluded_after_gaps"] = static_cast<double>(excluded);
    if (!gaps.empty()) {
      std::string list;
      for (std::size_t k = 0; k < gaps.size() && k < 5; ++k) {
        list += fmt::format("{}{:.3f}-{:.3f} s", k ? ", " : "", gaps[k].start, gaps[k].end);
      }
      if (gaps.size() > 5) list += fmt::format(", ... ({} more)", gaps.size() - 5);
      out.notices.push_back(fmt::format(
          "fnmpc: warning: sysid: {}: {} gap(s) in the time stamps (step > {} x the "
          "median): {}; {} sample(s) up to {} s after them left out of the fits",
          settings.attitude_steps_name, gaps.size(), kGapFactor, list, excluded, kGapSettle));
    }
    FirstOrderFitSettings fs;
    fs.use = use;
    for (int a = 0; a < 3; ++a) {
      refs[a] = steps.ref[a];
      angles[a] = steps.angle[a];
      if (a == 2) {
        refs[a] = UnwrapAngles(refs[a]);
        angles[a] = UnwrapAngles(angles[a]);
      }
      try {
        fo[a] = FitFirstOrder(t, refs[a], angles[a], fs);
      } catch (const std::exception& e) {
        throw std::invalid_argument(axes[a] + ": " + e.what());
      }
      const auto& f = fo[a];
      s.Param(axes[a] + " gain", f.gain, f.std_error[1], "-");
      s.Param(axes[a] + " lag tau (without delay)", f.time_constant, f.std_error[0], "s");
      s.Param(axes[a] + " delay", f.delay, f.std_error[2], "s");
      s.Param(axes[a] + " offset c (steady bias x gain)", f.offset, f.std_error[4], "rad");
      s.residuals["rms_" + axes[a]] = f.rms;
      s.residuals["noise_sigma_" + axes[a]] = f.noise_sigma;
      s.residuals["r_squared_" + axes[a]] = f.r_squared;
      s.Check(axes[a] + " R^2 of the step response", f.r_squared, 0.9, false);
      s.Check(axes[a] + " gain within [0.5, 2]", std::abs(f.gain - 1.25), 0.75);
      s.CheckTrue(axes[a] + " delay inside its range", !f.delay_at_bound,
                  fmt::format("{:.4f} s", f.delay));
      v.attitude_gain[a] = f.gain;
      j["attitude"][axes[a]] = {{"time_constant", f.time_constant},
                                {"delay", f.delay},
                                {"equivalent_time_constant", f.equivalent_time_constant},
                                {"gain", f.gain},
                                {"offset", f.offset},
                                {"rms", f.rms}};
    }
    have.push_back("attitude");
  });
  std::array<PdFit, 3> pd;
  bool yaw_clamped = true;  // the yaw PD fit kept the reaction-torque clamp
  double yaw_authority = kInf;
  RunStage(&out, &pd_stage, [&] {
    if (!att_stage.ok) {
      throw std::invalid_argument("needs the attitude model (stage 'attitude model' failed)");
    }
    auto& s = pd_stage;
    for (int a = 0; a < 3; ++a) {
      AttitudeLoopSettings ls = settings.loop;
      if (a == 2 && prop_stage.ok && inertia_stage.ok) {
        // Yaw authority of the reaction torques at hover (docs/simulator.md, mixer).
        const double hover = data.mass * kGravity;
        const double fmax = prop.throttle.Thrust(1.0, 16.0);
        const double ratio = prop.torque_constant / prop.thrust_constant;
        const double room = std::isfinite(fmax) ? std::min(hover, 4.0 * fmax - hover) : hover;
        ls.max_angular_acceleration = ratio * room / v.inertia.z();
        yaw_authority = ls.max_angular_acceleration;
      }
      try {
        pd[a] = FitPdGains(t, refs[a], angles[a], fo[a], ls, use);
      } catch (const std::exception& e) {
        if (!std::isfinite(ls.max_angular_acceleration)) {
          throw std::invalid_argument(axes[a] + ": " + e.what());
        }
        pd[a].rms = kInf;
      }
      if (std::isfinite(ls.max_angular_acceleration)) {
        // The authority computed from the identified propulsion is this simulator's
        // mixer model; if the measured response is faster than it allows (the clamped
        // loop fits clearly worse than an unclamped one), the data contradict it: the
        // unclamped fit is kept and the check fails.
        AttitudeLoopSettings free = ls;
        free.max_angular_acceleration = kInf;
        PdFit unclamped;
        try {
          unclamped = FitPdGains(t, refs[a], angles[a], fo[a], free, use);
        } catch (const std::exception& e) {
          if (!std::isfinite(pd[a].rms)) throw std::invalid_argument(axes[a] + ": " + e.what());
          unclamped.rms = kInf;
        }
        // Not a sanity check: the authority leaves out the rotors' spin-up torque (rotor
        // inertia, not in a campaign), which dominates a real vehicle's fast yaw response,
        // so every real campaign exceeded it (docs/sysid.md). Reported, and the gains that
        // reproduce the data are kept.
        const bool consistent = pd[a].rms <= 1.5 * unclamped.rms;
        s.residuals["yaw_authority"] = fmt::format(
            "{}: limit {:.3g} rad/s^2 (reaction torque only), rms {:.3g} clamped vs {:.3g} free",
            consistent ? "within" : "exceeded, unclamped gains kept", ls.max_angular_acceleration,
            pd[a].rms, unclamped.rms);
        if (!consistent) {
          pd[a] = unclamped;
          yaw_clamped = false;
        }
      }
      const auto& p = pd[a];
      s.Param(axes[a] + " K_p", p.kp, p.kp_std_error, "1/s^2");
      s.Param(axes[a] + " K_d", p.kd, p.kd_std_error, "1/s");
      s.Param(axes[a] + " transport delay", p.delay, -1.0, "s");
      s.residuals["rms_" + axes[a]] = p.rms;
      s.residuals["rms_to_first_order_" + axes[a]] = p.rms_to_first_order;
      s.residuals["r_squared_" + axes[a]] = p.r_squared;
      s.Check(axes[a] + " R^2 of the step response", p.r_squared, 0.9, false);
      s.CheckTrue(axes[a] + " gains inside their bounds", !p.at_bound,
                  fmt::format("K_p {:.4g}, K_d {:.4g}", p.kp, p.kd));
      s.Check(axes[a] + " closed loop: K_d / K_p > motor lag [s]", p.kd / p.kp,
              settings.loop.motor_time_constant, false);
      v.attitude_kp[a] = p.kp;
      v.attitude_kd[a] = p.kd;
      j["attitude"][axes[a]]["kp"] = p.kp;
      j["attitude"][axes[a]]["kd"] = p.kd;
      j["attitude"][axes[a]]["pd_delay"] = p.delay;
      j["attitude"][axes[a]]["pd_rms"] = p.rms;
      j["attitude"][axes[a]]["pd_rms_to_first_order"] = p.rms_to_first_order;
    }
    have.push_back("attitude_pd");
  });
  std::vector<std::string>& warnings = out.warnings;
  if (att_stage.ok) {
    // The vehicle's time constant is the lag of the first-order model without the
    // transport delay (the NMPC model has no delay). Whether the first-order fit's delay d
    // is a transport delay or the lag of fast closed-loop poles is decided by which model
    // predicts held-out segments better (docs/sysid.md, "Model selection"): first order +
    // dead time (tau = tau_fo), or the autopilot's PD loop with its own transport delay d_pd
    // (fast poles: tau = tau_fo + d - d_pd, the mean residence time of the lag part). When
    // the data do not decide (margin below kModelMarginThreshold, or the two folds disagree)
    // the conservative value is written: the residence time, which never leaves the delay
    // out of the delay-free model.
    auto& s = att_stage;
    for (int a = 0; a < 3; ++a) {
      const auto& f = fo[a];
      AttitudeLoopSettings ls = settings.loop;
      if (a == 2 && yaw_clamped) ls.max_angular_acceleration = yaw_authority;
      HeldOutValidation val;
      std::string val_error;
      try {
        val = ValidateOnHeldOutSegments(t, refs[a], angles[a], use, ls, kMinSegment);
        if (!val.pd_error.empty()) val_error = "PD loop: " + val.pd_error;
      } catch (const std::exception& e) {
        val_error = e.what();
        val.first_order.assign(t.size(), kNaN);
        val.pd_loop.assign(t.size(), kNaN);
        val.fold.assign(t.size(), 0);
      }
      // Decided by the data only when each fold alone prefers the same model by at least
      // the threshold: the choice then does not hang on which half of the steps is held out.
      const bool same_sign = val.fold_margin[0] * val.fold_margin[1] > 0.0;
      const bool decisive = std::isfinite(val.margin) && same_sign &&
                            std::abs(val.fold_margin[0]) >= kModelMarginThreshold &&
                            std::abs(val.fold_margin[1]) >= kModelMarginThreshold;
      const double residence_transport = pd_stage.ok ? std::min(pd[a].delay, f.delay) : 0.0;
      std::string model;
      double transport = 0.0;
      bool identifiable = false;
      if (settings.tau_convention == "lag") {
        model = "forced: lag only";
        transport = f.delay;
      } else if (settings.tau_convention == "residence") {
        model = "forced: lag + delay";
        transport = 0.0;
      } else if (!pd_stage.ok) {
        model = "PD loop unavailable: lag + delay (conservative)";
        transport = 0.0;
        s.CheckTrue(axes[a] + " transport delay determined", false,
                    "the PD stage failed; tau includes the first-order delay");
      } else if (decisive && val.margin > 0.0) {
        model = "first order + transport delay predicts held-out segments better";
        transport = f.delay;
        identifiable = !f.delay_at_bound;
      } else if (decisive) {
        model = "PD loop predicts held-out segments better: delay is fast dynamics";
        transport = residence_transport;
        identifiable = true;
      } else {
        model = "undecided: conservative lag + delay - PD delay";
        transport = residence_transport;
        const std::string why =
            val_error.empty()
                ? fmt::format("held-out RMS margin {:+.1f} % (folds {:+.1f} %, {:+.1f} %)",
                              100.0 * val.margin, 100.0 * val.fold_margin[0],
                              100.0 * val.fold_margin[1])
                : "no held-out comparison (" + val_error + ")";
        warnings.push_back(fmt::format(
            "{}: the data do not choose between first order + transport delay and the PD "
            "loop ({}; needs each fold >= {:.0f} % in the same direction): writing the "
            "conservative "
            "tau {:.4f} s (lag + delay - PD delay) instead of {:.4f} s",
            axes[a], why, 100.0 * kModelMarginThreshold, f.equivalent_time_constant - transport,
            f.time_constant));
      }
      const double tau = f.equivalent_time_constant - transport;
      const double tau_se =
          transport == f.delay ? f.std_error[0] : std::hypot(f.std_error[0], f.std_error[2]);
      s.Param(axes[a] + " time constant", tau, tau_se, "s");
      s.Param(axes[a] + " transport delay (not in the vehicle file)", transport,
              transport == f.delay ? f.std_error[2] : -1.0, "s");
      s.residuals["delay_model_" + axes[a]] = model;
      s.residuals["heldout_rms_first_order_" + axes[a]] = val.first_order_rms;
      s.residuals["heldout_rms_pd_loop_" + axes[a]] = val.pd_rms;
      s.residuals["heldout_margin_" + axes[a]] = val.margin;
      s.residuals["heldout_fit_percent_first_order_" + axes[a]] = val.first_order_fit_percent;
      s.residuals["heldout_fit_percent_pd_loop_" + axes[a]] = val.pd_fit_percent;
      s.Check(axes[a] + " relative std error of tau", tau_se / tau, 0.05);
      v.attitude_time_constant[a] = tau;
      auto& ja = j["attitude"][axes[a]];
      ja["vehicle_time_constant"] = tau;
      ja["transport_delay"] = transport;
      ja["transport_delay_identifiable"] = identifiable;
      ja["delay_model"] = model;
      const bool fo_chosen = transport == f.delay && settings.tau_convention != "residence";
      ja["validation"] = {
          {"segments", val.segments},
          {"min_segment", kMinSegment},
          {"first_order_rms", val.first_order_rms},
          {"pd_loop_rms", val.pd_rms},
          {"first_order_fit_percent", val.first_order_fit_percent},
          {"pd_loop_fit_percent", val.pd_fit_percent},
          {"chosen_fit_percent", fo_chosen ? val.first_order_fit_percent : val.pd_fit_percent},
          {"margin", val.margin},
          {"fold_margins", {val.fold_margin[0], val.fold_margin[1]}},
          {"threshold", kModelMarginThreshold},
          {"decisive", decisive},
          {"error", val_error}};
      std::vector<double> y1 = SimulateFirstOrderFit(t, refs[a], f);
      std::vector<double> y2(t.size(), kNaN);
      if (pd_stage.ok) y2 = SimulatePdFit(t, refs[a], f, pd[a], ls);
      std::vector<double> fold(t.size()), used(t.size());
      for (std::size_t i = 0; i < t.size(); ++i) {
        fold[i] = val.fold[i];
        used[i] = use[i];
      }
      out.tables.push_back(
          {fmt::format("attitude_{}.csv", axes[a]),
           {"t", "ref", "angle", "first_order", "pd_loop", "used", "fold", "heldout_first_order",
            "heldout_pd_loop"},
           {t, refs[a], angles[a], y1, y2, used, fold, val.first_order, val.pd_loop}});
    }
  }
  out.stages = {prop_stage, inertia_stage, att_stage, pd_stage};
  out.propulsion = prop;
  out.first_order = fo;
  out.pd = pd;
  return out;
}

}  // namespace fnmpc::sysid
