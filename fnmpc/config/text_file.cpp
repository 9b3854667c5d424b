// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/text_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "fnmpc/config/yaml_reader.hpp"

namespace fnmpc::config {

namespace {
std::string ErrnoText(int err) { return std::strerror(err); }

/// Closes the descriptor on every path out of ReadTextFile.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};
}  // namespace

std::string ReadTextFile(const std::string& path, std::size_t max_bytes) {
  if (path.empty()) throw ConfigError("(empty path): cannot open file: no file name given");
  // O_NONBLOCK: opening a FIFO without a writer must not block; regular files ignore it.
  Fd f;
  f.fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (f.fd < 0) throw ConfigError(path + ": cannot open file: " + ErrnoText(errno));
  struct stat st {};
  if (::fstat(f.fd, &st) != 0) throw ConfigError(path + ": cannot stat file: " + ErrnoText(errno));
  if (S_ISDIR(st.st_mode)) throw ConfigError(path + ": is a directory, expected a file");
  if (!S_ISREG(st.st_mode)) {
    throw ConfigError(path + ": not a regular file (device, FIFO or socket), refused");
  }
  if (static_cast<std::size_t>(st.st_size) > max_bytes) {
    throw ConfigError(path + ": file too large (" + std::to_string(st.st_size) + " bytes, limit " +
                      std::to_string(max_bytes) + ")");
  }
  std::string text;
  text.reserve(static_cast<std::size_t>(st.st_size));
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(f.fd, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw ConfigError(path + ": read failed: " + ErrnoText(errno));
    }
    if (n == 0) break;
    text.append(buf, static_cast<std::size_t>(n));
    if (text.size() > max_bytes) {
      throw ConfigError(path + ": file too large (limit " + std::to_string(max_bytes) + " bytes)");
    }
  }
  return text;
}

std::size_t FindInvalidUtf8(const std::string& text) {
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  std::size_t i = 0;
  while (i < n) {
    const unsigned c = s[i];
    if (c < 0x80) {
      ++i;
      continue;
    }
    int len = 0;
    unsigned cp = 0;
    if ((c & 0xE0) == 0xC0) {
      len = 2;
      cp = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      len = 3;
      cp = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      len = 4;
      cp = c & 0x07;
    } else {
      return i;
    }
    if (i + static_cast<std::size_t>(len) > n) return i;
    for (int k = 1; k < len; ++k) {
      const unsigned cc = s[i + static_cast<std::size_t>(k)];
      if ((cc & 0xC0) != 0x80) return i;
      cp = (cp << 6) | (cc & 0x3F);
    }
    const unsigned min_cp = len == 2 ? 0x80 : (len == 3 ? 0x800 : 0x10000);
    if (cp < min_cp || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return i;
    i += static_cast<std::size_t>(len);
  }
  return std::string::npos;
}

bool IsIdentifier(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  for (const char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_';
    if (!ok) return false;
  }
  return true;
}

}  // namespace fnmpc::config
