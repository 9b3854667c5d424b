// SPDX-License-Identifier: BSD-3-Clause
// The ULog reader allocates nothing per data message (docs/ulog.md, "Memory"): the C
// allocation calls of Reader::ReadData (tests/support/malloc_counter.hpp) are the same for a
// log of 50 and of 20000 data messages, and few on the 155638-message SITL log.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "fnmpc/ulog/reader.hpp"
#include "tests/support/malloc_counter.hpp"
#include "tests/ulog/ulog_builder.hpp"

namespace fnmpc::ulog {
namespace {

namespace fs = std::filesystem;

std::string WriteLog(int messages) {
  testing::Builder b;
  b.FlagBits(0);
  b.Format("t:uint64_t timestamp;float[3] v;int16_t k;uint8_t[2] _padding0;");
  b.Add(0, 0, "t");
  b.Add(1, 1, "t");
  for (int i = 0; i < messages; ++i) {
    testing::Bytes r;
    testing::Put(r, std::uint64_t(1000 + i));
    for (float f : {1.0f * i, 2.0f, 3.0f}) testing::Put(r, f);
    testing::Put(r, std::int16_t(i));
    b.Data(static_cast<std::uint16_t>(i % 2), r);
    if (i % 1000 == 999) b.Sync();
  }
  const fs::path p =
      fs::temp_directory_path() / ("fnmpc_ulog_alloc_" + std::to_string(messages) + ".ulg");
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(b.bytes().data()), static_cast<std::streamsize>(b.size()));
  return p.string();
}

long MallocsOfReadData(Reader& r, double* sum) {
  return fnmpc::testing::CountMallocs([&] {
    r.ReadData([&](const DataMessage& m) {
      for (const Column& c : m.subscription->columns) *sum += m.Value(c);
    });
  });
}

TEST(UlogAllocation, NoAllocationPerDataMessage) {
  Reader small(WriteLog(50));
  Reader large(WriteLog(20000));
  double sum_small = 0, sum_large = 0;
  const long a_small = MallocsOfReadData(small, &sum_small);
  const long a_large = MallocsOfReadData(large, &sum_large);
  EXPECT_GT(sum_large, sum_small);  // every message was read
  EXPECT_EQ(a_large, a_small);
  EXPECT_LT(a_small, 100);  // the subscriptions and their column tables
  std::printf("ReadData: %ld allocation calls for 50 messages, %ld for 20000\n", a_small, a_large);
}

TEST(UlogAllocation, FewAllocationsOnTheSitlLog) {
  const fs::path p =
      fs::path(FNMPC_SOURCE_DIR) / ".." / "shared" / "px4-logs" / "sitl" / "sih_quadx_sysid_a.ulg";
  ASSERT_TRUE(fs::is_regular_file(p)) << p;
  Reader r(p.string());
  double sum = 0;
  const long calls = MallocsOfReadData(r, &sum);
  std::uint64_t messages = 0;
  for (const Subscription& s : r.subscriptions()) messages += s.count;
  EXPECT_EQ(messages, 155638u);
  // Subscriptions (110, each with its name and column names) and 30 logged strings.
  EXPECT_LT(calls, 20000);
  std::printf("SITL log: %ld allocation calls for %llu data messages\n", calls,
              static_cast<unsigned long long>(messages));
}

}  // namespace
}  // namespace fnmpc::ulog
