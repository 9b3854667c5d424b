// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstddef>
#include <string>

namespace fnmpc::config {

/// Largest input file the readers accept [bytes]: far above any configuration or log of the
/// formats (docs/data-formats.md), low enough that a wrong path cannot exhaust memory.
inline constexpr std::size_t kMaxInputFileBytes = std::size_t{64} << 20;

/// Reads the whole of `path`. Only regular files are read (a directory, FIFO, socket or
/// device such as /dev/zero or /dev/urandom is refused before any byte is read, so nothing
/// blocks); files larger than `max_bytes` are refused. Throws ConfigError "path: what" with
/// the errno text on open or read failures.
std::string ReadTextFile(const std::string& path, std::size_t max_bytes = kMaxInputFileBytes);

/// Position of the first byte of `text` that is not valid UTF-8 (overlong forms, surrogates
/// and code points above U+10FFFF are invalid), or std::string::npos.
std::size_t FindInvalidUtf8(const std::string& text);

/// True when `name` is an identifier usable as a file name: 1 to 64 characters, each an
/// ASCII letter, digit, '-' or '_'.
bool IsIdentifier(const std::string& name);

}  // namespace fnmpc::config
