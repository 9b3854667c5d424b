// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/stage_report.hpp"

#include <fmt/core.h>

#include <cmath>

namespace fnmpc::sysid {

namespace {
// JSON has no NaN/inf: non-finite numbers are written as null.
nlohmann::json Num(double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(); }
}  // namespace

void StageReport::Param(const std::string& param, double value, double std_error,
                        const std::string& unit) {
  params.push_back({{"name", param},
                    {"value", Num(value)},
                    {"std_error", std_error >= 0.0 ? Num(std_error) : nlohmann::json()},
                    {"unit", unit}});
}

void StageReport::Check(const std::string& check, double value, double limit, bool upper) {
  const bool pass = std::isfinite(value) && (upper ? value <= limit : value >= limit);
  checks.push_back({{"name", check},
                    {"value", Num(value)},
                    {"limit", fmt::format("{} {:.4g}", upper ? "<=" : ">=", limit)},
                    {"pass", pass}});
}

void StageReport::CheckTrue(const std::string& check, bool pass, const std::string& detail) {
  checks.push_back({{"name", check}, {"value", detail}, {"limit", "true"}, {"pass", pass}});
}

bool StageReport::Passed() const {
  if (!ok) return false;
  for (const auto& c : checks) {
    if (!c["pass"].get<bool>()) return false;
  }
  return true;
}

std::string StageReport::FailedChecks() const {
  std::string which;
  for (const auto& c : checks) {
    if (!c["pass"].get<bool>()) which += (which.empty() ? "" : ", ") + c["name"].get<std::string>();
  }
  return which;
}

nlohmann::json StageReport::Json() const {
  return {{"name", name},
          {"ok", ok},
          {"reason", reason},
          {"params", params},
          {"checks", checks},
          {"residuals", residuals},
          {"sanity", Passed() ? "PASS" : "FAIL"}};
}

}  // namespace fnmpc::sysid
