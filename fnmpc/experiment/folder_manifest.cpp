// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/folder_manifest.hpp"

#include <fmt/core.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "fnmpc/config/output_files.hpp"
#include "fnmpc/mavlink/sha256.hpp"

namespace fnmpc::experiment {

namespace {
namespace fs = std::filesystem;

const char* const kHeader = "fnmpc-manifest 1";

std::string Hex(const mavlink::Sha256Digest& d) {
  std::string s;
  s.reserve(64);
  for (const std::uint8_t b : d) s += fmt::format("{:02x}", b);
  return s;
}

/// A relative, '/'-separated path without empty, "." or ".." parts: it stays inside the folder.
bool SafeRelativePath(const std::string& path) {
  if (path.empty() || path.front() == '/' || path.find('\0') != std::string::npos) return false;
  std::size_t start = 0;
  while (start <= path.size()) {
    const std::size_t end = std::min(path.find('/', start), path.size());
    const std::string part = path.substr(start, end - start);
    if (part.empty() || part == "." || part == "..") return false;
    start = end + 1;
  }
  return true;
}

std::string ManifestPath(const std::string& dir) { return config::PathInside(dir, kManifestName); }

/// The listed path's folders below `dir` are real folders (no symbolic link leads out).
void CheckNoLinkOnTheWay(const std::string& dir, const std::string& path) {
  fs::path at(dir);
  const fs::path rel(path);
  for (auto it = rel.begin(); it != rel.end(); ++it) {
    if (std::next(it) == rel.end()) break;  // the file itself: removing a link removes the link
    at /= *it;
    std::error_code ec;
    const fs::file_status st = fs::symlink_status(at, ec);
    if (fs::is_symlink(st) || (fs::exists(st) && !fs::is_directory(st))) {
      throw std::runtime_error(fmt::format(
          "{}: '{}' (listed in {}) goes through {}, which is not a plain folder; nothing deleted",
          dir, path, kManifestName, at.string()));
    }
  }
}
}  // namespace

std::string TextSha256(const std::string& bytes) {
  return Hex(mavlink::Sha256::Hash(
      std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size())));
}

std::string FileSha256(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": cannot read");
  mavlink::Sha256 h;
  std::vector<char> buffer(1 << 16);
  while (f) {
    f.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const auto n = static_cast<std::size_t>(f.gcount());
    h.Update(std::span(reinterpret_cast<const std::uint8_t*>(buffer.data()), n));
  }
  if (f.bad()) throw std::runtime_error(path + ": read failed");
  return Hex(h.Final());
}

bool FolderManifest::Exists(const std::string& dir) {
  std::error_code ec;
  return fs::is_regular_file(ManifestPath(dir), ec);
}

FolderManifest FolderManifest::Read(const std::string& dir) {
  const std::string file = ManifestPath(dir);
  std::ifstream f(file, std::ios::binary);
  if (!f) throw std::runtime_error(file + ": cannot read");
  FolderManifest m;
  std::string line;
  int number = 0;
  const auto bad = [&](const std::string& why) {
    return std::runtime_error(fmt::format("{}:{}: {}", file, number, why));
  };
  while (std::getline(f, line)) {
    ++number;
    if (number == 1) {
      if (line != kHeader) throw bad(fmt::format("expected '{}': not an fnmpc manifest", kHeader));
      continue;
    }
    if (line.empty()) continue;
    const std::size_t s1 = line.find(' ');
    const std::size_t s2 = s1 == std::string::npos ? s1 : line.find(' ', s1 + 1);
    if (s2 == std::string::npos) throw bad("expected 'SIZE SHA256 PATH'");
    const std::string size = line.substr(0, s1), digest = line.substr(s1 + 1, s2 - s1 - 1);
    const std::string path = line.substr(s2 + 1);
    if (!SafeRelativePath(path)) throw bad("path '" + path + "' would leave the folder");
    if (size == "gone" && digest == "-") {
      m.entries_.erase(path);
      continue;
    }
    ManifestEntry e;
    if (size != "-" || digest != "-") {
      try {
        std::size_t used = 0;
        e.size = std::stoll(size, &used);
        if (used != size.size() || e.size < 0) throw std::invalid_argument(size);
      } catch (const std::exception&) {
        throw bad("size '" + size + "' is not a byte count");
      }
      if (digest.size() != 64 ||
          digest.find_first_not_of("0123456789abcdef") != std::string::npos) {
        throw bad("'" + digest + "' is not a SHA-256 digest");
      }
      e.sha256 = digest;
    }
    m.entries_[path] = e;
  }
  if (number == 0) throw std::runtime_error(file + ": empty: not an fnmpc manifest");
  return m;
}

void FolderManifest::Plan(const std::string& path) {
  if (!SafeRelativePath(path)) throw std::runtime_error("manifest path '" + path + "'");
  entries_[path] = ManifestEntry{};
}

void FolderManifest::Record(const std::string& dir, const std::string& path) {
  if (!SafeRelativePath(path)) throw std::runtime_error("manifest path '" + path + "'");
  const std::string full = dir + "/" + path;
  std::error_code ec;
  const auto size = fs::file_size(full, ec);
  if (ec) throw std::runtime_error(full + ": " + ec.message());
  entries_[path] = ManifestEntry{static_cast<std::int64_t>(size), FileSha256(full)};
}

void FolderManifest::Forget(const std::string& path) {
  std::erase_if(entries_, [&](const auto& kv) {
    return kv.first == path || kv.first.starts_with(path + "/");
  });
}

namespace {
std::string Line(const std::string& path, const ManifestEntry& e) {
  return e.finished() ? fmt::format("{} {} {}\n", e.size, e.sha256, path)
                      : fmt::format("- - {}\n", path);
}
}  // namespace

void FolderManifest::Write(const std::string& dir) const {
  std::string text = std::string(kHeader) + "\n";
  for (const auto& [path, e] : entries_) text += Line(path, e);
  config::WriteFileAtomically(ManifestPath(dir), text);
}

void FolderManifest::Append(const std::string& dir, const std::vector<std::string>& paths) const {
  if (paths.empty()) return;
  std::string line;
  for (const std::string& path : paths) {
    const auto it = entries_.find(path);
    line += it == entries_.end() ? "gone - " + path + "\n" : Line(path, it->second);
  }
  const std::string file = ManifestPath(dir);
  std::FILE* f = std::fopen(file.c_str(), "ab");
  if (f == nullptr) config::ThrowFileError(file, "cannot append", errno);
  const bool written = std::fwrite(line.data(), 1, line.size(), f) == line.size() &&
                       std::fflush(f) == 0 && ::fsync(::fileno(f)) == 0;
  const int err = errno;
  if (std::fclose(f) != 0 || !written)
    config::ThrowFileError(file, "write failed", written ? errno : err);
}

int DeleteListedFiles(const std::string& dir, const FolderManifest& manifest,
                      const std::string& prefix) {
  const auto mine = [&](const std::string& path) {
    return prefix.empty() || path == prefix || path.starts_with(prefix + "/");
  };
  // Every check first: a refusal deletes nothing.
  for (const auto& [path, e] : manifest.entries()) {
    if (!mine(path)) continue;
    CheckNoLinkOnTheWay(dir, path);
    std::error_code ec;
    const fs::file_status st = fs::symlink_status(dir + "/" + path, ec);
    if (fs::is_directory(st)) {
      throw std::runtime_error(
          fmt::format("{}: '{}' (listed in {} as a file) is a folder; nothing deleted", dir, path,
                      kManifestName));
    }
  }
  int deleted = 0;
  std::set<std::string, std::greater<>> folders;  // deepest first
  for (const auto& [path, e] : manifest.entries()) {
    if (!mine(path)) continue;
    for (const std::string& victim : {path, path + ".part", path + ".tmp"}) {
      std::error_code ec;
      const fs::file_status st = fs::symlink_status(dir + "/" + victim, ec);
      if (!fs::exists(st) || fs::is_directory(st)) continue;
      if (!fs::remove(dir + "/" + victim, ec) || ec) {
        throw std::runtime_error(fmt::format("{}/{}: cannot delete: {}", dir, victim,
                                             ec ? ec.message() : "not removed"));
      }
      ++deleted;
    }
    for (fs::path p = fs::path(path).parent_path(); !p.empty(); p = p.parent_path()) {
      folders.insert(p.generic_string());
    }
  }
  for (const std::string& folder : folders) {
    std::error_code ec;
    if (fs::is_empty(dir + "/" + folder, ec) && !ec) fs::remove(dir + "/" + folder, ec);
  }
  return deleted;
}

std::vector<std::string> UnlistedFiles(const std::string& dir, const FolderManifest& manifest) {
  std::vector<std::string> extra;
  std::set<std::string> folders;  // the folders that hold listed files
  for (const auto& [path, e] : manifest.entries()) {
    for (fs::path p = fs::path(path).parent_path(); !p.empty(); p = p.parent_path()) {
      folders.insert(p.generic_string());
    }
  }
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    const std::string rel = fs::relative(it->path(), dir, ec).generic_string();
    if (it->is_directory() && !it->is_symlink() && folders.count(rel) == 1) continue;
    if (rel == kManifestName || manifest.entries().count(rel) == 1) continue;
    extra.push_back(rel);
  }
  if (ec) throw std::runtime_error(dir + ": cannot list: " + ec.message());
  return extra;
}

}  // namespace fnmpc::experiment
