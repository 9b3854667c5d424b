// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/settings_yaml.hpp"

#include <algorithm>
#include <vector>

namespace fnmpc::config {

YamlMap* SettingsReader::At(const std::string& path) {
  if (path.empty()) return root_;
  const auto it = maps_.find(path);
  if (it != maps_.end()) return &it->second;
  const std::size_t dot = path.rfind('.');
  YamlMap* parent = At(dot == std::string::npos ? std::string() : path.substr(0, dot));
  const std::string last = dot == std::string::npos ? path : path.substr(dot + 1);
  if (parent == nullptr || !parent->Has(last)) return nullptr;
  return &maps_.emplace(path, parent->Map(last)).first->second;
}

YamlMap& SettingsReader::Required(const std::string& path) {
  if (YamlMap* m = At(path)) return *m;
  const std::size_t dot = path.rfind('.');
  YamlMap* parent = dot == std::string::npos ? root_ : &Required(path.substr(0, dot));
  const std::string last = dot == std::string::npos ? path : path.substr(dot + 1);
  return maps_.emplace(path, parent->Map(last)).first->second;  // throws: missing
}

void SettingsReader::Finish() {
  std::vector<std::pair<long, YamlMap*>> order;
  for (auto& [path, map] : maps_)
    order.emplace_back(-static_cast<long>(std::count(path.begin(), path.end(), '.')), &map);
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& entry : order) entry.second->Finish();
}

std::pair<YamlMap*, std::string> SettingsReader::Place(std::string_view key) {
  const std::string full = Key(key);
  const std::size_t dot = full.rfind('.');
  if (dot == std::string::npos) return {root_, full};
  return {At(full.substr(0, dot)), full.substr(dot + 1)};
}

void SettingsReader::VisitRange(std::string_view key, double* lo, double* hi,
                                const RangeLimit& limit, std::string_view /*doc*/) {
  auto [map, leaf] = Place(key);
  if (map == nullptr || !map->Has(leaf)) return;
  const std::vector<double> v = map->Doubles(leaf, 2);
  const std::string bad = limit.Check(v[0], v[1]);
  if (!bad.empty()) throw map->ErrorAt(leaf, bad);
  *lo = v[0] * limit.unit_value;
  *hi = v[1] * limit.unit_value;
}

void SettingsReader::ReadValue(YamlMap* m, const std::string& key, const Limit& limit, double* v) {
  const double x = m->Double(key);
  const std::string bad = limit.Check(x);
  if (!bad.empty()) throw m->ErrorAt(key, bad);
  *v = x;
}

void SettingsReader::ReadValue(YamlMap* m, const std::string& key, const Limit& limit, int* v) {
  const int x = m->Int(key);
  const std::string bad = limit.Check(x);
  if (!bad.empty()) throw m->ErrorAt(key, bad);
  *v = x;
}

void SettingsReader::ReadValue(YamlMap* m, const std::string& key, const Limit& /*limit*/,
                               bool* v) {
  *v = m->Bool(key, *v);
}

void SettingsReader::ReadValue(YamlMap* m, const std::string& key, const Limit& limit, Vec3* v) {
  const Vec3 x = m->Vector3(key);
  for (int k = 0; k < 3; ++k) {
    const std::string bad = limit.Check(x[k]);
    if (!bad.empty()) throw m->ErrorAt(key, bad);
  }
  *v = x;
}

int SettingsReader::ReadChoice(YamlMap* m, const std::string& key, const Choice& choice) {
  int index = 0;
  const std::string bad = choice.Check(m->String(key), &index);
  if (!bad.empty()) throw m->ErrorAt(key, bad);
  return index;
}

}  // namespace fnmpc::config
