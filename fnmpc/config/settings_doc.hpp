// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"

namespace fnmpc::config {

/// One settings field as its Serialize defines it: the full dotted key, the default (the
/// value the struct holds), what it accepts and its meaning.
struct SettingDoc {
  std::string key, default_value, accepts, doc;
};

/// Collects SettingDocs by walking a Serialize (fnmpc/core/serialize.hpp).
class SettingsDocWriter {
 public:
  template <class S>
  void Read(S* settings) {
    settings->Serialize(this);
  }
  [[nodiscard]] const std::vector<SettingDoc>& fields() const { return fields_; }

  template <class T>
  void Visit(std::string_view key, T* value, const Limit& limit, std::string_view doc) {
    fields_.push_back(
        {prefix_ + std::string(key), Format(*value), limit.Describe(), std::string(doc)});
  }
  void VisitRange(std::string_view key, double* lo, double* hi, std::string_view doc);
  template <class E>
  void VisitChoice(std::string_view key, E* value, const Choice& choice, std::string_view doc) {
    fields_.push_back({prefix_ + std::string(key), choice.names[static_cast<int>(*value)],
                       choice.Describe(), std::string(doc)});
  }
  template <class S>
  void Nested(std::string_view key, S* settings) {
    const std::string saved = prefix_;
    prefix_ += std::string(key) + ".";
    settings->Serialize(this);
    prefix_ = saved;
  }

 private:
  static std::string Format(double v);
  static std::string Format(int v);
  static std::string Format(bool v);
  static std::string Format(const Vec3& v);

  std::string prefix_;
  std::vector<SettingDoc> fields_;
};

/// The markdown table of `fields` (| key | default | accepts | meaning |), one row each.
std::string SettingsTable(const std::vector<SettingDoc>& fields);

/// Markers around the generated table in a markdown file.
inline constexpr std::string_view kSettingsBegin =
    "<!-- settings table: generated from the "
    "Serialize definitions, do not edit -->";
inline constexpr std::string_view kSettingsEnd = "<!-- end of settings table -->";

/// Where `markdown` (docs/scenarios.md) and the definitions disagree, one line each: a key
/// documented in the table between the markers but not defined, a defined key not
/// documented, missing markers, or (when the key sets agree) a row that differs from
/// SettingsTable's. Empty: in agreement.
std::vector<std::string> SettingsDocDrift(const std::string& markdown,
                                          const std::vector<SettingDoc>& defined);

/// `markdown` with the text between the markers replaced by SettingsTable(defined).
std::string WithSettingsTable(const std::string& markdown, const std::vector<SettingDoc>& defined);

}  // namespace fnmpc::config
