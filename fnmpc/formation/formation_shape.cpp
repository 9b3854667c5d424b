// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/formation_shape.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "fnmpc/formation/neighbour_limits.hpp"

namespace fnmpc::formation {
namespace {

struct Placed {
  Vec3 offset;  // from the leader
  int rank;     // ties go to lower ranks (the first) or to the same rank, never higher
};

// Start offsets from the leader, front (leader) to back, with their rank.
std::vector<Placed> Place(const FormationSpec& spec) {
  const double s = spec.spacing;
  const int n = spec.count;
  std::vector<Placed> p;
  p.reserve(static_cast<std::size_t>(n));
  switch (spec.shape) {
    case FormationShape::kWedge:
      // Row r holds r + 1 vehicles, 2 s apart: the rows' ends lie on two 45-degree lines.
      for (int r = 0; static_cast<int>(p.size()) < n; ++r) {
        for (int k = 0; k <= r && static_cast<int>(p.size()) < n; ++k)
          p.push_back({Vec3(-r * s, (r - 2 * k) * s, 0.0), r});
      }
      break;
    case FormationShape::kLine:
      for (int i = 0; i < n; ++i) p.push_back({Vec3(-i * s, 0.0, 0.0), i});
      break;
    case FormationShape::kGrid: {
      // The leader at the front-left corner; rank: rows plus columns from it.
      const int cols = spec.columns > 0
                           ? spec.columns
                           : static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
      for (int i = 0; i < n; ++i)
        p.push_back({Vec3(-(i / cols) * s, -(i % cols) * s, 0.0), i / cols + i % cols});
      break;
    }
    case FormationShape::kCircle: {
      // The leader in the centre; the followers on a circle of radius >= s whose chords
      // between neighbours are s, the first follower straight behind the leader.
      const int m = n - 1;
      const double radius = m < 2 ? s : std::max(s, s / (2.0 * std::sin(std::numbers::pi / m)));
      p.push_back({Vec3::Zero(), 0});
      for (int k = 0; k < m; ++k) {
        const double a = std::numbers::pi + 2.0 * std::numbers::pi * k / m;
        p.push_back({Vec3(radius * std::cos(a), radius * std::sin(a), 0.0), 1});
      }
      break;
    }
  }
  return p;
}

// Distances compared at micrometres, so that equal distances are equal whatever rounding
// the placement did and the lower slot wins.
long long Micrometres(const Vec3& d) { return std::llround(d.norm() * 1e6); }

}  // namespace

bool ParseFormationShape(std::string_view name, FormationShape* shape) {
  if (name == "wedge")
    *shape = FormationShape::kWedge;
  else if (name == "line")
    *shape = FormationShape::kLine;
  else if (name == "grid")
    *shape = FormationShape::kGrid;
  else if (name == "circle")
    *shape = FormationShape::kCircle;
  else
    return false;
  return true;
}

std::vector<int> TieDepths(const std::vector<std::vector<int>>& neighbours, int leader) {
  std::vector<int> depth(neighbours.size(), -1);
  if (leader >= 0) depth.at(static_cast<std::size_t>(leader)) = 0;
  // Relaxed until nothing changes: at most one round per vehicle.
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; i < neighbours.size(); ++i) {
      for (const int j : neighbours[i]) {
        const int d = depth.at(static_cast<std::size_t>(j));
        if (d >= 0 && (depth[i] < 0 || d + 1 < depth[i])) {
          depth[i] = d + 1;
          changed = true;
        }
      }
    }
  }
  return depth;
}

std::vector<FormationSlot> GenerateFormation(const FormationSpec& spec) {
  if (spec.count < 2)
    throw std::invalid_argument("[GenerateFormation] count must be >= 2, got " +
                                std::to_string(spec.count));
  if (!(std::isfinite(spec.spacing) && spec.spacing > 0.0))
    throw std::invalid_argument("[GenerateFormation] spacing must be positive and finite");
  if (spec.ties < 1 || spec.ties > kMaxNeighbours)
    throw std::invalid_argument("[GenerateFormation] ties must be 1 to " +
                                std::to_string(kMaxNeighbours) + ", got " +
                                std::to_string(spec.ties));
  if (spec.columns < 0) throw std::invalid_argument("[GenerateFormation] columns must be >= 0");
  if (!spec.origin.allFinite())
    throw std::invalid_argument("[GenerateFormation] origin must be finite");

  const std::vector<Placed> place = Place(spec);
  const std::size_t n = place.size();
  std::vector<FormationSlot> slots(n);
  for (std::size_t i = 0; i < n; ++i) slots[i].start = spec.origin + place[i].offset;
  std::vector<int> candidates;
  for (std::size_t i = 1; i < n; ++i) {
    const auto distance = [&](int j) {
      return Micrometres(place[static_cast<std::size_t>(j)].offset - place[i].offset);
    };
    const auto nearer = [&](int a, int b) { return distance(a) < distance(b); };
    // The first tie: the nearest vehicle of a lower rank, so every follower has a chain of
    // ties to the leader. Then the nearest of lower or equal rank.
    candidates.clear();
    for (std::size_t j = 0; j < n; ++j)
      if (place[j].rank < place[i].rank) candidates.push_back(static_cast<int>(j));
    std::stable_sort(candidates.begin(), candidates.end(), nearer);
    const int parent = candidates.front();
    candidates.clear();
    for (std::size_t j = 0; j < n; ++j) {
      if (j != i && static_cast<int>(j) != parent && place[j].rank <= place[i].rank)
        candidates.push_back(static_cast<int>(j));
    }
    std::stable_sort(candidates.begin(), candidates.end(), nearer);
    candidates.insert(candidates.begin(), parent);
    const std::size_t ties = std::min(candidates.size(), static_cast<std::size_t>(spec.ties));
    for (std::size_t k = 0; k < ties; ++k) {
      const auto j = static_cast<std::size_t>(candidates[k]);
      slots[i].ties.push_back({candidates[k], place[j].offset - place[i].offset});
    }
  }
  std::vector<std::vector<int>> neighbours(n);
  for (std::size_t i = 0; i < n; ++i)
    for (const FormationTie& t : slots[i].ties) neighbours[i].push_back(t.neighbour);
  const std::vector<int> depth = TieDepths(neighbours, 0);
  for (std::size_t i = 0; i < n; ++i) slots[i].depth = depth[i];
  return slots;
}

}  // namespace fnmpc::formation
