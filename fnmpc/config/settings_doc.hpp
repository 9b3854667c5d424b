// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "fnmpc/config/settings_archive.hpp"
#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"

namespace fnmpc::config {

/// One settings field as its Serialize defines it: the full dotted key, the default (the
/// value the struct holds), what it accepts and its meaning.
struct SettingDoc {
  std::string key, default_value, accepts, doc;
};

/// Collects SettingDocs by walking a Serialize (fnmpc/core/serialize.hpp).
class SettingsDocWriter : public SettingsArchive<SettingsDocWriter> {
 public:
  [[nodiscard]] const std::vector<SettingDoc>& fields() const { return fields_; }

  template <class T>
  void Visit(std::string_view key, T* value, const Limit& limit, std::string_view doc) {
    fields_.push_back({Key(key), Format(*value), limit.Describe(), std::string(doc)});
  }
  /// A list's item fields, documented as "<key>[].<field>" with a default item's values.
  template <class T>
  void VisitList(std::string_view key, std::vector<T>* /*list*/, std::string_view /*doc*/) {
    T item{};
    Nested(std::string(key) + "[]", &item);
  }
  template <class E>
  void VisitChoice(std::string_view key, E* value, const Choice& choice, std::string_view doc) {
    fields_.push_back(
        {Key(key), choice.names[static_cast<int>(*value)], choice.Describe(), std::string(doc)});
  }
  void VisitRange(std::string_view key, double* lo, double* hi, const RangeLimit& limit,
                  std::string_view doc);

 private:
  static std::string Format(double v);
  static std::string Format(int v);
  static std::string Format(bool v);
  static std::string Format(const Vec3& v);

  std::vector<SettingDoc> fields_;
};

/// The markdown table of `fields` (| key | default | accepts | meaning |), one row each.
std::string SettingsTable(const std::vector<SettingDoc>& fields);

/// Markers around a generated table in a markdown file; `table` names it ("settings": the
/// scenario's settings, "reality", "sensors file").
std::string TableBegin(std::string_view table);
std::string TableEnd(std::string_view table);

/// Where `markdown` (docs/scenarios.md) and the definitions disagree, one line each: a key
/// documented in the table `table` between its markers but not defined, a defined key not
/// documented, missing markers, or (when the key sets agree) a row that differs from
/// SettingsTable's. Empty: in agreement.
std::vector<std::string> SettingsDocDrift(const std::string& markdown,
                                          const std::vector<SettingDoc>& defined,
                                          std::string_view table = "settings");

/// `markdown` with the text between the markers of `table` replaced by SettingsTable(defined).
std::string WithSettingsTable(const std::string& markdown, const std::vector<SettingDoc>& defined,
                              std::string_view table = "settings");

}  // namespace fnmpc::config
