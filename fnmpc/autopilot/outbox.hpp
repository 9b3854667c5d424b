// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>

#include "fnmpc/mavlink/message.hpp"

namespace fnmpc::autopilot {

/// Messages a session or an emulated autopilot wants sent, in order; fixed capacity (no
/// allocation). The caller encodes and sends them, then clears the outbox.
class Outbox {
 public:
  static constexpr std::size_t kCapacity = 8;
  /// Appends `message`; false (and `dropped()` counts it) when full.
  bool Push(const mavlink::Message& message) {
    if (size_ == kCapacity) {
      ++dropped_;
      return false;
    }
    items_[size_++] = message;
    return true;
  }
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] const mavlink::Message& operator[](std::size_t i) const { return items_[i]; }
  [[nodiscard]] const mavlink::Message* begin() const { return items_.data(); }
  [[nodiscard]] const mavlink::Message* end() const { return items_.data() + size_; }
  void Clear() { size_ = 0; }
  [[nodiscard]] std::size_t dropped() const { return dropped_; }

 private:
  std::array<mavlink::Message, kCapacity> items_{};
  std::size_t size_ = 0;
  std::size_t dropped_ = 0;
};

}  // namespace fnmpc::autopilot
