// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/signing_key.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

namespace fnmpc::link {
namespace {

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

mavlink::SigningKey ReadSigningKey(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument(path + ": cannot read the signing key file");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  mavlink::SigningKey key{};
  std::string text = bytes;
  text.erase(std::remove_if(text.begin(), text.end(),
                            [](unsigned char c) { return std::isspace(c) != 0; }),
             text.end());
  const bool hex = text.size() == 64 &&
                   std::all_of(text.begin(), text.end(), [](char c) { return HexDigit(c) >= 0; });
  if (hex) {
    for (std::size_t i = 0; i < key.size(); ++i) {
      key[i] = static_cast<std::uint8_t>(HexDigit(text[2 * i]) * 16 + HexDigit(text[2 * i + 1]));
    }
  } else if (bytes.size() == 32 || bytes.size() == 40) {
    std::copy_n(bytes.begin(), key.size(), key.begin());
  } else {
    throw std::invalid_argument(
        path +
        ": not a signing key: expected 64 hexadecimal digits, or a binary file of 32 "
        "bytes (40: PX4's key file, key then timestamp), got " +
        std::to_string(bytes.size()) + " bytes");
  }
  if (std::all_of(key.begin(), key.end(), [](std::uint8_t b) { return b == 0; })) {
    throw std::invalid_argument(path + ": the signing key is all zero (PX4: signing disabled)");
  }
  return key;
}

}  // namespace fnmpc::link
