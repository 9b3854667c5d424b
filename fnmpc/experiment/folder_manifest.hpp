// SPDX-License-Identifier: BSD-3-Clause
// The manifest of a folder fnmpc writes (run, shard and merge folders): which files fnmpc
// wrote there, with their sizes and SHA-256 digests. `--overwrite` deletes only what it
// lists; `merge` checks every file of its shards against it (docs/cli.md, "Output folders").
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace fnmpc::experiment {

/// The manifest's file name inside the folder it describes.
inline constexpr const char* kManifestName = ".fnmpc-manifest";

/// One file fnmpc wrote (or is writing) in the folder.
struct ManifestEntry {
  std::int64_t size = -1;  ///< bytes; -1: planned, not yet finished (a run in progress)
  std::string sha256;      ///< 64 lowercase hex digits; empty while planned
  [[nodiscard]] bool finished() const { return size >= 0; }
};

/// The manifest as a text file:
///   fnmpc-manifest 1
///   SIZE SHA256 PATH      (one line per finished file)
///   - - PATH              (a file fnmpc was writing when it stopped: a run killed mid-way)
/// PATH is relative to the folder, '/'-separated, without "." or ".." parts. While a run
/// folder is written, lines are appended (a later line for a PATH replaces an earlier one;
/// `gone - PATH` drops it), so that a run killed at any moment leaves every file it began
/// listed; Write() then leaves one line per PATH, sorted, so the finished manifest depends on
/// the files alone (a merged folder's equals the unsharded run's byte for byte).
class FolderManifest {
 public:
  /// True when `dir` holds a manifest file.
  static bool Exists(const std::string& dir);
  /// Reads <dir>/.fnmpc-manifest; std::runtime_error naming FILE:LINE on a damaged line or
  /// an unsafe path (absolute, "..", empty part).
  static FolderManifest Read(const std::string& dir);

  /// Marks `path` as being written (finished files stay listed, as planned, until Record).
  void Plan(const std::string& path);
  /// Records <dir>/`path` as written: its size and digest, read back from the disk.
  void Record(const std::string& dir, const std::string& path);
  /// Drops the entries of `path` and of every path below it ("run-03" drops run-03/...).
  void Forget(const std::string& path);
  /// Writes <dir>/.fnmpc-manifest atomically, one sorted line per file.
  void Write(const std::string& dir) const;
  /// Appends the current lines of `paths` (`gone - PATH` for one not listed) to
  /// <dir>/.fnmpc-manifest in one write, synced before returning.
  void Append(const std::string& dir, const std::vector<std::string>& paths) const;

  [[nodiscard]] const std::map<std::string, ManifestEntry>& entries() const { return entries_; }

 private:
  std::map<std::string, ManifestEntry> entries_;
};

/// SHA-256 of a file's bytes (64 lowercase hex digits); std::runtime_error naming the file.
std::string FileSha256(const std::string& path);
/// SHA-256 of bytes in memory, as FileSha256.
std::string TextSha256(const std::string& bytes);

/// Deletes from `dir` the files of `manifest` under `prefix` (all when empty) with their
/// temporaries (PATH.part, PATH.tmp), then the folders that held them when they are left
/// empty; nothing else. A listed path that goes through a symbolic link or is a folder is
/// refused (std::runtime_error naming it) before anything is deleted. Returns the number of
/// files deleted.
int DeleteListedFiles(const std::string& dir, const FolderManifest& manifest,
                      const std::string& prefix = "");

/// The files below `dir` (relative paths, '/'-separated) that neither `manifest` lists nor
/// are the manifest itself, and the folders that hold no listed file: what a user added to a
/// folder fnmpc wrote.
std::vector<std::string> UnlistedFiles(const std::string& dir, const FolderManifest& manifest);

}  // namespace fnmpc::experiment
