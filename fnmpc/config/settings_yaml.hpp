// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "fnmpc/config/settings_archive.hpp"
#include "fnmpc/config/yaml_reader.hpp"
#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"

namespace fnmpc::config {

/// Reads settings structs from YAML by walking their Serialize (fnmpc/core/serialize.hpp):
/// each key present is read, checked against its Limit and stored; an absent key keeps the
/// field's default. Dotted keys ("controller.bounds.speed") are read from nested mappings,
/// each opened once and shared with hand-written parsing through At()/Required(), so that
/// Finish() reports any key nobody read. Errors are ConfigErrors with file:line:column and
/// the full key.
class SettingsReader : public SettingsArchive<SettingsReader> {
 public:
  explicit SettingsReader(YamlMap* root) : root_(root) {}

  /// The mapping at a dotted path ("" is the root), opened once; nullptr when absent.
  YamlMap* At(const std::string& path);
  /// The same, but an error (missing required key) when absent.
  YamlMap& Required(const std::string& path);
  /// Finish() of every nested mapping opened, deepest first (the root's is the caller's).
  void Finish();

  // ---- The archive interface of Serialize.
  template <class T>
  void Visit(std::string_view key, T* value, const Limit& limit, std::string_view /*doc*/) {
    auto [map, leaf] = Place(key);
    if (map == nullptr || (!map->Has(leaf) && !limit.required)) return;
    ReadValue(map, leaf, limit, value);  // a required key that is absent: "missing required key"
  }
  /// A list of mappings, each item's fields walked below "<key>[i].". Present: replaces the
  /// default list.
  template <class T>
  void VisitList(std::string_view key, std::vector<T>* list, std::string_view /*doc*/) {
    auto [map, leaf] = Place(key);
    if (map == nullptr || !map->Has(leaf)) return;
    std::vector<YamlMap> items = map->MapList(leaf);
    list->assign(items.size(), T{});
    for (std::size_t i = 0; i < items.size(); ++i) {
      const std::string item = std::string(key) + "[" + std::to_string(i) + "]";
      maps_.emplace(Key(item), std::move(items[i]));
      Nested(item, &(*list)[i]);
    }
  }
  template <class E>
  void VisitChoice(std::string_view key, E* value, const Choice& choice, std::string_view /*doc*/) {
    auto [map, leaf] = Place(key);
    if (map == nullptr || !map->Has(leaf)) return;
    *value = static_cast<E>(ReadChoice(map, leaf, choice));
  }
  void VisitRange(std::string_view key, double* lo, double* hi, const RangeLimit& limit,
                  std::string_view doc);

 private:
  /// The mapping holding prefix + key and the key's last component.
  std::pair<YamlMap*, std::string> Place(std::string_view key);
  static void ReadValue(YamlMap* m, const std::string& key, const Limit& limit, double* v);
  static void ReadValue(YamlMap* m, const std::string& key, const Limit& limit, int* v);
  static void ReadValue(YamlMap* m, const std::string& key, const Limit& limit, bool* v);
  static void ReadValue(YamlMap* m, const std::string& key, const Limit& limit, Vec3* v);
  static int ReadChoice(YamlMap* m, const std::string& key, const Choice& choice);

  YamlMap* root_;
  std::map<std::string, YamlMap> maps_;  // by dotted path; node addresses are stable
};

}  // namespace fnmpc::config
