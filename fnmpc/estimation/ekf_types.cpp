// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/estimation/ekf_types.hpp"

namespace fnmpc::estimation {

std::string_view ToString(EkfStatus s) {
  constexpr std::array<std::string_view, kNumEkfStatus> kNames{
      "accepted", "ignored",         "non_finite",      "gated",    "too_old",
      "invalid",  "not_initialized", "numerical_error", "time_jump"};
  const int i = static_cast<int>(s);
  return i >= 0 && i < kNumEkfStatus ? kNames[i] : "unknown";
}

std::string_view ToString(HealthFlag f) {
  constexpr std::array<std::string_view, kNumHealthFlags> kNames{"not_initialized",
                                                                 "non_finite",
                                                                 "position_uncertain",
                                                                 "velocity_uncertain",
                                                                 "attitude_uncertain",
                                                                 "attitude_envelope",
                                                                 "stale",
                                                                 "extrapolation_limit"};
  const auto bits = static_cast<std::uint32_t>(f);
  for (int i = 0; i < kNumHealthFlags; ++i) {
    if (bits == (1u << i)) return kNames[static_cast<std::size_t>(i)];
  }
  return "unknown";
}

std::string_view ToString(VehicleMode m) { return m == VehicleMode::kLanded ? "landed" : "flying"; }

}  // namespace fnmpc::estimation
