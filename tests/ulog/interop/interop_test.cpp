// SPDX-License-Identifier: BSD-3-Clause
// Interop of our ULog reader with an independent implementation, @foxglove/ulog 2.3.2
// (tests/ulog/interop/interop.mjs, pinned in package-lock.json; docs/ulog.md). On every sample
// log in ../shared/px4-logs (read in place beside the repository) both readers must agree on:
// the header and flag bits; the information, multi-information and parameters of the
// definitions section; every format definition's fields; every subscription (msg_id, multi_id,
// topic, number of messages, first and last timestamp) and a SHA-256 over the canonical text
// of all its messages (every timestamp and every field value, bit for bit; the canonical text
// is described in interop.mjs); the logged strings (level, tag, timestamp, text) and the
// dropouts. Our reader must also read every log to its end without a warning.
#include <gtest/gtest.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fnmpc/mavlink/sha256.hpp"
#include "fnmpc/ulog/reader.hpp"

namespace fnmpc::ulog {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

const fs::path kLogs = fs::path(FNMPC_SOURCE_DIR) / ".." / "shared" / "px4-logs";

std::string HexBytes(std::span<const std::uint8_t> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string s;
  s.reserve(2 * bytes.size());
  for (std::uint8_t b : bytes) {
    s.push_back(kDigits[b >> 4]);
    s.push_back(kDigits[b & 15]);
  }
  return s;
}
std::string HexText(const std::string& text) {
  return HexBytes({reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
}

// The bits of the double a float or double widens to, in hex without leading zeros.
std::string FloatHex(double v) {
  if (std::isnan(v)) return "nan";
  std::uint64_t bits = 0;
  std::memcpy(&bits, &v, 8);
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, bits, 16);
  return {buf, r.ptr};
}

template <class T>
T Load(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

// One leaf in the canonical text of interop.mjs.
void AppendLeaf(const DataMessage& m, const Column& c, std::string& out) {
  const std::span<const std::uint8_t> b = m.Bytes(c);
  if (c.is_string()) {
    out += HexBytes(b);
    return;
  }
  const std::uint8_t* p = b.data();
  switch (c.type) {
    case BasicType::kFloat:
      out += FloatHex(Load<float>(p));
      return;
    case BasicType::kDouble:
      out += FloatHex(Load<double>(p));
      return;
    case BasicType::kBool:
      out += p[0] != 0 ? "1" : "0";
      return;
    case BasicType::kInt64:
      out += std::to_string(Load<std::int64_t>(p));
      return;
    case BasicType::kUint64:
      out += std::to_string(Load<std::uint64_t>(p));
      return;
    default:
      out += std::to_string(static_cast<std::int64_t>(m.Value(c)));
      return;
  }
}

std::string InfoValue(const Info& i) {
  if (i.type == BasicType::kChar) return HexText(i.AsString());
  const std::size_t n = BasicSize(i.type);
  std::string s;
  const std::size_t count = i.is_array ? i.array_length : 1;
  for (std::size_t k = 0; k < count && (k + 1) * n <= i.value.size(); ++k) {
    Info one = i;
    one.is_array = false;
    one.value.assign(i.value.begin() + static_cast<std::ptrdiff_t>(k * n),
                     i.value.begin() + static_cast<std::ptrdiff_t>((k + 1) * n));
    const double v = *one.AsNumber();
    if (!s.empty()) s += ",";
    if (i.type == BasicType::kUint64) {
      s += std::to_string(Load<std::uint64_t>(one.value.data()));
    } else if (i.type == BasicType::kInt64) {
      s += std::to_string(Load<std::int64_t>(one.value.data()));
    } else if (i.type == BasicType::kBool) {
      s += v != 0 ? "1" : "0";
    } else if (v == std::floor(v) && std::isfinite(v)) {
      s += std::to_string(static_cast<std::int64_t>(v));  // JavaScript prints integers so
    } else {
      s += FloatHex(v);
    }
  }
  return s;
}

json Ours(const fs::path& path) {
  Reader r(path.string());
  json out;
  out["version"] = r.version();
  out["timestamp"] = std::to_string(r.start_timestamp());
  out["compat_flags"] = r.compat_flags();
  out["incompat_flags"] = r.incompat_flags();
  json appended = json::array();
  for (std::uint64_t a : r.appended_offsets()) appended.push_back(std::to_string(a));
  out["appended_offsets"] = appended;
  out["info"] = json::object();
  for (const Info& i : r.info()) {
    if (!i.in_data_section) out["info"][i.name] = InfoValue(i);
  }
  out["multi_info"] = json::object();
  for (const Info& i : r.multi_info()) {
    if (!i.in_data_section) out["multi_info"][i.key].push_back(InfoValue(i));
  }
  // Last message of each name in the definitions section: a 'P' (default types 0) or a 'Q'.
  std::map<std::string, std::pair<std::uint64_t, json>> params;
  for (const auto& [name, p] : r.parameters()) {
    params[name] = {p.file_offset, {{"value", FloatHex(p.value)}, {"default_types", 0}}};
  }
  for (const Parameter& q : r.default_parameters()) {
    auto& slot = params[q.name];
    if (q.file_offset >= slot.first) {
      slot = {q.file_offset, {{"value", FloatHex(q.value)}, {"default_types", q.default_types}}};
    }
  }
  out["parameters"] = json::object();
  for (const auto& [name, p] : params) out["parameters"][name] = p.second;
  out["formats"] = json::object();
  for (const Format& f : r.formats()) {
    json fields = json::array();
    for (const Field& field : f.fields) {
      std::string text = field.type_name;
      if (field.is_array) {
        text.push_back('[');
        text += std::to_string(field.array_length);
        text.push_back(']');
      }
      text += " ";
      text += field.name;
      fields.push_back(text);
    }
    out["formats"][f.name] = fields;
  }

  // Canonical text per message, then per subscription in (timestamp, offset) order.
  struct Line {
    std::uint64_t timestamp, offset;
    std::string text;
  };
  std::map<std::uint16_t, std::vector<Line>> lines;
  r.ReadData([&](const DataMessage& m) {
    std::string text;
    for (const Column& c : m.subscription->columns) {
      if (!text.empty() || &c != &m.subscription->columns.front()) text += ",";
      AppendLeaf(m, c, text);
    }
    lines[m.subscription->msg_id].push_back({m.timestamp, m.file_offset, std::move(text)});
  });
  EXPECT_TRUE(r.warnings().empty()) << path << ": " << r.warnings().front().what;
  EXPECT_FALSE(r.truncated());
  out["subscriptions"] = json::array();
  std::vector<const Subscription*> subs;
  for (const Subscription& s : r.subscriptions()) subs.push_back(&s);
  std::sort(subs.begin(), subs.end(), [](auto* a, auto* b) { return a->msg_id < b->msg_id; });
  for (const Subscription* s : subs) {
    auto& l = lines[s->msg_id];
    std::stable_sort(l.begin(), l.end(), [](const Line& a, const Line& b) {
      return a.timestamp != b.timestamp ? a.timestamp < b.timestamp : a.offset < b.offset;
    });
    mavlink::Sha256 sha;
    for (std::size_t k = 0; k < l.size(); ++k) {
      if (k > 0) sha.Update({reinterpret_cast<const std::uint8_t*>("\n"), 1});
      sha.Update({reinterpret_cast<const std::uint8_t*>(l[k].text.data()), l[k].text.size()});
    }
    const auto digest = sha.Final();
    json j{{"msg_id", s->msg_id},
           {"multi_id", s->multi_id},
           {"name", s->name},
           {"count", s->count},
           {"sha256", HexBytes(digest)}};
    j["first"] = l.empty() ? json(nullptr) : json(std::to_string(l.front().timestamp));
    j["last"] = l.empty() ? json(nullptr) : json(std::to_string(l.back().timestamp));
    out["subscriptions"].push_back(j);
  }
  std::vector<LogMessage> logs = r.logs();
  std::stable_sort(logs.begin(), logs.end(), [](const LogMessage& a, const LogMessage& b) {
    return a.timestamp != b.timestamp ? a.timestamp < b.timestamp : a.file_offset < b.file_offset;
  });
  out["logs"] = json::array();
  for (const LogMessage& l : logs) {
    out["logs"].push_back({{"level", l.level},
                           {"tag", l.tagged ? json(l.tag) : json(nullptr)},
                           {"timestamp", std::to_string(l.timestamp)},
                           {"text", HexText(l.text)}});
  }
  out["dropouts"] = json::array();
  for (const Dropout& d : r.dropouts()) out["dropouts"].push_back(d.duration_ms);
  return out;
}

json Theirs(const fs::path& path) {
  const std::string cmd = std::string("'") + FNMPC_NODE + "' '" + FNMPC_ULOG_INTEROP_DIR +
                          "/interop.mjs' '" + path.string() + "'";
  std::FILE* p = popen(cmd.c_str(), "r");
  if (p == nullptr) throw std::runtime_error("cannot run " + cmd);
  std::string text;
  char buf[65536];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) text.append(buf, n);
  const int status = pclose(p);
  if (status != 0)
    throw std::runtime_error(cmd + " failed (status " + std::to_string(status) + ")");
  return json::parse(text);
}

class UlogInterop : public ::testing::TestWithParam<std::string> {};

TEST_P(UlogInterop, AgreesWithFoxgloveUlog) {
  const fs::path path = kLogs / GetParam();
  ASSERT_TRUE(fs::is_regular_file(path)) << path << " missing (../shared/px4-logs beside the repo)";
  const json ours = Ours(path);
  const json theirs = Theirs(path);
  for (const char* key :
       {"version", "timestamp", "compat_flags", "incompat_flags", "appended_offsets", "info",
        "multi_info", "parameters", "formats", "logs", "dropouts"}) {
    EXPECT_EQ(ours[key], theirs[key]) << key << " differs";
  }
  ASSERT_EQ(ours["subscriptions"].size(), theirs["subscriptions"].size());
  std::size_t messages = 0;
  for (std::size_t i = 0; i < ours["subscriptions"].size(); ++i) {
    EXPECT_EQ(ours["subscriptions"][i], theirs["subscriptions"][i]);
    messages += ours["subscriptions"][i]["count"].get<std::size_t>();
  }
  // Not vacuous: the logs have data, parameters and formats.
  EXPECT_GT(messages, 1000u);
  EXPECT_GT(ours["parameters"].size(), 100u);
  EXPECT_GT(ours["formats"].size(), 10u);
  std::printf(
      "%s: %zu subscriptions, %zu data messages, %zu parameters, %zu logged strings agree\n",
      GetParam().c_str(), ours["subscriptions"].size(), messages, ours["parameters"].size(),
      ours["logs"].size());
}

INSTANTIATE_TEST_SUITE_P(SampleLogs, UlogInterop,
                         ::testing::Values("real/battery_brownout.ulg", "real/ekf_failure.ulg",
                                           "real/motor_failure.ulg", "sitl/sih_quadx_sysid_a.ulg"),
                         [](const auto& info) {
                           std::string n = fs::path(info.param).stem().string();
                           return n;
                         });

}  // namespace
}  // namespace fnmpc::ulog
