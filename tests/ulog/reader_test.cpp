// SPDX-License-Identifier: BSD-3-Clause
// The ULog reader on synthetic files written by the test (docs/ulog.md): nested types used
// before their definition, arrays, padding (also an omitted trailing one), multi-instance
// topics, information / multi-information / parameters / default parameters, logged strings,
// dropouts, sync, appended data, truncated tails, corrupt messages (resynchronised or strict)
// and a robustness loop over random truncations and byte flips.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "fnmpc/ulog/reader.hpp"
#include "fnmpc/ulog/series.hpp"
#include "tests/ulog/ulog_builder.hpp"

namespace fnmpc::ulog {
namespace {

namespace fs = std::filesystem;
using testing::Builder;
using testing::Bytes;
using testing::Put;
using testing::PutText;

std::string WriteFile(const Bytes& b, const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("fnmpc_ulog_test_" + name + ".ulg");
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  return p.string();
}

// A record of "sample": uint64 timestamp; float[3] v; int16 k; uint8 _padding0[6] (omittable).
Bytes Sample(std::uint64_t ts, float v0, std::int16_t k, bool with_padding = false) {
  Bytes r;
  Put(r, ts);
  Put(r, v0);
  Put(r, v0 + 1);
  Put(r, v0 + 2);
  Put(r, k);
  if (with_padding) r.insert(r.end(), 6, 0);
  return r;
}

// A small complete log: two topics, one with two instances, strings, params, syncs.
Builder SmallLog(int messages = 20) {
  Builder b;
  b.FlagBits(0);
  b.Format("sample:uint64_t timestamp;float[3] v;int16_t k;uint8_t[6] _padding0;");
  b.Format("pair:uint64_t timestamp;double a;int64_t b;bool ok;char[4] tag;");
  b.Info("char[3] sys_name", {'P', 'X', '4'});
  b.ParamInt("SYS_AUTOSTART", 4001);
  b.ParamFloat("MPC_THR_HOVER", 0.5f);
  b.Add(0, 0, "sample");
  b.Add(1, 1, "sample");
  b.Add(0, 2, "pair");
  for (int i = 0; i < messages; ++i) {
    b.Data(0, Sample(1000 + 10 * i, static_cast<float>(i), static_cast<std::int16_t>(-i)));
    b.Data(1, Sample(1005 + 10 * i, 100.0f + i, static_cast<std::int16_t>(i), true));
    Bytes pr;
    Put(pr, std::uint64_t(1002 + 10 * i));
    Put(pr, 0.25 * i);
    Put(pr, std::int64_t{-5000000000} * i);
    pr.push_back(i % 2);
    PutText(pr, std::string("ab\0d", 4));
    b.Data(2, pr);
    if (i % 5 == 4) b.Sync();
    if (i == 7) b.Log('6', 1070, "hello");
  }
  return b;
}

TEST(UlogReader, NestedTypesArraysPaddingAndInstances) {
  Builder b;
  b.FlagBits(0);
  // `outer` uses `inner` before inner is defined (allowed by the spec).
  b.Format(
      "outer:uint64_t timestamp;inner[2] in;float x;char[4] name;bool ok;uint8_t[3] _padding0;");
  b.Format("inner:uint64_t timestamp;float[2] v;int16_t k;uint8_t[2] _padding0;");
  b.Add(0, 0, "outer");
  b.Add(1, 1, "outer");
  auto record = [](std::uint64_t ts, float base, bool padding) {
    Bytes r;
    Put(r, ts);
    for (int e = 0; e < 2; ++e) {
      Put(r, ts + e);
      Put(r, base + 10 * e);
      Put(r, base + 10 * e + 1);
      Put(r, std::int16_t(-3 - e));
      r.insert(r.end(), 2, 0xAB);  // inner padding: present, ignored
    }
    Put(r, base * 2);
    PutText(r, "qwer");
    r.push_back(1);
    if (padding) r.insert(r.end(), 3, 0);
    return r;
  };
  b.Data(0, record(5000, 1.5f, false));  // trailing padding omitted
  b.Data(1, record(5001, 7.0f, true));   // trailing padding logged
  b.Data(0, record(5100, 2.5f, true));
  Reader r(WriteFile(b.bytes(), "nested"));
  ASSERT_NE(r.FindFormat("outer"), nullptr);
  std::vector<double> seen;
  r.ReadData([&](const DataMessage& m) {
    const Subscription& s = *m.subscription;
    seen.push_back(m.Value(*s.FindColumn("in[1].v[0]")));
    seen.push_back(m.Value(*s.FindColumn("in[0].k")));
    seen.push_back(m.Value(*s.FindColumn("x")));
    seen.push_back(m.Value(*s.FindColumn("ok")));
    EXPECT_EQ(s.FindColumn("name")->length, 4u);
    EXPECT_TRUE(s.FindColumn("name")->is_string());
    EXPECT_EQ(s.FindColumn("_padding0"), nullptr);
    EXPECT_EQ(s.FindColumn("in[0]._padding0"), nullptr);
  });
  ASSERT_TRUE(r.warnings().empty()) << r.warnings().front().what;
  const Format& outer = *r.FindFormat("outer");
  EXPECT_EQ(outer.size, 8u + 2 * 20 + 4 + 4 + 1 + 3);
  EXPECT_EQ(outer.trailing_padding, 3u);
  ASSERT_EQ(r.subscriptions().size(), 2u);
  const std::vector<std::string> expected_columns{
      "timestamp",  "in[0].timestamp", "in[0].v[0]", "in[0].v[1]", "in[0].k", "in[1].timestamp",
      "in[1].v[0]", "in[1].v[1]",      "in[1].k",    "x",          "name",    "ok"};
  std::vector<std::string> columns;
  for (const Column& c : r.subscriptions()[0].columns) columns.push_back(c.name);
  EXPECT_EQ(columns, expected_columns);
  EXPECT_EQ(seen, (std::vector<double>{11.5, -3, 3, 1, 17, -3, 14, 1, 12.5, -3, 5, 1}));
  EXPECT_EQ(r.subscriptions()[0].count, 2u);
  EXPECT_EQ(r.subscriptions()[1].multi_id, 1);
  EXPECT_EQ(r.subscriptions()[0].max_interval, 100u);

  // Per-topic columns, one series per instance.
  const LogSeries series = LogSeries::Read(r, {"outer"});
  const TopicSeries& i0 = series.Get("outer", 0);
  const TopicSeries& i1 = series.Get("outer", 1);
  EXPECT_EQ(i0.timestamp, (std::vector<std::uint64_t>{5000, 5100}));
  EXPECT_EQ(i0.Column("in[0].v[1]"), (std::vector<double>{2.5, 3.5}));
  EXPECT_EQ(i1.Column("x"), (std::vector<double>{14.0}));
  EXPECT_FALSE(i0.Has("name"));  // strings are not numeric columns
  EXPECT_THROW((void)series.Get("outer", 2), std::runtime_error);
  try {
    (void)i0.Column("y");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("topic 'outer' (instance 0) has no field 'y'"),
              std::string::npos)
        << e.what();
  }
}

TEST(UlogReader, InfoParametersLogsDropoutsAndSync) {
  Builder b;
  b.FlagBits(0);
  b.Format("t:uint64_t timestamp;float x;");
  b.Info("char[3] sys_name", {'P', 'X', '4'});
  Bytes release;
  Put(release, std::uint32_t{0x010F01FF});
  b.Info("uint32_t ver_sw_release", release);
  b.Info("char[5] perf", {'a', 'b', 'c', 'd', 'e'}, 'M');
  b.Info("char[2] perf", {'f', 'g'}, 'M', true);
  b.Info("char[1] perf", {'z'}, 'M');
  b.ParamInt("SYS_AUTOSTART", 4001);
  b.ParamFloat("MPC_THR_HOVER", 0.58f);
  b.ParamFloat("MPC_THR_HOVER", 0.5f, 'Q', 1);
  b.Add(0, 0, "t");
  Bytes d;
  Put(d, std::uint64_t{2000});
  Put(d, 1.0f);
  b.Data(0, d);
  b.Log('6', 2001, "armed");
  b.Tagged('3', 7, 2002, "motor");
  b.Dropout(35);
  b.Sync();
  b.ParamFloat("MPC_THR_HOVER", 0.6f);  // changed in flight
  b.Info("char[2] late", {'o', 'k'});
  Reader r(WriteFile(b.bytes(), "info"));
  EXPECT_EQ(r.FindInfo("sys_name")->AsString(), "PX4");
  EXPECT_EQ(*r.FindInfo("ver_sw_release")->AsNumber(), double{0x010F01FF});
  EXPECT_EQ(r.MultiInfoStrings("perf"), (std::vector<std::string>{"abcdefg", "z"}));
  EXPECT_EQ(*r.ParameterValue("SYS_AUTOSTART"), 4001.0);
  EXPECT_EQ(*r.ParameterValue("MPC_THR_HOVER"), double{0.58f});
  ASSERT_EQ(r.default_parameters().size(), 1u);
  EXPECT_EQ(r.default_parameters()[0].default_types, 1);
  r.ReadData({});
  ASSERT_EQ(r.logs().size(), 2u);
  EXPECT_EQ(r.logs()[0].text, "armed");
  EXPECT_FALSE(r.logs()[0].tagged);
  EXPECT_EQ(r.logs()[1].tag, 7);
  EXPECT_EQ(r.logs()[1].level, '3');
  EXPECT_EQ(r.logs()[1].timestamp, 2002u);
  ASSERT_EQ(r.dropouts().size(), 1u);
  EXPECT_EQ(r.dropouts()[0].duration_ms, 35);
  EXPECT_EQ(r.dropouts()[0].last_timestamp, 2000u);
  EXPECT_EQ(r.sync_count(), 1u);
  ASSERT_EQ(r.parameter_changes().size(), 1u);
  EXPECT_EQ(r.parameter_changes()[0].value, double{0.6f});
  EXPECT_EQ(r.parameter_changes()[0].last_timestamp, 2000u);
  EXPECT_EQ(r.FindInfo("late")->AsString(), "ok");
  EXPECT_TRUE(r.FindInfo("late")->in_data_section);
  // A second pass gives the same, not twice as much.
  r.ReadData({});
  EXPECT_EQ(r.logs().size(), 2u);
  EXPECT_EQ(r.info().size(), 3u);
}

TEST(UlogReader, AppendedDataAfterACutMessage) {
  Builder b;
  b.FlagBits(1, {0, 0, 0});
  const std::size_t flag_offsets = 16 + 3 + 16;  // appended_offsets[0] in the file
  b.Format("t:uint64_t timestamp;float x;");
  b.Add(0, 0, "t");
  auto rec = [](std::uint64_t ts, float x) {
    Bytes d;
    Put(d, ts);
    Put(d, x);
    return d;
  };
  b.Data(0, rec(1, 1.0f));
  b.Data(0, rec(2, 2.0f));
  // The log stops inside a message (the logger was cut), then crash data is appended.
  b.Data(0, rec(3, 3.0f));
  b.bytes().resize(b.size() - 5);
  const std::uint64_t appended = b.size();
  std::memcpy(b.bytes().data() + flag_offsets, &appended, 8);
  b.Data(0, rec(4, 4.0f));
  b.Log('0', 5, "hardfault");
  Reader r(WriteFile(b.bytes(), "appended"));
  EXPECT_EQ(r.appended_offsets()[0], appended);
  std::vector<double> x;
  r.ReadData([&](const DataMessage& m) { x.push_back(m.Value(m.subscription->columns[1])); });
  EXPECT_EQ(x, (std::vector<double>{1, 2, 4}));
  ASSERT_EQ(r.logs().size(), 1u);
  EXPECT_EQ(r.logs()[0].text, "hardfault");
  EXPECT_FALSE(r.truncated());
  ASSERT_EQ(r.warnings().size(), 1u);
  EXPECT_NE(r.warnings()[0].what.find("where appended data starts (offset " +
                                      std::to_string(appended) + ")"),
            std::string::npos)
      << r.warnings()[0].what;
}

TEST(UlogReader, UnknownIncompatibleFlagIsRefused) {
  Builder b;
  b.FlagBits(0x02);
  b.Format("t:uint64_t timestamp;float x;");
  try {
    Reader r(WriteFile(b.bytes(), "incompat"));
    FAIL() << "read a log with an unknown incompatible flag";
  } catch (const FormatError& e) {
    EXPECT_EQ(e.offset(), 16u + 3 + 8);
    EXPECT_NE(std::string(e.what()).find("unknown incompatible flag bits 0x02"), std::string::npos)
        << e.what();
  }
}

TEST(UlogReader, TruncatedTailKeepsWhatWasRead) {
  Builder full = SmallLog(20);
  const std::size_t last = full.size();  // the last message: a data message of 3 + 2 + 22 bytes
  full.Data(0, Sample(5000, 1.0f, 2));
  std::uint64_t complete = 0;
  {
    Reader r(WriteFile(Builder(full).bytes(), "full"));
    r.ReadData([&](const DataMessage&) { ++complete; });
    EXPECT_FALSE(r.truncated());
    EXPECT_TRUE(r.warnings().empty());
  }
  EXPECT_EQ(complete, 61u);
  // Cut the last message at every byte.
  for (std::size_t cut = last + 1; cut < full.size(); ++cut) {
    Bytes b = Builder(full).bytes();
    b.resize(cut);
    Reader r(WriteFile(b, "cut"));
    std::uint64_t n = 0;
    r.ReadData([&](const DataMessage&) { ++n; });
    EXPECT_EQ(n, complete - 1) << "cut at " << cut;
    EXPECT_TRUE(r.truncated());
    ASSERT_EQ(r.warnings().size(), 1u);
    EXPECT_EQ(r.warnings()[0].offset, last);
    EXPECT_NE(r.warnings()[0].what.find("truncated: the file ends inside"), std::string::npos)
        << r.warnings()[0].what;
  }
}

TEST(UlogReader, CorruptMessageSizeResynchronisesOrThrowsInStrictMode) {
  Builder b = SmallLog(0);
  auto rec = [](std::uint64_t ts) { return Sample(ts, 1.0f, 1); };
  b.Data(0, rec(10));
  const std::size_t bad = b.size();
  Bytes short_record = rec(11);
  short_record.resize(10);  // shorter than the format allows
  b.Data(0, short_record);
  b.Data(0, rec(12));  // lost: before the next sync
  b.Sync();
  b.Data(0, rec(13));
  const std::string path = WriteFile(b.bytes(), "corrupt");
  {
    Reader r(path);
    std::vector<std::uint64_t> ts;
    r.ReadData([&](const DataMessage& m) { ts.push_back(m.timestamp); });
    EXPECT_EQ(ts, (std::vector<std::uint64_t>{10, 13}));
    ASSERT_EQ(r.warnings().size(), 1u);
    EXPECT_EQ(r.warnings()[0].offset, bad);
    EXPECT_NE(r.warnings()[0].what.find("data message of 10 bytes for 'sample' (msg_id 0)"),
              std::string::npos)
        << r.warnings()[0].what;
    EXPECT_NE(r.warnings()[0].what.find("skipped to the sync message at offset"),
              std::string::npos);
  }
  {
    Reader r(path, {.buffer_size = 0, .strict = true});
    try {
      r.ReadData({});
      FAIL() << "strict mode accepted a corrupt message";
    } catch (const FormatError& e) {
      EXPECT_EQ(e.offset(), bad);
      EXPECT_NE(std::string(e.what()).find(path + ": offset " + std::to_string(bad) +
                                           ": corrupt message"),
                std::string::npos)
          << e.what();
    }
  }
  // A corrupt message size without a sync after it: the rest is skipped, with both offsets.
  Builder c = SmallLog(0);
  c.Data(0, rec(10));
  const std::size_t bad2 = c.size();
  c.Data(7, rec(11));  // msg_id 7 is not subscribed
  c.Data(0, rec(12));
  Reader r(WriteFile(c.bytes(), "corrupt2"));
  std::uint64_t n = 0;
  r.ReadData([&](const DataMessage&) { ++n; });
  EXPECT_EQ(n, 1u);
  ASSERT_EQ(r.warnings().size(), 1u);
  EXPECT_NE(r.warnings()[0].what.find("msg_id 7 not subscribed"), std::string::npos);
  EXPECT_NE(r.warnings()[0].what.find("data from offset " + std::to_string(bad2) + " to " +
                                      std::to_string(c.size()) + " skipped"),
            std::string::npos)
      << r.warnings()[0].what;
}

TEST(UlogReader, ClearErrorsForFilesThatAreNotULog) {
  auto error_of = [](const Bytes& b, const std::string& name) -> std::string {
    try {
      Reader r(WriteFile(b, name));
      r.ReadData({});
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(error_of({'U', 'L', 'o'}, "short").find("offset 0: not a ULog file: shorter"),
            std::string::npos);
  EXPECT_NE(error_of(Bytes(32, 'x'), "magic").find("offset 0: not a ULog file"), std::string::npos);
  Builder bad_format;
  bad_format.FlagBits(0);
  bad_format.Format("t:uint64_t timestamp;float");
  EXPECT_NE(error_of(bad_format.bytes(), "badformat")
                .find("offset 59: format definition 't:uint64_t timestamp;float': malformed field "
                      "'float'"),
            std::string::npos)
      << error_of(bad_format.bytes(), "badformat");
  Builder cycle;
  cycle.FlagBits(0);
  cycle.Format("a:uint64_t timestamp;b x;");
  cycle.Format("b:a y;");
  cycle.Add(0, 0, "a");
  EXPECT_NE(error_of(cycle.bytes(), "cycle").find("nested types form a cycle"), std::string::npos);
  Builder unknown_type;
  unknown_type.FlagBits(0);
  unknown_type.Format("a:uint64_t timestamp;nothing x;");
  unknown_type.Add(0, 0, "a");
  EXPECT_NE(error_of(unknown_type.bytes(), "unknowntype")
                .find("format 'a': field 'x' has unknown type 'nothing'"),
            std::string::npos);
  EXPECT_THROW(Reader("/nonexistent/x.ulg"), std::runtime_error);
  EXPECT_THROW(Reader(fs::temp_directory_path().string()), std::runtime_error);
}

TEST(UlogReader, StreamsALogLargerThanItsBuffer) {
  // ~3 MB of messages, among them 60 KB records that straddle the 128 KiB buffer's refills.
  Builder b;
  b.FlagBits(0);
  b.Format("big:uint64_t timestamp;uint8_t[60000] blob;");
  b.Format("t:uint64_t timestamp;float x;");
  b.Add(0, 0, "big");
  b.Add(0, 1, "t");
  std::uint64_t ts = 0;
  double sum_expected = 0;
  for (int i = 0; i < 50; ++i) {
    Bytes big;
    Put(big, ++ts);
    for (int k = 0; k < 60000; ++k) big.push_back(static_cast<std::uint8_t>((i + k) & 0xFF));
    b.Data(0, big);
    for (int j = 0; j < 37; ++j) {
      Bytes d;
      Put(d, ++ts);
      Put(d, static_cast<float>(j));
      sum_expected += j;
      b.Data(1, d);
    }
  }
  Reader r(WriteFile(b.bytes(), "big"), {.buffer_size = 1, .strict = true});
  double sum = 0;
  std::uint64_t big_ok = 0;
  std::uint64_t previous = 0;
  r.ReadData([&](const DataMessage& m) {
    EXPECT_EQ(m.timestamp, previous + 1);
    previous = m.timestamp;
    if (m.subscription->name == "t") {
      sum += m.Value(m.subscription->columns[1]);
    } else {
      const auto i = static_cast<int>(big_ok);
      const Column& last = m.subscription->columns.back();  // blob[59999]
      big_ok += m.Value(last) == static_cast<double>((i + 59999) & 0xFF) ? 1 : 0;
    }
  });
  EXPECT_EQ(sum, sum_expected);
  EXPECT_EQ(big_ok, 50u);
  EXPECT_EQ(previous, ts);
}

TEST(UlogReader, RandomTruncationsAndByteFlipsNeverCrash) {
  const Bytes good = SmallLog(30).bytes();
  std::mt19937 rng(51);
  int errors = 0;
  int warned = 0;
  for (int trial = 0; trial < 1500; ++trial) {
    Bytes b = good;
    if (trial % 3 == 0) {
      b.resize(std::uniform_int_distribution<std::size_t>(0, b.size())(rng));
    } else {
      const int flips = 1 + trial % 4;
      for (int f = 0; f < flips; ++f) {
        b[std::uniform_int_distribution<std::size_t>(0, b.size() - 1)(rng)] ^=
            static_cast<std::uint8_t>(1u << std::uniform_int_distribution<int>(0, 7)(rng));
      }
    }
    try {
      Reader r(WriteFile(b, "fuzz"));
      std::uint64_t n = 0;
      double sink = 0;
      r.ReadData([&](const DataMessage& m) {
        ++n;
        for (const Column& c : m.subscription->columns) {
          const double v = m.Value(c);
          if (!std::isnan(v)) sink += v * 0;
        }
      });
      const LogSeries s = LogSeries::Read(r, {"sample", "pair"});
      warned += r.warnings().empty() ? 0 : 1;
      EXPECT_LE(n, 90u + 5u);
      EXPECT_EQ(sink, 0.0);
    } catch (const FormatError& e) {
      ++errors;
      EXPECT_NE(std::string(e.what()).find(": offset "), std::string::npos) << e.what();
    }
  }
  // Both outcomes occur (a flip in the definitions is an error, one in the data a warning).
  EXPECT_GT(errors, 50);
  EXPECT_GT(warned, 200);
  std::printf("1500 damaged logs: %d FormatError, %d read with warnings\n", errors, warned);
}

}  // namespace
}  // namespace fnmpc::ulog
