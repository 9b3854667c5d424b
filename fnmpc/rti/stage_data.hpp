// SPDX-License-Identifier: BSD-3-Clause
// The user's stage data of an RtiSolver: references, weights, parameters and bounds, with
// the argument checks of the public setters.
#pragma once

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/rti/problem_contract.hpp"

namespace fnmpc::rti {

/// Throws std::out_of_range naming the setter and the stage (CheckStage's error path, out of
/// line so that the check itself inlines into the setters the controller calls every step).
[[noreturn, gnu::cold, gnu::noinline]] inline void ThrowStageOutOfRange(const char* setter, int k,
                                                                        int first, int last,
                                                                        int horizon) {
  throw std::out_of_range(std::string("[RtiSolver] ") + setter + ": stage " + std::to_string(k) +
                          " outside " + std::to_string(first) + ".." + std::to_string(last) +
                          " (horizon " + std::to_string(horizon) + ")");
}

/// Throws std::out_of_range naming the setter when the stage k is outside first..last.
inline void CheckStage(const char* setter, int k, int first, int last, int horizon) {
  if (k < first || k > last) [[unlikely]] {
    ThrowStageOutOfRange(setter, k, first, last, horizon);
  }
}

/// Throws std::invalid_argument naming the setter for a negative, NaN or infinite weight.
template <class Y, class YN>
void CheckWeights(const char* setter, const Y& w, const YN& w_terminal) {
  auto check = [&](const char* which, const auto& v) {
    for (int r = 0; r < v.size(); ++r) {
      if (!(v[r] >= 0.0) || !std::isfinite(v[r])) {
        throw std::invalid_argument(std::string("[RtiSolver] ") + setter + ": " + which +
                                    " weight " + std::to_string(r) +
                                    " must be finite and >= 0, got " + std::to_string(v[r]));
      }
    }
  };
  check("stage", w);
  check("terminal", w_terminal);
}

/// References yref_k (k = 0..N-1) and yrefN, diagonal weights, parameters p_k (k = 0..N),
/// state bounds (k = 1..N; entry 0 unused) and input bounds (k = 0..N-1). Allocated once.
template <class Problem>
struct StageData {
  using X = Vec<Problem::kNx>;
  using U = Vec<Problem::kNu>;
  using Y = Vec<Problem::kNy>;
  using YN = Vec<Problem::kNyN>;
  using P = typename Problem::Params;

  explicit StageData(int horizon)
      : yref(horizon, Y::Zero()),
        params(horizon + 1, detail::ZeroParams<P>()),
        lbx(horizon + 1, X::Constant(-kInf)),
        ubx(horizon + 1, X::Constant(kInf)),
        lbu(horizon, U::Constant(-kInf)),
        ubu(horizon, U::Constant(kInf)) {
    yref_n.setZero();
    w.setOnes();
    w_n.setOnes();
  }

  std::vector<Y> yref;
  YN yref_n;
  Y w;
  YN w_n;
  std::vector<P> params;
  std::vector<X> lbx, ubx;
  std::vector<U> lbu, ubu;
};

}  // namespace fnmpc::rti
