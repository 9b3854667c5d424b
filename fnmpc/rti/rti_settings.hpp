// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fnmpc/core/serialize.hpp"
#include "fnmpc/qp/dense_qp.hpp"

namespace fnmpc::rti {

/// The most RK4 steps per shooting interval a setting may ask for (a bound on the work of one
/// linearisation; docs/failure.md "Limits").
inline constexpr int kMaxIntegratorSteps = 100;

/// Settings of the real-time-iteration solver (defaults: the reference work and the
/// benchmark spec).
struct RtiSettings {
  int horizon = 15;
  double sample_time = 0.05;
  int integrator_steps = 2;
  int max_initial_iterations = 50;
  double kkt_threshold = 1e-6;
  int max_iterations = 1;
  double cpu_budget = 0.05;
  double soft_linear_weight = 1e4;
  double soft_quadratic_weight = 1e2;
  bool unconstrained_shortcut = true;
  qp::QpSettings qp;

  /// Every field with its key (scenario block `controller:`), accepted values and meaning.
  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("sample_time", &sample_time, Positive(), "Ts [s], length of one interval");
    a->Visit("horizon", &horizon, IntIn(1, 100).Quiet(), "N, shooting intervals");
    a->Visit("integrator_steps", &integrator_steps, IntIn(1, kMaxIntegratorSteps),
             "RK4 steps per interval");
    a->Visit("max_iterations", &max_iterations, IntIn(1, 100),
             "SQP iterations per call after the first (1 = pure RTI)");
    a->Visit("max_initial_iterations", &max_initial_iterations, IntIn(1, 1000),
             "SQP iteration cap of the first call (t = 0)");
    a->Visit("kkt_threshold", &kkt_threshold, Positive(),
             "Algorithm 1: stop iterating below this KKT value");
    a->Visit("cpu_budget", &cpu_budget, Positive(),
             "[s] later calls stop iterating past this CPU time");
    a->Visit("soft_linear_weight", &soft_linear_weight, NonNegative(),
             "L1 penalty on the per-stage slack of the soft bounds");
    a->Visit("soft_quadratic_weight", &soft_quadratic_weight, Positive(),
             "L2 penalty on the same slack");
    a->Visit("unconstrained_shortcut", &unconstrained_shortcut, AnyValue(),
             "with Riccati condensing: after a step whose QP had no active constraint, take "
             "the unconstrained Riccati step and skip condensing and the QP when it satisfies "
             "every bound (it is then the QP's solution); false: always condense and solve the "
             "QP. Same iterates either way");
    a->Nested("qp", &qp);
  }

  void Validate() const {
    auto fail = [](const std::string& what) {
      throw std::invalid_argument("[RtiSettings] " + what);
    };
    if (horizon < 1) fail("horizon must be >= 1, got " + std::to_string(horizon));
    if (!(sample_time > 0.0)) fail("sample_time must be > 0, got " + std::to_string(sample_time));
    if (integrator_steps < 1) fail("integrator_steps must be >= 1");
    if (max_initial_iterations < 1) fail("max_initial_iterations must be >= 1");
    if (max_iterations < 1) fail("max_iterations must be >= 1");
    if (!(kkt_threshold > 0.0)) fail("kkt_threshold must be > 0");
    if (!(cpu_budget > 0.0)) fail("cpu_budget must be > 0");
    if (!(soft_linear_weight >= 0.0) || !(soft_quadratic_weight > 0.0)) {
      fail("soft weights: linear must be >= 0 and quadratic > 0");
    }
  }
};

/// Which state components carry box bounds (fixed at construction: it sets the QP's
/// size) and whether each is soft. Bound values are set per stage at run time.
struct StateBoundLayout {
  std::vector<int> indices;  ///< bounded state components
  std::vector<bool> soft;    ///< same length: true = soft (slack with exact penalty)
};

/// Outcome of one solver call.
enum class RtiStatus : int {
  kSuccess = 0,       ///< QP solved, iterate updated
  kQpFailure = 1,     ///< QP infeasible or failed: fallback applied
  kNanDetected = 2,   ///< NaN/Inf in the linearisation or the step: fallback applied
  kInvalidInput = 3,  ///< NaN/Inf in x0: fallback applied
};
constexpr std::string_view ToString(RtiStatus s) {
  switch (s) {
    case RtiStatus::kSuccess:
      return "success";
    case RtiStatus::kQpFailure:
      return "qp_failure";
    case RtiStatus::kNanDetected:
      return "nan_detected";
    case RtiStatus::kInvalidInput:
      return "invalid_input";
  }
  return "?";
}

/// Statistics of the last call (acados-like per-phase times, always on).
struct RtiStats {
  RtiStatus status = RtiStatus::kSuccess;
  qp::QpStatus qp_status = qp::QpStatus::kOptimal;
  int sqp_iterations = 0;           ///< SQP iterations in the last call
  int qp_iterations = 0;            ///< active-set changes, summed over the call's QPs
  bool unconstrained_step = false;  ///< the last feedback took the unconstrained Riccati step
  bool fallback = false;            ///< the shifted previous solution was applied
  long fallback_count = 0;          ///< fallbacks since construction
  double kkt = -1.0;                ///< KKT value when computed (else -1)
  double time_prepare = 0;          ///< [s] linearisation + condensing of the last iteration
  double time_feedback = 0;         ///< [s] from x0 to u0 of the last iteration
  double time_total = 0;            ///< [s] whole call
};

}  // namespace fnmpc::rti
