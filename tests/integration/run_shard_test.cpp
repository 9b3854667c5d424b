// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc run --shard I/N` and `fnmpc merge`: the shards of an experiment merge into the very
// folder the unsharded run writes (byte for byte, with the timings off); a resumed shard
// flies only what an interrupted attempt left; the merge refuses shards that are not one
// experiment, missing shards and unfinished runs, naming the run and its seed.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/folder_manifest.hpp"
#include "fnmpc/experiment/run_folder.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {
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

std::string MessageOf(const std::vector<std::string>& shards, const std::string& out,
                      bool overwrite = false) {
  try {
    MergeRunFolders(shards, out, overwrite);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

void WriteText(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

/// The entries of `dir` itself (names), to see that nothing was left beside a folder.
std::vector<std::string> Names(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

class RunShardTest : public ::testing::Test {
 protected:
  void SetUp() override {
    file_ = std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/triangle.yaml";
    sc_ = Shortened(config::LoadScenarioFile(file_), 26.0);
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
    // as fnmpc would have written it (else the merge refuses the changed file first)
    FolderManifest m = FolderManifest::Read(base_ + to);
    m.Record(base_ + to, "summary.json");
    m.Write(base_ + to);
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

TEST_F(RunShardTest, TheManifestListsEveryFileARunWritesAndNothingElse) {
  // Given a run folder of 2 runs (reality on: plant files too),
  RunFolderOptions o = options_;
  o.runs = 2;
  RunFolder(sc_, o, base_ + "/whole");
  ASSERT_TRUE(sc_.reality.enabled);
  ASSERT_TRUE(fs::exists(base_ + "/whole/run-02/plant-leader.yaml"));
  // then its manifest lists every file in it, finished, with its size and digest.
  const FolderManifest m = FolderManifest::Read(base_ + "/whole");
  EXPECT_EQ(UnlistedFiles(base_ + "/whole", m), std::vector<std::string>{});
  EXPECT_EQ(m.entries().size(), Files(base_ + "/whole").size() - 1);  // the manifest itself
  for (const auto& [path, e] : m.entries()) {
    ASSERT_TRUE(e.finished()) << path;
    EXPECT_EQ(e.size, static_cast<std::int64_t>(fs::file_size(base_ + "/whole/" + path)));
    EXPECT_EQ(e.sha256, FileSha256(base_ + "/whole/" + path)) << path;
  }
  EXPECT_EQ(TextSha256("abc"),  // FIPS 180-4's example
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST_F(RunShardTest, OverwriteDeletesOnlyWhatFnmpcWrote) {
  // Given a user's project folder that happens to hold a scenario.yaml and a summary.json,
  const std::string project = base_ + "/project";
  WriteText(project + "/scenario.yaml", "mine\n");
  WriteText(project + "/summary.json", "{}\n");
  WriteText(project + "/src/main.cpp", "int main() {}\n");
  WriteText(project + "/notes.md", "notes\n");
  const auto before = Files(project);
  // then --overwrite refuses it, saying why, and deletes nothing.
  try {
    PrepareRunFolder(project, /*overwrite=*/true);
    ADD_FAILURE() << "--overwrite emptied a folder fnmpc did not write";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(".fnmpc-manifest"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("delete it yourself"), std::string::npos) << e.what();
  }
  EXPECT_EQ(Files(project), before);
  // Given a run folder of fnmpc into which the user put a file of their own (and one into a
  // run folder),
  const std::string run = base_ + "/run";
  PrepareRunFolder(run, false);
  RunFolder(sc_, options_, run);
  WriteText(run + "/my-notes.txt", "keep me\n");
  WriteText(run + "/run-02/my-plot.py", "keep me too\n");
  // then --overwrite deletes fnmpc's files only: the user's stay (and the folders holding
  // them), fnmpc's run folders without them are gone, the manifest lists nothing.
  PrepareRunFolder(run, true);
  const auto left = Files(run);
  EXPECT_EQ(left.size(), 3u);
  EXPECT_EQ(left.count("my-notes.txt"), 1u);
  EXPECT_EQ(left.count("run-02/my-plot.py"), 1u);
  EXPECT_EQ(left.count(".fnmpc-manifest"), 1u);
  EXPECT_FALSE(fs::exists(run + "/run-01"));
  EXPECT_TRUE(FolderManifest::Read(run).entries().empty());
  // A run killed mid-way (its manifest as appended, not yet sorted): the files it began go
  // with their temporaries, a line `gone` took back keeps its file.
  WriteText(run + "/run-01/leader.csv.part", "t,phase\n");
  WriteText(run + "/run-01/follower1.csv", "t,phase\n");
  WriteText(run + "/.fnmpc-manifest",
            "fnmpc-manifest 1\n- - run-01/leader.csv\n- - run-01/follower1.csv\n"
            "gone - run-01/follower1.csv\n");
  PrepareRunFolder(run, true);
  EXPECT_FALSE(fs::exists(run + "/run-01/leader.csv.part"));
  EXPECT_TRUE(fs::exists(run + "/run-01/follower1.csv"));
  // A manifest naming a path outside the folder, or through a symbolic link, is refused
  // before anything is deleted.
  WriteText(run + "/.fnmpc-manifest", "fnmpc-manifest 1\n- - ../project/notes.md\n");
  EXPECT_THROW(PrepareRunFolder(run, true), std::runtime_error);
  fs::create_directory_symlink(project, run + "/link");
  WriteText(run + "/.fnmpc-manifest", "fnmpc-manifest 1\n- - my-notes.txt\n- - link/notes.md\n");
  EXPECT_THROW(PrepareRunFolder(run, true), std::runtime_error);
  EXPECT_TRUE(fs::exists(run + "/my-notes.txt"));  // listed, but the refusal came first
  EXPECT_EQ(Files(project), before);
}

TEST_F(RunShardTest, ARefusedOrFailedMergeLeavesTheOutputAsItWas) {
  // Given the two shards of an experiment and their merge,
  Fly("s0", ParseShard("0/2"));
  Fly("s1", ParseShard("1/2"));
  const std::string merged = base_ + "/merged";
  MergeRunFolders({base_ + "/s0", base_ + "/s1"}, merged);
  const auto before = Files(merged);
  const auto s1 = Files(base_ + "/s1");
  const auto names = Names(base_);
  const auto refused = [&](const std::vector<std::string>& shards, const std::string& out,
                           const std::string& why) {
    const std::string message = MessageOf(shards, out, /*overwrite=*/true);
    EXPECT_NE(message.find(why), std::string::npos) << "'" << message << "' lacks '" << why << "'";
    EXPECT_EQ(message.find("filesystem error"), std::string::npos) << message;
  };
  // a merge into one of its shards (or inside one) is refused, the shard untouched;
  refused({base_ + "/s0", base_ + "/s1"}, base_ + "/s1", "its own input");
  refused({base_ + "/s0", base_ + "/s1"}, base_ + "/s1/sub", "its own input");
  refused({base_ + "/merged/s0", base_ + "/s1"}, merged, "lies inside -o");
  EXPECT_EQ(Files(base_ + "/s1"), s1);
  // a shard with a truncated CSV, with a changed one, or without a run folder is refused
  // before the earlier merge is touched: it stays byte for byte, nothing is left beside it.
  fs::copy(base_ + "/s1", base_ + "/s1-cut", fs::copy_options::recursive);
  fs::resize_file(base_ + "/s1-cut/run-02/follower1.csv",
                  fs::file_size(base_ + "/s1-cut/run-02/follower1.csv") / 2);
  refused({base_ + "/s0", base_ + "/s1-cut"}, merged, "truncated or changed");
  fs::copy(base_ + "/s1", base_ + "/s1-edited", fs::copy_options::recursive);
  {
    std::string csv = Files(base_ + "/s1").at("run-02/leader.csv");
    csv[csv.size() - 2] = csv[csv.size() - 2] == '1' ? '2' : '1';  // same size, one digit
    WriteText(base_ + "/s1-edited/run-02/leader.csv", csv);
  }
  refused({base_ + "/s0", base_ + "/s1-edited"}, merged, "SHA-256 differs");
  fs::copy(base_ + "/s0", base_ + "/s0-gone", fs::copy_options::recursive);
  fs::remove_all(base_ + "/s0-gone/run-03");
  refused({base_ + "/s0-gone", base_ + "/s1"}, merged, "run-03/");
  fs::copy(base_ + "/s0", base_ + "/s0-old", fs::copy_options::recursive);
  fs::remove(base_ + "/s0-old/.fnmpc-manifest");  // a shard of an earlier fnmpc
  refused({base_ + "/s0-old", base_ + "/s1"}, merged, "no .fnmpc-manifest");
  EXPECT_EQ(Files(merged), before);
  // into a new folder: none is made.
  refused({base_ + "/s0-gone", base_ + "/s1"}, base_ + "/new", "run-03/");
  EXPECT_FALSE(fs::exists(base_ + "/new"));
  // A folder holding a file fnmpc did not write is not replaced.
  WriteText(merged + "/mine.txt", "x\n");
  refused({base_ + "/s0", base_ + "/s1"}, merged, "did not write");
  fs::remove(merged + "/mine.txt");
  // Without --overwrite a non-empty -o is refused.
  EXPECT_NE(MessageOf({base_ + "/s0", base_ + "/s1"}, merged).find("--overwrite"),
            std::string::npos);
  EXPECT_EQ(Files(merged), before);
  // A merge that succeeds replaces the earlier one whole, leaving nothing beside it.
  for (const char* copy : {"s1-cut", "s1-edited", "s0-gone", "s0-old"}) {
    fs::remove_all(base_ + "/" + copy);
  }
  EXPECT_EQ(Names(base_), names);
  fs::remove(merged + "/run-01/leader.csv");  // damage the earlier merge: it is replaced
  MergeRunFolders({base_ + "/s1", base_ + "/s0"}, merged, /*overwrite=*/true);
  EXPECT_EQ(Files(merged), before);
  EXPECT_EQ(Names(base_), names);
}

TEST_F(RunShardTest, ResumeRefusesAnotherExperimentsFolder) {
  // Given a shard folder of a 26 s experiment,
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
  shorter.duration = 25.0;
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
}  // namespace fnmpc::experiment
