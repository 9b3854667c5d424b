// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/tie_weights.hpp"

#include <algorithm>

namespace fnmpc::formation {

void TieWeights(TieWeighting rule, const int* depth, const bool* active, int n, double* w) {
  int count = 0, lowest = -1;
  bool known = true;
  for (int j = 0; j < n; ++j) {
    if (!active[j]) continue;
    ++count;
    known = known && depth[j] >= 0;
    if (depth[j] >= 0) lowest = lowest < 0 ? depth[j] : std::min(lowest, depth[j]);
  }
  double sum = 0.0;
  for (int j = 0; j < n; ++j) {
    double r = 0.0;
    if (active[j]) {
      if (!known || rule == TieWeighting::kEqual) {
        r = 1.0;
      } else {
        r = depth[j] == lowest ? 1.0 : 0.0;
      }
    }
    w[j] = r;
    sum += r;
  }
  if (count == 0) return;
  for (int j = 0; j < n; ++j) w[j] *= count / sum;
}

bool DiscountDisagreeingTies(const int* depth, const bool* active, const Vec3* place, double scale,
                             int n, double* w, Vec3* disagreement) {
  if (disagreement != nullptr) {
    for (int j = 0; j < n; ++j) disagreement[j].setZero();
  }
  if (!(scale > 0.0)) return false;
  int count = 0, lowest = -1;
  for (int j = 0; j < n; ++j) {
    if (!active[j]) continue;
    if (depth[j] < 0) return false;
    ++count;
    lowest = lowest < 0 ? depth[j] : std::min(lowest, depth[j]);
  }
  if (count < 2) return false;
  Vec3 anchor = Vec3::Zero();
  int anchors = 0;
  for (int j = 0; j < n; ++j) {
    if (active[j] && depth[j] == lowest) {
      anchor += place[j];
      ++anchors;
    }
  }
  anchor /= anchors;
  double sum = 0.0;
  bool deeper = false;
  for (int j = 0; j < n; ++j) {
    if (!active[j]) continue;
    if (depth[j] > lowest) {
      deeper = true;
      const Vec3 off = place[j] - anchor;
      const double e = off.norm() / scale;
      w[j] /= 1.0 + e * e;
      if (disagreement != nullptr) disagreement[j] = off.cwiseAbs();
    }
    sum += w[j];
  }
  if (!(sum > 0.0)) return false;
  for (int j = 0; j < n; ++j) w[j] *= count / sum;
  return deeper;
}

}  // namespace fnmpc::formation
