// SPDX-License-Identifier: BSD-3-Clause
// Output paths stay inside their folder; a failed write (full disk, here a file size limit) is
// an error naming the file and the errno text, and nothing half-written is left under the final
// name (docs/failure.md "What is written").
#include "fnmpc/config/output_files.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <string>

namespace fnmpc::config {
namespace {

std::string Dir(const std::string& tag) {
  const std::string dir = testing::TempDir() + "/fnmpc-out-" + tag + "-" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(OutputFilesTest, NamesThatLeaveTheFolderAreRefused) {
  EXPECT_EQ(PathInside("run", "leader.csv"), "run/leader.csv");
  for (const std::string bad : {"../../pwned.csv", "a/b.csv", "..", ".", ""}) {
    EXPECT_NE(ErrorOf([&] { PathInside("run", bad); }).find("would leave the folder"),
              std::string::npos)
        << bad;
  }
}

TEST(OutputFilesTest, AtomicWriteReplacesTheFileWhole) {
  const std::string dir = Dir("atomic");
  const std::string path = dir + "/summary.json";
  WriteFileAtomically(path, "{\"a\": 1}\n");
  WriteFileAtomically(path, "{\"a\": 2}\n");
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  EXPECT_EQ(s.str(), "{\"a\": 2}\n");
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  const std::string e = ErrorOf([&] { WriteFileAtomically(dir + "/no/such/dir/x.json", "x"); });
  EXPECT_NE(e.find(dir + "/no/such/dir/x.json.tmp: cannot create file: No such file or directory"),
            std::string::npos)
      << e;
  std::filesystem::remove_all(dir);
}

TEST(OutputFilesTest, FullDiskIsAnErrorNamingTheFileAndReason) {
  // Given a file size limit of 64 KiB (what a full disk looks like to the writer: EFBIG
  // instead of ENOSPC; SIGXFSZ ignored so the write returns the error),
  const std::string dir = Dir("full");
  struct rlimit old {};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old), 0);
  auto* old_handler = std::signal(SIGXFSZ, SIG_IGN);
  struct rlimit small = old;
  small.rlim_cur = 64 * 1024;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string csv_error, json_error;
  {
    // When a CSV log and a summary larger than that are written,
    CheckedFile f(dir + "/leader.csv");
    const std::string row(1000, 'x');
    csv_error = ErrorOf([&] {
      for (int i = 0; i < 200; ++i) f.Write(row + "\n");
      f.Finish();
    });
  }
  json_error =
      ErrorOf([&] { WriteFileAtomically(dir + "/summary.json", std::string(200000, 'y')); });
  setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);
  // Then both fail naming the file and the errno text, and no final file exists.
  EXPECT_NE(csv_error.find(dir + "/leader.csv.part: write failed: File too large"),
            std::string::npos)
      << csv_error;
  EXPECT_NE(json_error.find(dir + "/summary.json.tmp: write failed: File too large"),
            std::string::npos)
      << json_error;
  EXPECT_FALSE(std::filesystem::exists(dir + "/leader.csv"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/leader.csv.part"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/summary.json"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fnmpc::config
