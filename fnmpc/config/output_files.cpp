// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/output_files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace fnmpc::config {

void ThrowFileError(const std::string& path, const std::string& what, int err) {
  throw std::runtime_error(path + ": " + what + ": " + std::strerror(err));
}

std::string PathInside(const std::string& dir, const std::string& name) {
  if (name.empty() || name == "." || name == ".." || name.find('/') != std::string::npos ||
      name.find('\0') != std::string::npos) {
    throw std::runtime_error("output file name '" + name + "' would leave the folder " + dir);
  }
  return dir + "/" + name;
}

namespace {
/// fsync of an open stdio file; errno is set on failure.
bool Sync(std::FILE* f) { return std::fflush(f) == 0 && ::fsync(::fileno(f)) == 0; }
}  // namespace

void WriteFileAtomically(const std::string& path, const std::string& content) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) ThrowFileError(tmp, "cannot create file", errno);
  const bool written = std::fwrite(content.data(), 1, content.size(), f) == content.size();
  int err = errno;
  const bool synced = written && Sync(f);
  if (written && !synced) err = errno;
  const bool closed = std::fclose(f) == 0;
  if (written && synced && !closed) err = errno;
  if (!(written && synced && closed)) {
    std::remove(tmp.c_str());
    ThrowFileError(tmp, "write failed", err);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    err = errno;
    std::remove(tmp.c_str());
    ThrowFileError(path, "cannot rename " + tmp + " into place", err);
  }
}

CheckedFile::CheckedFile(std::string path) : path_(std::move(path)), part_(path_ + ".part") {
  file_ = std::fopen(part_.c_str(), "wb");
  if (file_ == nullptr) ThrowFileError(part_, "cannot create file", errno);
}

CheckedFile::~CheckedFile() {
  if (file_ != nullptr) {
    std::fclose(file_);
    std::remove(part_.c_str());
  }
}

void CheckedFile::Fail(const std::string& what, int err) const { ThrowFileError(part_, what, err); }

void CheckedFile::Write(std::string_view text) {
  if (std::fwrite(text.data(), 1, text.size(), file_) != text.size()) Fail("write failed", errno);
}

void CheckedFile::Finish() {
  if (file_ == nullptr) return;
  std::FILE* f = file_;
  file_ = nullptr;
  if (!Sync(f)) {
    const int err = errno;
    std::fclose(f);
    std::remove(part_.c_str());
    Fail("write failed", err);
  }
  if (std::fclose(f) != 0) {
    const int err = errno;
    std::remove(part_.c_str());
    Fail("write failed", err);
  }
  if (std::rename(part_.c_str(), path_.c_str()) != 0) {
    ThrowFileError(path_, "cannot rename " + part_ + " into place", errno);
  }
}

}  // namespace fnmpc::config
