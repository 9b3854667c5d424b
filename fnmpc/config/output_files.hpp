// SPDX-License-Identifier: BSD-3-Clause
// Checked output files of the fnmpc commands: paths confined to the output folder, every
// write checked, results renamed into place only when complete.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace fnmpc::config {

/// `dir`/`name` after checking that `name` is a plain file name (no '/', not "." or "..",
/// not empty) so that the result lies inside `dir`; throws std::runtime_error otherwise.
std::string PathInside(const std::string& dir, const std::string& name);

/// Writes `content` to `path` through a temporary file in the same folder that is flushed,
/// synced and renamed over `path`: a reader sees the old file or the whole new one, never a
/// part. Throws std::runtime_error naming the file and the errno text on any failure.
void WriteFileAtomically(const std::string& path, const std::string& content);

/// A text file written row by row to `path`.part and renamed to `path` by Finish(); every
/// write is checked and a failure throws std::runtime_error naming the file and the errno
/// text. Without Finish() the destructor removes the .part file.
class CheckedFile {
 public:
  explicit CheckedFile(std::string path);
  ~CheckedFile();
  CheckedFile(const CheckedFile&) = delete;
  CheckedFile& operator=(const CheckedFile&) = delete;

  /// Appends `text`.
  void Write(std::string_view text);
  /// Flushes, syncs, closes and renames the file into place.
  void Finish();
  [[nodiscard]] std::FILE* handle() const { return file_; }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  [[noreturn]] void Fail(const std::string& what, int err) const;
  std::string path_, part_;
  std::FILE* file_ = nullptr;
};

/// Throws std::runtime_error "path: what: <errno text>".
[[noreturn]] void ThrowFileError(const std::string& path, const std::string& what, int err);

}  // namespace fnmpc::config
