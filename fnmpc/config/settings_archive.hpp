// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <string_view>

namespace fnmpc::config {

/// What every archive of Serialize (fnmpc/core/serialize.hpp) shares: walking a settings
/// struct and the dotted key prefix of its nested structs. `Derived` (SettingsReader,
/// SettingsDocWriter) adds Visit and VisitRange, which name a field by Key(key).
template <class Derived>
class SettingsArchive {
 public:
  /// Walks `settings->Serialize(archive)` below the current key prefix.
  template <class S>
  void Read(S* settings) {
    settings->Serialize(static_cast<Derived*>(this));
  }
  /// The fields of `settings` below "<prefix><key>.".
  template <class S>
  void Nested(std::string_view key, S* settings) {
    const std::string saved = prefix_;
    prefix_.append(key).append(".");
    Read(settings);
    prefix_ = saved;
  }

 protected:
  /// The full dotted key of `key` below the current prefix.
  [[nodiscard]] std::string Key(std::string_view key) const {
    std::string full = prefix_;
    return full.append(key);
  }

 private:
  std::string prefix_;
};

}  // namespace fnmpc::config
