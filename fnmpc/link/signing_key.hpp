// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

#include "fnmpc/mavlink/signing.hpp"

namespace fnmpc::link {

/// Reads a MAVLink 2 signing key (the 32-byte shared secret) from `path`: either 64
/// hexadecimal digits (whitespace around them allowed; what `openssl rand -hex 32` writes),
/// or a binary file of exactly 32 bytes, or PX4's key file of 40 bytes (the key, then an
/// 8-byte timestamp; `mavlink-signing-key.bin` on its SD card). Throws std::invalid_argument
/// naming the file and what is wrong (missing, unreadable, wrong length, not hexadecimal, all
/// zero).
mavlink::SigningKey ReadSigningKey(const std::string& path);

}  // namespace fnmpc::link
