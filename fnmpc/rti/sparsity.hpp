// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <vector>

#include "fnmpc/core/eigen_abi.hpp"

/// Structural nonzeros of small matrices that are stored densely. The follower models'
/// transition matrices, cost Hessians and input matrices are mostly zero (a neighbour's
/// block is identity plus a few entries); products over the nonzeros only are what make
/// condensing O(nnz) instead of O(nx^2) per block.
namespace fnmpc::rti {

class SparsityPattern {
 public:
  struct Entry {
    int row, col;
  };
  /// Room for every entry of a rows x cols matrix, so that SetFromMask never allocates.
  void Reserve(int rows, int cols) { entries_.reserve(static_cast<std::size_t>(rows) * cols); }
  /// Entries of m that are not NaN (NaN marks "never written", see model::Discretise).
  template <class M>
  void SetFromWritten(const M& m) {
    SetFromMask(m.array() == m.array());
  }
  /// Entries where the boolean mask is set.
  template <class M>
  void SetFromMask(const M& mask) {
    entries_.clear();
    for (int c = 0; c < mask.cols(); ++c) {
      for (int r = 0; r < mask.rows(); ++r) {
        if (mask(r, c)) entries_.push_back({r, c});
      }
    }
  }
  [[nodiscard]] const std::vector<Entry>& entries() const { return entries_; }

  /// out = m * in (out must not alias in).
  template <class M, class In, class Out>
  void Multiply(const M& m, const In& in, Out* out) const {
    out->setZero();
    AddProduct(m, in, out);
  }
  /// out += m' * in.
  template <class M, class In, class Out>
  void AddTransposedProduct(const M& m, const In& in, Out* out) const {
    for (const Entry& e : entries_) out->row(e.col) += m(e.row, e.col) * in.row(e.row);
  }
  /// out += m * in.
  template <class M, class In, class Out>
  void AddProduct(const M& m, const In& in, Out* out) const {
    for (const Entry& e : entries_) out->row(e.row) += m(e.row, e.col) * in.row(e.col);
  }
  /// out = in * m (out must not alias in): column updates, contiguous for column-major.
  template <class M, class In, class Out>
  void MultiplyRight(const In& in, const M& m, Out* out) const {
    out->setZero();
    for (const Entry& e : entries_) out->col(e.col) += m(e.row, e.col) * in.col(e.row);
  }
  /// True when every structural entry of m is finite.
  template <class M>
  [[nodiscard]] bool AllFinite(const M& m) const {
    // NaN or Inf times zero is NaN. Four sums: one would be a chain of dependent additions.
    const auto at = [&](std::size_t i) { return m(entries_[i].row, entries_[i].col) * 0.0; };
    const std::size_t n = entries_.size();
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    std::size_t i = 0;
    for (; i + 4 <= n; i += 4) {
      s0 += at(i);
      s1 += at(i + 1);
      s2 += at(i + 2);
      s3 += at(i + 3);
    }
    for (; i < n; ++i) s0 += at(i);
    return (s0 + s1) + (s2 + s3) == 0.0;
  }

 private:
  std::vector<Entry> entries_;
};

}  // namespace fnmpc::rti
