// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "fnmpc/core/types.hpp"

namespace fnmpc::sim {

/// Uniform grid ("cell list") over the horizontal positions of a set of points, for the
/// points near a query point without testing all of them: Build() bins the points into square
/// cells of side `cell` [m] (z is not binned), Near() returns every point whose cell overlaps
/// the square of half-side `radius` around the query, in ascending index order (a superset of
/// the points within `radius`; the caller applies its exact test). Buffers grow to the largest
/// set seen and are then reused: no allocation once sized.
class CellList {
 public:
  /// Bins `positions` into cells of side `cell` (> 0). The grid spans the points' bounding
  /// box; when that would need more than kMaxCellsPerPoint cells per point, the cells are
  /// enlarged (fewer, larger cells: still a superset). The positions must be finite.
  void Build(const std::vector<Vec3>& positions, double cell) {
    const int n = static_cast<int>(positions.size());
    lo_x_ = lo_y_ = kInf;
    double hi_x = -kInf, hi_y = -kInf;
    for (const Vec3& p : positions) {
      lo_x_ = std::min(lo_x_, p.x());
      lo_y_ = std::min(lo_y_, p.y());
      hi_x = std::max(hi_x, p.x());
      hi_y = std::max(hi_y, p.y());
    }
    if (n == 0) {
      lo_x_ = lo_y_ = 0.0;
      hi_x = hi_y = 0.0;
    }
    cell_ = cell;
    const double max_cells = kMaxCellsPerPoint * std::max(n, 1);
    while ((std::floor((hi_x - lo_x_) / cell_) + 1.0) * (std::floor((hi_y - lo_y_) / cell_) + 1.0) >
           max_cells) {
      cell_ *= 2.0;
    }
    nx_ = static_cast<int>(std::floor((hi_x - lo_x_) / cell_)) + 1;
    ny_ = static_cast<int>(std::floor((hi_y - lo_y_) / cell_)) + 1;
    // Counting sort by cell; within a cell the indices stay ascending.
    start_.assign(static_cast<std::size_t>(nx_) * ny_ + 1, 0);
    cell_of_.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      const int c = CellIndex(CellX(positions[i].x()), CellY(positions[i].y()));
      cell_of_[i] = c;
      ++start_[static_cast<std::size_t>(c) + 1];
    }
    for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(static_cast<std::size_t>(n));
    fill_.assign(start_.begin(), start_.end() - 1);
    for (int i = 0; i < n; ++i) items_[fill_[cell_of_[i]]++] = i;
  }

  /// Indices of the points in the cells that overlap [x - radius, x + radius] x
  /// [y - radius, y + radius] around `p`, ascending, into *out (cleared first).
  void Near(const Vec3& p, double radius, std::vector<int>* out) const {
    out->clear();
    const int x0 = CellX(p.x() - radius), x1 = CellX(p.x() + radius);
    const int y0 = CellY(p.y() - radius), y1 = CellY(p.y() + radius);
    for (int cy = y0; cy <= y1; ++cy) {
      for (int cx = x0; cx <= x1; ++cx) {
        const int c = CellIndex(cx, cy);
        for (int k = start_[c]; k < start_[c + 1]; ++k) out->push_back(items_[k]);
      }
    }
    std::sort(out->begin(), out->end());
  }

  /// Side of the cells in use [m] (the requested one, or larger, see Build).
  [[nodiscard]] double cell() const { return cell_; }

 private:
  static constexpr double kMaxCellsPerPoint = 4.0;
  // Cell coordinates, clamped to the grid (points outside the box are in no cell; a query
  // beyond the box reads the border cells, a superset).
  [[nodiscard]] int CellX(double x) const {
    const double c = std::floor((x - lo_x_) / cell_);
    return c >= 0.0 ? static_cast<int>(std::min(c, static_cast<double>(nx_ - 1))) : 0;
  }
  [[nodiscard]] int CellY(double y) const {
    const double c = std::floor((y - lo_y_) / cell_);
    return c >= 0.0 ? static_cast<int>(std::min(c, static_cast<double>(ny_ - 1))) : 0;
  }
  [[nodiscard]] int CellIndex(int cx, int cy) const { return cy * nx_ + cx; }

  double lo_x_ = 0.0, lo_y_ = 0.0, cell_ = 1.0;
  int nx_ = 1, ny_ = 1;
  std::vector<int> start_;    // first item of each cell, one past the last at the end
  std::vector<int> fill_;     // counting-sort cursor per cell
  std::vector<int> cell_of_;  // cell of each point
  std::vector<int> items_;    // point indices, grouped by cell
};

}  // namespace fnmpc::sim
