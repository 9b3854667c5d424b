// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/autopilot/modes.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace fnmpc::autopilot {
namespace {

// PX4 (src/modules/commander/px4_custom_mode.h): main modes and the AUTO sub modes.
constexpr std::uint32_t kPx4MainPosctl = 3;
constexpr std::uint32_t kPx4MainAuto = 4;
constexpr std::uint32_t kPx4MainOffboard = 6;
constexpr std::uint32_t kPx4AutoLand = 6;
constexpr std::uint32_t Px4Mode(std::uint32_t main, std::uint32_t sub) {
  return main << 16 | sub << 24;
}
// ArduPilot Copter (ArduCopter/mode.h, enum class Mode::Number).
constexpr std::uint32_t kCopterStabilize = 0;
constexpr std::uint32_t kCopterLand = 9;
constexpr std::uint32_t kCopterGuidedNoGps = 20;

}  // namespace

std::string_view ToString(AutopilotKind kind) {
  return kind == AutopilotKind::kPx4 ? "px4" : "ardupilot";
}

AutopilotKind ParseAutopilotKind(std::string_view text) {
  if (text == "px4") return AutopilotKind::kPx4;
  if (text == "ardupilot") return AutopilotKind::kArduPilot;
  throw std::invalid_argument("autopilot '" + std::string(text) +
                              "' is not known; expected px4 or ardupilot");
}

std::string_view ToString(FlightMode mode) {
  switch (mode) {
    case FlightMode::kOffboard:
      return "offboard";
    case FlightMode::kLand:
      return "land";
    case FlightMode::kOther:
      break;
  }
  return "other";
}

std::uint32_t CustomMode(AutopilotKind kind, FlightMode mode) {
  if (kind == AutopilotKind::kPx4) {
    switch (mode) {
      case FlightMode::kOffboard:
        return Px4Mode(kPx4MainOffboard, 0);
      case FlightMode::kLand:
        return Px4Mode(kPx4MainAuto, kPx4AutoLand);
      case FlightMode::kOther:
        break;
    }
    return Px4Mode(kPx4MainPosctl, 0);
  }
  switch (mode) {
    case FlightMode::kOffboard:
      return kCopterGuidedNoGps;
    case FlightMode::kLand:
      return kCopterLand;
    case FlightMode::kOther:
      break;
  }
  return kCopterStabilize;
}

FlightMode ModeOf(AutopilotKind kind, std::uint32_t custom_mode) {
  if (kind == AutopilotKind::kPx4) {
    const std::uint32_t main = custom_mode >> 16 & 0xFF;
    const std::uint32_t sub = custom_mode >> 24 & 0xFF;
    if (main == kPx4MainOffboard) return FlightMode::kOffboard;
    if (main == kPx4MainAuto && sub == kPx4AutoLand) return FlightMode::kLand;
    return FlightMode::kOther;
  }
  if (custom_mode == kCopterGuidedNoGps) return FlightMode::kOffboard;
  if (custom_mode == kCopterLand) return FlightMode::kLand;
  return FlightMode::kOther;
}

SetModeParams SetModeParamsOf(AutopilotKind kind, FlightMode mode) {
  const std::uint32_t custom = CustomMode(kind, mode);
  SetModeParams p;
  p.base_mode = static_cast<float>(mav::kModeFlagCustomModeEnabled);
  if (kind == AutopilotKind::kPx4) {
    p.custom_main = static_cast<float>(custom >> 16 & 0xFF);
    p.custom_sub = static_cast<float>(custom >> 24 & 0xFF);
  } else {
    p.custom_main = static_cast<float>(custom);
  }
  return p;
}

FlightMode ModeOf(AutopilotKind kind, const SetModeParams& params) {
  if (!std::isfinite(params.custom_main) || !std::isfinite(params.custom_sub) ||
      params.custom_main < 0 || params.custom_main > 255 || params.custom_sub < 0 ||
      params.custom_sub > 255) {
    return FlightMode::kOther;
  }
  const auto main = static_cast<std::uint32_t>(params.custom_main);
  const auto sub = static_cast<std::uint32_t>(params.custom_sub);
  return ModeOf(kind, kind == AutopilotKind::kPx4 ? Px4Mode(main, sub) : main);
}

}  // namespace fnmpc::autopilot
