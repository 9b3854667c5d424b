// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/calibration.hpp"

#include <ceres/ceres.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>

namespace fnmpc::sysid {

template <class T>
Eigen::Matrix<T, 9, 1> PredictStep(const Eigen::Matrix<T, 9, 1>& x, const Vec<4>& command,
                                   const T& bias_roll, const T& bias_pitch, const T& thrust_scale,
                                   const model::AttitudeModelParams& m, double dt, int substeps) {
  using X = Eigen::Matrix<T, 9, 1>;
  using M = model::QuadrotorModel;
  const Eigen::Matrix<T, 3, 1> u(thrust_scale * command[0], T(command[1]) + bias_roll,
                                 T(command[2]) + bias_pitch);
  const double psi_ref = command[3];
  const double h = dt / substeps;
  X xs = x;
  for (int s = 0; s < substeps; ++s) {
    const X k1 = M::Flow<T>(xs, u, psi_ref, m);
    const X k2 = M::Flow<T>(X(xs + (0.5 * h) * k1), u, psi_ref, m);
    const X k3 = M::Flow<T>(X(xs + (0.5 * h) * k2), u, psi_ref, m);
    const X k4 = M::Flow<T>(X(xs + h * k3), u, psi_ref, m);
    xs += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
  return xs;
}

template Vec<9> PredictStep<double>(const Vec<9>&, const Vec<4>&, const double&, const double&,
                                    const double&, const model::AttitudeModelParams&, double, int);

namespace {

void CheckLog(const FlightLog& log, const CalibrationSettings& st) {
  const std::size_t n = log.t.size();
  if (log.state.size() != n || log.command.size() != n) {
    throw std::invalid_argument("[Calibrate] t, state and command differ in length");
  }
  for (std::size_t i = 1; i < n; ++i) {
    if (!(log.t[i] > log.t[i - 1])) {
      throw std::invalid_argument("[Calibrate] time is not increasing at sample " +
                                  std::to_string(i));
    }
  }
  if (!(st.window > 0.0) || !(st.window_stride > 0.0) || st.substeps < 1) {
    throw std::invalid_argument("[Calibrate] window, window_stride and substeps must be > 0");
  }
  if (n < 2 || log.t.back() - log.t.front() < st.window) {
    throw std::invalid_argument("[Calibrate] the flight is shorter than one window (" +
                                std::to_string(st.window) + " s)");
  }
}

// Index one past the last sample of the window starting at `start`.
std::size_t WindowEnd(const FlightLog& log, int start, double window) {
  std::size_t e = static_cast<std::size_t>(start);
  while (e < log.t.size() && log.t[e] <= log.t[static_cast<std::size_t>(start)] + window + 1e-9) {
    ++e;
  }
  return e;
}

struct WindowCost {
  const FlightLog* log;
  int start;
  std::size_t end;
  model::AttitudeModelParams m;
  CalibrationSettings st;
  template <class T>
  bool operator()(const T* const p, T* residuals) const {
    Eigen::Matrix<T, 9, 1> x = log->state[static_cast<std::size_t>(start)].template cast<T>();
    int r = 0;
    for (std::size_t i = static_cast<std::size_t>(start) + 1; i < end; ++i) {
      x = PredictStep<T>(x, log->command[i - 1], p[0], p[1], p[2], m, log->t[i] - log->t[i - 1],
                         st.substeps);
      const Vec<9>& z = log->state[i];
      for (int k = 0; k < 3; ++k) residuals[r++] = (x[k] - z[k]) / st.position_scale;
      for (int k = 6; k < 8; ++k) residuals[r++] = (x[k] - z[k]) / st.angle_scale;
    }
    return true;
  }
};

}  // namespace

std::vector<int> WindowStarts(const FlightLog& log, const CalibrationSettings& st) {
  std::vector<int> starts;
  if (log.t.empty()) return starts;
  double next = log.t.front();
  for (std::size_t i = 0; i < log.t.size(); ++i) {
    if (log.t[i] + 1e-9 < next) continue;
    if (log.t[i] + st.window > log.t.back() + 1e-9) break;
    starts.push_back(static_cast<int>(i));
    next = log.t[i] + st.window_stride;
  }
  return starts;
}

std::vector<WindowPrediction> PredictWindows(const model::VehicleParams& params,
                                             const FlightLog& log, const CalibrationSettings& st) {
  CheckLog(log, st);
  const auto m = model::AttitudeModelParams::From(params);
  std::vector<WindowPrediction> out;
  for (int s : WindowStarts(log, st)) {
    WindowPrediction w;
    w.start = s;
    const std::size_t end = WindowEnd(log, s, st.window);
    Vec<9> x = log.state[static_cast<std::size_t>(s)];
    w.state.push_back(x);
    for (std::size_t i = static_cast<std::size_t>(s) + 1; i < end; ++i) {
      x = PredictStep<double>(x, log.command[i - 1], params.bias.roll, params.bias.pitch,
                              params.bias.thrust_scale, m, log.t[i] - log.t[i - 1], st.substeps);
      w.state.push_back(x);
    }
    out.push_back(std::move(w));
  }
  return out;
}

double MeanPositionError(const FlightLog& log, const std::vector<WindowPrediction>& windows) {
  double sum = 0.0;
  long count = 0;
  for (const auto& w : windows) {
    for (std::size_t k = 1; k < w.state.size(); ++k) {
      const auto i = static_cast<std::size_t>(w.start) + k;
      sum += (w.state[k].head<3>() - log.state[i].head<3>()).norm();
      ++count;
    }
  }
  return count > 0 ? sum / static_cast<double>(count) : 0.0;
}

CalibrationResult Calibrate(const model::VehicleParams& params, const FlightLog& log,
                            const CalibrationSettings& st) {
  CheckLog(log, st);
  CalibrationResult res;
  res.position_error_before = MeanPositionError(log, PredictWindows(params, log, st));
  const auto m = model::AttitudeModelParams::From(params);
  std::array<double, 3> p{params.bias.roll, params.bias.pitch, params.bias.thrust_scale};
  const std::vector<int> starts = WindowStarts(log, st);
  // The least-squares problem over the windows `use` (a window may appear several times).
  auto add_windows = [&](ceres::Problem* problem, const std::vector<int>& use, double* q) {
    int added = 0;
    for (int s : use) {
      const std::size_t end = WindowEnd(log, s, st.window);
      const int residuals = 5 * static_cast<int>(end - static_cast<std::size_t>(s) - 1);
      if (residuals <= 0) continue;
      auto* cost = new ceres::AutoDiffCostFunction<WindowCost, ceres::DYNAMIC, 3>(
          new WindowCost{&log, s, end, m, st}, residuals);
      problem->AddResidualBlock(cost, nullptr, q);
      ++added;
    }
    if (added > 0) {
      problem->SetParameterLowerBound(q, 0, -0.5);
      problem->SetParameterUpperBound(q, 0, 0.5);
      problem->SetParameterLowerBound(q, 1, -0.5);
      problem->SetParameterUpperBound(q, 1, 0.5);
      problem->SetParameterLowerBound(q, 2, 0.5);
      problem->SetParameterUpperBound(q, 2, 2.0);
    }
    return added;
  };
  ceres::Problem problem;
  res.windows = add_windows(&problem, starts, p.data());
  if (res.windows == 0)
    throw std::invalid_argument("[Calibrate] no prediction window fits the log");
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 50;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  res.converged = summary.IsSolutionUsable() && std::isfinite(summary.final_cost);
  res.bias = {p[0], p[1], p[2]};
  const double n_res = static_cast<double>(summary.num_residuals);
  if (n_res > 3.0) {
    const double s2 = 2.0 * summary.final_cost / (n_res - 3.0);
    res.rms_scaled = std::sqrt(2.0 * summary.final_cost / n_res);
    ceres::Covariance::Options co;
    ceres::Covariance cov(co);
    const std::vector<std::pair<const double*, const double*>> blocks{{p.data(), p.data()}};
    if (cov.Compute(blocks, &problem)) {
      std::array<double, 9> c{};
      cov.GetCovarianceBlock(p.data(), p.data(), c.data());
      for (int k = 0; k < 3; ++k) res.std_error[k] = std::sqrt(s2 * c[4 * k]);
    }
  }
  // Bootstrap over windows: resample the windows with replacement, refit from the estimate,
  // standard deviation of the refits. Each window is a 1 s block of the log, so the
  // bootstrap keeps the correlation inside a window (the covariance above ignores it).
  if (st.bootstrap > 0 && res.converged && starts.size() > 1) {
    std::mt19937 rng(st.bootstrap_seed);
    std::uniform_int_distribution<std::size_t> pick(0, starts.size() - 1);
    std::vector<std::array<double, 3>> fits;
    ceres::Solver::Options sb = so;
    sb.max_num_iterations = 20;
    for (int b = 0; b < st.bootstrap; ++b) {
      std::vector<int> use(starts.size());
      for (int& u : use) u = starts[pick(rng)];
      std::array<double, 3> q = p;
      ceres::Problem pb;
      if (add_windows(&pb, use, q.data()) == 0) continue;
      ceres::Solver::Summary sum;
      ceres::Solve(sb, &pb, &sum);
      if (sum.IsSolutionUsable() && std::isfinite(sum.final_cost)) fits.push_back(q);
    }
    if (fits.size() >= 2) {
      for (int k = 0; k < 3; ++k) {
        double mean = 0.0, ss = 0.0;
        for (const auto& f : fits) mean += f[k] / static_cast<double>(fits.size());
        for (const auto& f : fits) ss += (f[k] - mean) * (f[k] - mean);
        res.bootstrap_std_error[k] = std::sqrt(ss / static_cast<double>(fits.size() - 1));
      }
    }
  }
  res.at_bound = std::abs(p[0]) >= 0.5 - 1e-9 || std::abs(p[1]) >= 0.5 - 1e-9 ||
                 p[2] <= 0.5 + 1e-9 || p[2] >= 2.0 - 1e-9;
  model::VehicleParams after = params;
  after.bias = res.bias;
  after.has_bias = true;
  res.position_error_after = MeanPositionError(log, PredictWindows(after, log, st));
  return res;
}

}  // namespace fnmpc::sysid
