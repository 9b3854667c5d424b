// SPDX-License-Identifier: BSD-3-Clause
// Dimensions of the condensed QP and its state-bound rows, fixed at construction (what
// acados and HPIPM keep in their *_dims structures).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnmpc/core/assert.hpp"
#include "fnmpc/rti/rti_settings.hpp"

namespace fnmpc::rti {

/// One row of the condensed QP's general constraints: a bounded state component at a node.
struct BoundRow {
  int stage;  ///< node k = 1..N
  int index;  ///< state component
  int kind;   ///< 0 two-sided (hard, or any row of the hard QP), 1 soft lower, 2 soft upper
};

/// Sizes and constraint rows of the condensed QP for a horizon, input size and bound layout.
/// The QP variables are the input increments, last stage first (UPos), then one slack per
/// stage when any bounded component is soft.
class RtiDimensions {
 public:
  /// Throws std::invalid_argument for a layout whose soft flags and indices differ in size
  /// or with a state index outside 0..nx-1.
  RtiDimensions(int horizon, int nx, int nu, const StateBoundLayout& layout) : n(horizon), nu(nu) {
    if (layout.soft.size() != layout.indices.size()) {
      throw std::invalid_argument("[RtiSolver] StateBoundLayout: soft and indices differ in size");
    }
    for (int i : layout.indices) {
      if (i < 0 || i >= nx) {
        throw std::invalid_argument("[RtiSolver] bounded state index out of range: " +
                                    std::to_string(i));
      }
    }
    int rows_per_stage = 0;
    bool any_soft = false;
    for (bool s : layout.soft) {
      rows_per_stage += s ? 2 : 1;
      any_soft = any_soft || s;
    }
    nsl = any_soft ? n : 0;
    nv = n * nu;
    nz = nv + nsl;
    nc = n * rows_per_stage;
    for (int k = 1; k <= n; ++k) {
      for (std::size_t c = 0; c < layout.indices.size(); ++c) {
        const int kind = layout.soft[c] ? 1 : 0;
        soft_to_hard.push_back(static_cast<int>(hard_rows.size()));
        rows.push_back({k, layout.indices[c], kind});
        if (kind == 1) {
          soft_to_hard.push_back(static_cast<int>(hard_rows.size()));
          rows.push_back({k, layout.indices[c], 2});
        }
        hard_rows.push_back({k, layout.indices[c], 0});
      }
    }
    nch = static_cast<int>(hard_rows.size());
  }

  /// Position of u_k in the QP variables: last stage first, so that the Riccati recursion
  /// (which eliminates u_{N-1} first) gives a lower-triangular factor. Slacks come after.
  [[nodiscard]] int UPos(int k) const {
    FNMPC_ASSERT(k >= 0 && k < n);
    return (n - 1 - k) * nu;
  }

  int n;        ///< horizon N
  int nu;       ///< inputs per stage
  int nv = 0;   ///< input increments, N nu
  int nsl = 0;  ///< slacks: N with a soft bound, else 0
  int nz = 0;   ///< QP variables, nv + nsl
  int nc = 0;   ///< rows of the (soft) QP
  int nch = 0;  ///< rows of the hard QP (the QP without slacks)
  /// Rows of the (soft) QP: a soft component has a lower and an upper row, each with the
  /// stage's slack. Rows of the hard QP: one two-sided row per component and stage;
  /// soft_to_hard maps the first onto the second.
  std::vector<BoundRow> rows, hard_rows;
  std::vector<int> soft_to_hard;
};

}  // namespace fnmpc::rti
