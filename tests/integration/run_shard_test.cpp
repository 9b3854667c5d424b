// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc run --shard I/N` and `fnmpc merge`: the shards of an experiment merge into the very
// folder the unsharded run writes (byte for byte, with the timings off); a resumed shard
// flies only what an interrupted attempt left; the merge refuses shards that are not one
// experiment, missing shards and unfinished runs, naming the run and its seed.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/fnmpc/run_folder.hpp"
#include "apps/fnmpc/scenario_runner.hpp"
#include "fnmpc/config/scenario_yaml.hpp"

namespace fnmpc::app {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

/// Every file below `dir` (relative path -> bytes).
std::map<std::string, std::string> Files(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    std::ifstream f(e.path(), std::ios::binary);
    files[fs::relative(e.path(), dir).string()] = {std::istreambuf_iterator<char>(f),
                                                   std::istreambuf_iterator<char>()};
  }
  return files;
}

void ExpectSameFolder(const std::string& a, const std::string& b) {
  const auto fa = Files(a), fb = Files(b);
  ASSERT_EQ(fa.size(), fb.size()) << a << " vs " << b;
  for (const auto& [name, bytes] : fa) {
    ASSERT_TRUE(fb.count(name) == 1) << name;
    EXPECT_TRUE(bytes == fb.at(name)) << name << " differs";
  }
}

std::string MessageOf(const std::vector<std::string>& shards, const std::string& out) {
  try {
    MergeRunFolders(shards, out);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

class RunShardTest : public ::testing::Test {
 protected:
  void SetUp() override {
    file_ = std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/triangle.yaml";
    sc_ = Shortened(config::LoadScenarioFile(file_), 20.0);
    base_ = testing::TempDir() + "/fnmpc-shard-" + std::to_string(getpid());
    fs::remove_all(base_);
    options_.runs = 3;
    options_.seed = 4;
    options_.timing = false;
    options_.scenario_file = file_;
  }
  void TearDown() override { fs::remove_all(base_); }
  json Fly(const std::string& name, Shard shard, bool resume = false) {
    RunFolderOptions o = options_;
    o.shard = shard;
    o.resume = resume;
    return RunFolder(sc_, o, base_ + "/" + name);
  }

  std::string file_, base_;
  config::ScenarioConfig sc_;
  RunFolderOptions options_;
};

TEST_F(RunShardTest, ShardsMergeIntoTheUnshardedFolderByteForByte) {
  // Given the 3 runs flown whole, and as shards 0/2 (runs 1, 3) and 1/2 (run 2),
  const json whole = Fly("whole", {});
  const json s0 = Fly("s0", ParseShard("0/2"));
  const json s1 = Fly("s1", ParseShard("1/2"));
  EXPECT_EQ(s0["runs"].get<int>(), 2);
  EXPECT_EQ(s1["runs"].get<int>(), 1);
  EXPECT_EQ(s0["shard"], "0/2");
  EXPECT_TRUE(fs::exists(base_ + "/s0/run-03/leader.csv"));
  EXPECT_FALSE(fs::exists(base_ + "/s0/run-02"));
  // when merged (in either order),
  const json merged = MergeRunFolders({base_ + "/s1", base_ + "/s0"}, base_ + "/merged");
  // then the folder is the unsharded one, every file byte for byte.
  EXPECT_TRUE(merged["complete"].get<bool>());
  EXPECT_EQ(merged["runs"].get<int>(), 3);
  EXPECT_FALSE(merged.contains("shard"));
  ExpectSameFolder(base_ + "/whole", base_ + "/merged");
  EXPECT_EQ(whole["run_summaries"][1]["seed"].get<int>(), 5);

  // A shard whose run was interrupted is resumed: the complete run is kept as it was, the
  // other flown, and the folder is the uninterrupted one.
  fs::copy(base_ + "/s0", base_ + "/s0-resumed", fs::copy_options::recursive);
  fs::remove(base_ + "/s0-resumed/run-03/summary.json");
  fs::remove(base_ + "/s0-resumed/run-01/follower1.csv");  // kept: not flown again
  Fly("s0-resumed", ParseShard("0/2"), /*resume=*/true);
  EXPECT_FALSE(fs::exists(base_ + "/s0-resumed/run-01/follower1.csv"));
  fs::copy(base_ + "/s0/run-01/follower1.csv", base_ + "/s0-resumed/run-01/follower1.csv");
  ExpectSameFolder(base_ + "/s0", base_ + "/s0-resumed");

  // Refused merges, each naming what is wrong.
  EXPECT_NE(MessageOf({base_ + "/s0"}, base_ + "/m1").find("shard 1/2 is missing"),
            std::string::npos);
  EXPECT_NE(MessageOf({base_ + "/s0", base_ + "/s0-resumed", base_ + "/s1"}, base_ + "/m2")
                .find("given twice"),
            std::string::npos);
  EXPECT_NE(MessageOf({base_ + "/whole"}, base_ + "/m3").find("not a shard folder"),
            std::string::npos);
  // A single shard 0/1 is a shard folder: it merges on its own into the whole folder.
  Fly("only", ParseShard("0/1"));
  MergeRunFolders({base_ + "/only"}, base_ + "/only-merged");
  ExpectSameFolder(base_ + "/whole", base_ + "/only-merged");
  // another experiment (another first seed) in shard 1,
  const auto edited = [&](const std::string& from, const std::string& to, auto&& edit) {
    fs::copy(base_ + from, base_ + to, fs::copy_options::recursive);
    std::ifstream f(base_ + to + "/summary.json");
    json s = json::parse(f);
    edit(&s);
    std::ofstream(base_ + to + "/summary.json") << s.dump(2);
  };
  edited("/s1", "/s1-other", [](json* s) { (*s)["first_seed"] = 9; });
  EXPECT_NE(MessageOf({base_ + "/s0", base_ + "/s1-other"}, base_ + "/m4").find("first_seed"),
            std::string::npos);
  // an unfinished run (the summary of an interrupted attempt), named with its seed.
  edited("/s1", "/s1-cut", [](json* s) { (*s)["run_summaries"][0]["complete"] = false; });
  const std::string cut = MessageOf({base_ + "/s0", base_ + "/s1-cut"}, base_ + "/m5");
  EXPECT_NE(cut.find("run-02 (seed 5)"), std::string::npos) << cut;
  EXPECT_NE(cut.find("not complete"), std::string::npos) << cut;
  for (const char* m : {"/m1", "/m2", "/m3", "/m4", "/m5"}) {
    EXPECT_FALSE(fs::exists(base_ + "/" + m + "/summary.json")) << m;
  }
}

TEST_F(RunShardTest, ResumeRefusesAnotherExperimentsFolder) {
  // Given a shard folder of a 20 s experiment,
  Fly("s1", ParseShard("1/2"));
  RunFolderOptions o = options_;
  o.shard = ParseShard("1/2");
  o.resume = true;
  EXPECT_NO_THROW(CheckResumable(sc_, o, base_ + "/s1"));
  // then resuming it with another duration, shard or timing is refused, naming the key.
  const auto refusal = [&](const config::ScenarioConfig& sc, const RunFolderOptions& ro) {
    try {
      CheckResumable(sc, ro, base_ + "/s1");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  config::ScenarioConfig shorter = sc_;
  shorter.duration = 19.0;
  EXPECT_NE(refusal(shorter, o).find("key 'duration_s'"), std::string::npos);
  RunFolderOptions other = o;
  other.shard = ParseShard("0/2");
  EXPECT_NE(refusal(sc_, other).find("key 'shard'"), std::string::npos);
  other = o;
  other.timing = true;
  EXPECT_NE(refusal(sc_, other).find("key 'timing'"), std::string::npos);
  EXPECT_THROW(ParseShard("2/2"), std::invalid_argument);
  EXPECT_THROW(ParseShard("1/"), std::invalid_argument);
  EXPECT_EQ(ParseShard("3/8").index, 3);
}

}  // namespace
}  // namespace fnmpc::app
