// SPDX-License-Identifier: BSD-3-Clause
// What RunFolder (run_folder.cpp) and MergeRunFolders (run_folder_merge.cpp) share: the run
// folders' names, the summaries' reading and writing, the folder summary from its runs.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fnmpc::experiment::run_folder_detail {

/// The key of a shard's identity in its summary.
inline constexpr const char* kShardKey = "shard";

/// run-01, run-02, ... (run r, 0-based).
std::string RunDir(int r);
/// The whole file; throws std::runtime_error "path: cannot read".
std::string ReadText(const std::string& path);
/// A summary file; throws std::runtime_error naming the file when it is not JSON.
nlohmann::json ReadJson(const std::string& path);
/// <dir>/summary.json, written atomically (invalid UTF-8 replaced).
void WriteSummary(const std::string& dir, const nlohmann::json& summary);
/// The folder's summary from its runs, in run order: the same for RunFolder and the merge.
nlohmann::json FolderSummary(const nlohmann::json& identity, std::vector<nlohmann::json> runs,
                             int expected, bool stopped, bool sim_failed);
/// Why `--overwrite` refuses a folder without a manifest, and what to do.
std::string NoManifest(const std::string& dir);

}  // namespace fnmpc::experiment::run_folder_detail
