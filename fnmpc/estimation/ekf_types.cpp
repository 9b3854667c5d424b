// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/estimation/ekf_types.hpp"

namespace fnmpc::estimation {

std::string_view ToString(EkfStatus s) {
  constexpr std::array<std::string_view, kNumEkfStatus> kNames{
      "accepted", "ignored", "non_finite",      "gated",
      "too_old",  "invalid", "not_initialized", "numerical_error"};
  const int i = static_cast<int>(s);
  return i >= 0 && i < kNumEkfStatus ? kNames[i] : "unknown";
}

std::string_view ToString(VehicleMode m) { return m == VehicleMode::kLanded ? "landed" : "flying"; }

}  // namespace fnmpc::estimation
