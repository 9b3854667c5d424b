// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/attitude_fit.hpp"

#include <ceres/ceres.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/sysid/trajectory_fit.hpp"

namespace fnmpc::sysid {

template <class T>
void SimulateFirstOrder(const std::vector<double>& t, const std::vector<double>& ref, const T& tau,
                        const T& gain, const T& offset, const T& delay, const T& y0,
                        std::vector<T>* y) {
  using std::exp;
  const std::size_t n = t.size();
  y->resize(n);
  if (n == 0) return;
  T state = y0;
  T s = T(t[0]);
  std::size_t j = 0;  // ref[j] acts for s in [t_j + d, t_{j+1} + d); ref[0] also before
  auto propagate = [&](double r, const T& dt) {
    const T target = gain * r + offset;
    state = target + (state - target) * exp(-dt / tau);
  };
  (*y)[0] = state;
  for (std::size_t i = 1; i < n; ++i) {
    const T end = T(t[i]);
    while (j + 1 < n && T(t[j + 1]) + delay < end) {
      const T b = T(t[j + 1]) + delay;
      if (b > s) {
        propagate(ref[j], b - s);
        s = b;
      }
      ++j;
    }
    propagate(ref[j], end - s);
    s = end;
    (*y)[i] = state;
  }
}

template void SimulateFirstOrder<double>(const std::vector<double>&, const std::vector<double>&,
                                         const double&, const double&, const double&, const double&,
                                         const double&, std::vector<double>*);

template <class T>
void SimulateAttitudeLoop(const std::vector<double>& t, const std::vector<double>& ref, double gain,
                          const T& kp, const T& kd, double y0, const AttitudeLoopSettings& st,
                          std::vector<T>* y) {
  const std::size_t n = t.size();
  y->resize(n);
  if (n == 0) return;
  const double h = st.physics_dt;
  const int every = std::max(1, static_cast<int>(std::lround(1.0 / (st.autopilot_rate_hz * h))));
  const double lag = 1.0 - std::exp(-h / st.motor_time_constant);
  const double amax = st.max_angular_acceleration;
  T theta = T(y0), omega = T(0.0), accel = T(0.0), accel_cmd = T(0.0);
  T theta_prev = theta;
  double s = t[0];
  std::size_t j = 0;  // reference index: last with t_j <= s
  (*y)[0] = theta;
  std::size_t i = 1;
  for (long step = 0; i < n; ++step) {
    while (j + 1 < n && t[j + 1] <= s - st.delay + 1e-12) ++j;
    if (step % every == 0) {
      accel_cmd = kp * (gain * ref[j] - theta) - kd * omega;
      if (accel_cmd > T(amax)) accel_cmd = T(amax);
      if (accel_cmd < T(-amax)) accel_cmd = T(-amax);
    }
    accel += (accel_cmd - accel) * lag;
    omega += h * accel;
    theta_prev = theta;
    theta += h * omega;
    const double s_next = s + h;
    // Linear interpolation for every sample time in (s, s_next].
    while (i < n && t[i] <= s_next + 1e-12) {
      const double w = std::clamp((t[i] - s) / h, 0.0, 1.0);
      (*y)[i] = theta_prev + (theta - theta_prev) * w;
      ++i;
    }
    s = s_next;
  }
}

template void SimulateAttitudeLoop<double>(const std::vector<double>&, const std::vector<double>&,
                                           double, const double&, const double&, double,
                                           const AttitudeLoopSettings&, std::vector<double>*);

namespace {

bool Used(const SampleMask& use, std::size_t i) { return use.empty() || use[i] != 0; }

std::size_t CountUsed(const SampleMask& use, std::size_t n) {
  if (use.empty()) return n;
  return static_cast<std::size_t>(std::count_if(use.begin(), use.end(), [](auto u) { return u; }));
}

void CheckLog(const char* who, const std::vector<double>& t, const std::vector<double>& ref,
              const std::vector<double>& angle, const SampleMask& use = {}) {
  if (ref.size() != t.size() || angle.size() != t.size() ||
      (!use.empty() && use.size() != t.size())) {
    throw std::invalid_argument(std::string("[") + who +
                                "] t, ref, angle (and the sample mask) differ in length");
  }
  const std::size_t n_used = CountUsed(use, t.size());
  if (n_used < 20) {
    throw std::invalid_argument(std::string("[") + who + "] need at least 20 samples, got " +
                                std::to_string(n_used));
  }
  double lo = ref[0], hi = ref[0];
  for (double r : ref) {
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  if (!(hi - lo > 1e-6)) {
    throw std::invalid_argument(std::string("[") + who +
                                "] the reference never changes: nothing to identify");
  }
}

struct FirstOrderSim {
  const std::vector<double>* t;
  const std::vector<double>* ref;
  bool fit_delay;
  template <class T>
  void operator()(const T* p, std::vector<T>* y) const {
    SimulateFirstOrder<T>(*t, *ref, p[0], p[1], p[4], fit_delay ? p[2] : T(0.0), p[3], y);
  }
};

// The gains in log coordinates: p = (ln K_p, ln K_d).
struct LoopSim {
  const std::vector<double>* t;
  const std::vector<double>* ref;
  double gain;
  double y0;
  AttitudeLoopSettings settings;
  template <class T>
  void operator()(const T* p, std::vector<T>* y) const {
    using std::exp;
    SimulateAttitudeLoop<T>(*t, *ref, gain, exp(p[0]), exp(p[1]), y0, settings, y);
  }
};

double SumSquares(const std::vector<double>& y, const std::vector<double>& m,
                  const SampleMask& use = {}) {
  double ss = 0.0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    if (Used(use, i)) ss += (y[i] - m[i]) * (y[i] - m[i]);
  }
  return ss;
}

double RSquared(double rms, const std::vector<double>& m, const SampleMask& use = {}) {
  double mean = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    if (Used(use, i)) {
      mean += m[i];
      ++n;
    }
  }
  if (n == 0) return 0.0;
  mean /= static_cast<double>(n);
  double tot = 0.0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    if (Used(use, i)) tot += (m[i] - mean) * (m[i] - mean);
  }
  return tot > 0.0 ? 1.0 - rms * rms * static_cast<double>(n) / tot : 0.0;
}

}  // namespace

FirstOrderFit FitFirstOrder(const std::vector<double>& t, const std::vector<double>& ref,
                            const std::vector<double>& angle, const FirstOrderFitSettings& st) {
  CheckLog("FitFirstOrder", t, ref, angle, st.use);
  // Start: grid over tau and d with (k, y0, c) by linear least squares: y = k u + y0 v + c w,
  // u the unit-gain response from 0, v = exp(-(s)/tau) the free response and w = 1 - v the
  // response to a unit offset (s = t - t0).
  double best_tau = 0.1, best_d = 0.0, best_err = kInf;
  Eigen::Vector3d best_x(1.0, angle[0], 0.0);
  std::vector<double> u;
  const std::size_t n = t.size();
  Eigen::MatrixXd A(n, 3);
  Eigen::VectorXd yw(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    yw[static_cast<Eigen::Index>(i)] = Used(st.use, i) ? angle[i] : 0.0;
  }
  std::vector<double> delays{0.0};
  if (st.fit_delay) {
    for (double d = 0.01; d < st.max_delay; d += 0.01) delays.push_back(d);
  }
  for (double d : delays) {
    for (double tau = 0.01; tau < 1.0; tau *= 1.05) {
      SimulateFirstOrder<double>(t, ref, tau, 1.0, 0.0, d, 0.0, &u);
      for (std::size_t i = 0; i < n; ++i) {
        const double v = std::exp(-(t[i] - t[0]) / tau);
        const double w = Used(st.use, i) ? 1.0 : 0.0;  // left-out rows weigh nothing
        A(static_cast<Eigen::Index>(i), 0) = w * u[i];
        A(static_cast<Eigen::Index>(i), 1) = w * v;
        A(static_cast<Eigen::Index>(i), 2) = w * (1.0 - v);
      }
      const Eigen::Matrix3d AtA = A.transpose() * A;
      const Eigen::Vector3d x = AtA.ldlt().solve(A.transpose() * yw);
      if (!x.allFinite()) continue;
      const double err = (A * x - yw).squaredNorm();
      if (err < best_err) {
        best_err = err;
        best_tau = tau;
        best_d = d;
        best_x = x;
      }
    }
  }
  FirstOrderFit fit;
  fit.noise_sigma = NoiseSigma(angle);
  const FirstOrderSim sim{&t, &ref, st.fit_delay};
  // Delay start inside its range (a start on the bound d = 0 is not differentiable there).
  const double d0 = st.fit_delay ? std::max(best_d, std::min(0.002, 0.5 * st.max_delay)) : 0.0;
  const std::array<double, 5> p0{best_tau, best_x[0], d0, best_x[1], best_x[2]};
  const std::array<double, 5> lo{1e-3, -10.0, 0.0, -kInf, -kInf};
  const std::array<double, 5> hi{10.0, 10.0, st.fit_delay ? st.max_delay : 1.0, kInf, kInf};
  // Plain least squares first; then a Huber loss at 3x that fit's RMS, which only
  // down-weights real outliers (a scale from the sensor noise alone would also discount
  // the step transitions, where the first-order model cannot follow the loop exactly).
  const auto r0 = FitTrajectory<5>(sim, angle, p0, lo, hi, 0.0, 100, kInf, st.use);
  const auto r = FitTrajectory<5>(sim, angle, r0.p, lo, hi, 3.0 * std::max(r0.rms, fit.noise_sigma),
                                  100, kInf, st.use);
  if (!r.converged) throw std::invalid_argument("[FitFirstOrder] the fit did not converge");
  fit.time_constant = r.p[0];
  fit.gain = r.p[1];
  fit.delay = st.fit_delay ? r.p[2] : 0.0;
  fit.initial = r.p[3];
  fit.offset = r.p[4];
  fit.equivalent_time_constant = fit.time_constant + fit.delay;
  fit.rms = r.rms;
  fit.std_error = r.std_error;
  fit.delay_at_bound = st.fit_delay && r.at_bound[2] && fit.delay > 0.5 * st.max_delay;
  fit.r_squared = RSquared(r.rms, angle, st.use);
  return fit;
}

PdFit FitPdGains(const std::vector<double>& t, const std::vector<double>& ref,
                 const std::vector<double>& angle, const FirstOrderFit& fo,
                 const AttitudeLoopSettings& st, const SampleMask& use) {
  CheckLog("FitPdGains", t, ref, angle, use);
  if (!(st.physics_dt > 0.0) || !(st.autopilot_rate_hz > 0.0) || !(st.motor_time_constant > 0.0)) {
    throw std::invalid_argument(
        "[FitPdGains] physics_dt, autopilot_rate_hz and "
        "motor_time_constant must be > 0");
  }
  const double tau = fo.equivalent_time_constant;
  if (!(tau > 0.0) || !std::isfinite(fo.gain) || !std::isfinite(fo.initial)) {
    throw std::invalid_argument("[FitPdGains] the first-order fit is not usable (tau_eq " +
                                std::to_string(tau) + " s)");
  }
  // The first-order offset c enters the loop's set point k r + c = k (r + c / k).
  std::vector<double> ref_c(ref);
  if (std::abs(fo.gain) > 1e-6) {
    for (double& r : ref_c) r += fo.offset / fo.gain;
  }
  // A simulated angle further than this from the data is a diverged loop: rejected.
  double span = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    span = std::max({span, std::abs(angle[i] - fo.initial), std::abs(fo.gain * ref_c[i])});
  }
  const double max_abs = std::abs(fo.initial) + 10.0 * span + 1e-3;
  auto finite_error = [&](const std::vector<double>& y) {
    for (double v : y) {
      if (!std::isfinite(v) || std::abs(v) > max_abs) return kInf;
    }
    return SumSquares(y, angle, use);
  };
  // Gains: K_p in [kp_lo, 1e6] 1/s^2, K_d in [1e-3, 1e4] 1/s, fitted as logarithms.
  const double kp_lo = 1e-2 / (tau * tau);
  const std::array<double, 2> lo{std::log(kp_lo), std::log(1e-3)};
  const std::array<double, 2> hi{std::log(1e6), std::log(1e4)};

  // Start: grid over the delay (physics_dt steps, up to the first-order delay) and K_p,
  // with K_d = (tau_eq - d) K_p.
  const double h = st.physics_dt;
  const int max_steps = static_cast<int>(std::floor(std::min(fo.delay, 0.8 * tau) / h + 1e-9));
  const int stride = std::max(1, max_steps / 15);
  double best_err = kInf, best_kp = 0.0, best_lag = tau;
  int best_steps = 0;
  std::vector<double> y;
  for (int k = 0; k <= max_steps; k += stride) {
    AttitudeLoopSettings sk = st;
    sk.delay = k * h;
    const double lag = tau - sk.delay;
    const LoopSim sim{&t, &ref_c, fo.gain, fo.initial, sk};
    for (double kp = 1.0 / (lag * lag); kp < 1e5; kp *= 1.15) {
      const double p[2] = {std::log(kp), std::log(lag * kp)};
      sim(p, &y);
      const double err = finite_error(y);
      if (err < best_err) {
        best_err = err;
        best_kp = kp;
        best_lag = lag;
        best_steps = k;
      }
    }
  }
  if (!(best_err < kInf)) {
    throw std::invalid_argument("[FitPdGains] no start point gives a bounded simulation");
  }
  // Ceres on (ln K_p, ln K_d) at a fixed delay; plain least squares, then a Huber loss at
  // 3x that fit's RMS (as FitFirstOrder).
  const double noise = NoiseSigma(angle);
  auto fit_at = [&](int steps, const std::array<double, 2>& p0) {
    AttitudeLoopSettings sk = st;
    sk.delay = steps * h;
    const LoopSim sim{&t, &ref_c, fo.gain, fo.initial, sk};
    const auto r0 = FitTrajectory<2>(sim, angle, p0, lo, hi, 0.0, 100, max_abs, use);
    if (!r0.converged) return r0;
    return FitTrajectory<2>(sim, angle, r0.p, lo, hi, 3.0 * std::max(r0.rms, noise), 100, max_abs,
                            use);
  };
  auto clamp_start = [&](std::array<double, 2> p) {
    for (int k = 0; k < 2; ++k) p[k] = std::clamp(p[k], lo[k], hi[k]);
    return p;
  };
  auto best = fit_at(best_steps, clamp_start({std::log(best_kp), std::log(best_lag * best_kp)}));
  if (!best.converged) throw std::invalid_argument("[FitPdGains] the fit did not converge");
  // Line search over the delay on the physics_dt grid, warm-started from the neighbour.
  for (int dir : {-1, 1}) {
    int steps = best_steps;
    while (true) {
      const int next = steps + dir;
      if (next < 0 || next * h >= 0.9 * tau) break;
      const auto r = fit_at(next, best.p);
      if (!r.converged || !(r.rms < best.rms)) break;
      best = r;
      best_steps = next;
      steps = next;
    }
  }
  PdFit fit;
  fit.kp = std::exp(best.p[0]);
  fit.kd = std::exp(best.p[1]);
  fit.delay = best_steps * h;
  // d K = K d(ln K): standard errors of the gains from those of their logarithms.
  fit.kp_std_error = fit.kp * best.std_error[0];
  fit.kd_std_error = fit.kd * best.std_error[1];
  fit.at_bound = best.at_bound[0] || best.at_bound[1];
  fit.rms = best.rms;
  fit.r_squared = RSquared(best.rms, angle, use);
  AttitudeLoopSettings sk = st;
  sk.delay = fit.delay;
  std::vector<double> yf;
  SimulateAttitudeLoop<double>(t, ref_c, fo.gain, fit.kp, fit.kd, fo.initial, sk, &y);
  SimulateFirstOrder<double>(t, ref, fo.time_constant, fo.gain, fo.offset, fo.delay, fo.initial,
                             &yf);
  fit.rms_to_first_order =
      std::sqrt(SumSquares(y, yf, use) / static_cast<double>(CountUsed(use, t.size())));
  return fit;
}

std::vector<Gap> FindGaps(const std::vector<double>& t, double factor) {
  if (!(factor > 1.0)) throw std::invalid_argument("[FindGaps] factor must be > 1");
  std::vector<Gap> gaps;
  if (t.size() < 3) return gaps;
  std::vector<double> dt(t.size() - 1);
  for (std::size_t i = 1; i < t.size(); ++i) dt[i - 1] = t[i] - t[i - 1];
  std::vector<double> sorted(dt);
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                   sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (std::size_t i = 1; i < t.size(); ++i) {
    if (dt[i - 1] > factor * median) gaps.push_back({t[i - 1], t[i], i});
  }
  return gaps;
}

SampleMask GapMask(const std::vector<double>& t, const std::vector<Gap>& gaps, double settle) {
  SampleMask use(t.size(), 1);
  for (const Gap& g : gaps) {
    for (std::size_t i = g.index; i < t.size() && t[i] <= g.end + settle; ++i) use[i] = 0;
  }
  return use;
}

double FitPercent(const std::vector<double>& measured, const std::vector<double>& predicted,
                  const SampleMask& use) {
  double mean = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    if (Used(use, i) && std::isfinite(predicted[i])) {
      mean += measured[i];
      ++n;
    }
  }
  if (n == 0) return kNaN;
  mean /= static_cast<double>(n);
  double err = 0.0, tot = 0.0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    if (!Used(use, i) || !std::isfinite(predicted[i])) continue;
    err += (measured[i] - predicted[i]) * (measured[i] - predicted[i]);
    tot += (measured[i] - mean) * (measured[i] - mean);
  }
  if (!(tot > 0.0)) return kNaN;
  return 100.0 * (1.0 - std::sqrt(err / tot));
}

std::vector<double> SimulateFirstOrderFit(const std::vector<double>& t,
                                          const std::vector<double>& ref, const FirstOrderFit& fo) {
  std::vector<double> y;
  SimulateFirstOrder<double>(t, ref, fo.time_constant, fo.gain, fo.offset, fo.delay, fo.initial,
                             &y);
  return y;
}

std::vector<double> SimulatePdFit(const std::vector<double>& t, const std::vector<double>& ref,
                                  const FirstOrderFit& fo, const PdFit& pd,
                                  const AttitudeLoopSettings& settings) {
  AttitudeLoopSettings sk = settings;
  sk.delay = pd.delay;
  std::vector<double> ref_c(ref);
  if (std::abs(fo.gain) > 1e-6) {
    for (double& r : ref_c) r += fo.offset / fo.gain;
  }
  std::vector<double> y;
  SimulateAttitudeLoop<double>(t, ref_c, fo.gain, pd.kp, pd.kd, fo.initial, sk, &y);
  return y;
}

std::vector<unsigned char> SegmentFolds(const std::vector<double>& t,
                                        const std::vector<double>& ref, double min_segment,
                                        int* segments) {
  std::vector<unsigned char> fold(t.size(), 2);
  int segment = 0;
  double segment_start = t.empty() ? 0.0 : t[0];
  for (std::size_t i = 1; i < t.size(); ++i) {
    // A new segment starts at a change of the reference once the current one is long enough.
    if (ref[i] != ref[i - 1] && t[i] - segment_start >= min_segment) {
      ++segment;
      segment_start = t[i];
    }
    fold[i] = static_cast<unsigned char>(segment == 0 ? 2 : segment % 2);
  }
  if (segments != nullptr) *segments = t.empty() ? 0 : segment + 1;
  return fold;
}

HeldOutValidation ValidateOnHeldOutSegments(const std::vector<double>& t,
                                            const std::vector<double>& ref,
                                            const std::vector<double>& angle, const SampleMask& use,
                                            const AttitudeLoopSettings& loop, double min_segment) {
  HeldOutValidation v;
  v.fold = SegmentFolds(t, ref, min_segment, &v.segments);
  if (v.segments < 3) {
    throw std::invalid_argument(
        "[ValidateOnHeldOutSegments] fewer than three segments: nothing to hold out");
  }
  const std::size_t n = t.size();
  v.first_order.assign(n, kNaN);
  v.pd_loop.assign(n, kNaN);
  std::array<SampleMask, 2> test;
  for (int f = 0; f < 2; ++f) {
    SampleMask train(n, 0);
    test[1 - f].assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      if (!Used(use, i)) continue;
      if (v.fold[i] == 2) {
        train[i] = 1;  // the first segment fixes the start y0 of both fits
      } else {
        (v.fold[i] == f ? train : test[1 - f])[i] = 1;
      }
    }
    FirstOrderFitSettings fs;
    fs.use = train;
    const FirstOrderFit fo = FitFirstOrder(t, ref, angle, fs);
    const std::vector<double> y_fo = SimulateFirstOrderFit(t, ref, fo);
    std::vector<double> y_pd(n, kNaN);
    try {
      const PdFit pd = FitPdGains(t, ref, angle, fo, loop, train);
      y_pd = SimulatePdFit(t, ref, fo, pd, loop);
    } catch (const std::exception& e) {
      v.pd_error = e.what();
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (test[1 - f][i] == 0) continue;
      v.first_order[i] = y_fo[i];
      v.pd_loop[i] = y_pd[i];
    }
  }
  auto rms = [&](const std::vector<double>& y, const SampleMask& m) {
    double ss = 0.0;
    std::size_t k = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (m[i] == 0) continue;
      ss += (y[i] - angle[i]) * (y[i] - angle[i]);  // NaN when the PD fit failed: NaN rms
      ++k;
    }
    return k > 0 ? std::sqrt(ss / static_cast<double>(k)) : kNaN;
  };
  SampleMask held_out(n, 0);
  for (std::size_t i = 0; i < n; ++i) held_out[i] = test[0][i] | test[1][i];
  auto margin = [](double pd_rms, double fo_rms) {
    return (pd_rms - fo_rms) / std::min(pd_rms, fo_rms);
  };
  for (int f = 0; f < 2; ++f) {
    v.fold_margin[f] = margin(rms(v.pd_loop, test[f]), rms(v.first_order, test[f]));
  }
  v.first_order_rms = rms(v.first_order, held_out);
  v.pd_rms = rms(v.pd_loop, held_out);
  v.margin = margin(v.pd_rms, v.first_order_rms);
  v.first_order_fit_percent = FitPercent(angle, v.first_order, held_out);
  v.pd_fit_percent = v.pd_error.empty() ? FitPercent(angle, v.pd_loop, held_out) : kNaN;
  return v;
}

}  // namespace fnmpc::sysid
