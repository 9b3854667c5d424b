// SPDX-License-Identifier: BSD-3-Clause
// Signing key files: hexadecimal, 32-byte binary and PX4's 40-byte key file; bad files named.
#include "fnmpc/link/signing_key.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

namespace fnmpc::link {
namespace {

class KeyFile {
 public:
  explicit KeyFile(const std::string& bytes)
      : path_(::testing::TempDir() + "signing-key-" + std::to_string(::getpid()) + "-" +
              std::to_string(counter_++)) {
    std::ofstream(path_, std::ios::binary) << bytes;
  }
  ~KeyFile() { std::remove(path_.c_str()); }
  KeyFile(const KeyFile&) = delete;
  KeyFile& operator=(const KeyFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  static inline int counter_ = 0;
  std::string path_;
};

std::string ErrorOf(const std::string& path) {
  try {
    ReadSigningKey(path);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(SigningKeyTest, HexBinaryAndPx4KeyFilesGiveTheSameKey) {
  std::string binary(32, '\0');
  std::string hex;
  for (int i = 0; i < 32; ++i) {
    binary[i] = static_cast<char>(7 * i + 1);
    char b[3];
    std::snprintf(b, sizeof b, "%02X", (7 * i + 1) & 0xFF);
    hex += b;
  }
  const KeyFile h("  " + hex + "\n"), b(binary), px4(binary + std::string(8, '\x05'));
  const mavlink::SigningKey key = ReadSigningKey(h.path());
  for (int i = 0; i < 32; ++i) EXPECT_EQ(key[i], static_cast<std::uint8_t>(7 * i + 1)) << i;
  EXPECT_EQ(ReadSigningKey(b.path()), key);
  EXPECT_EQ(ReadSigningKey(px4.path()), key);
}

TEST(SigningKeyTest, BadFilesAreNamedWithWhatIsWrong) {
  EXPECT_NE(ErrorOf("/nonexistent/key").find("/nonexistent/key: cannot read"), std::string::npos);
  const KeyFile short_hex(std::string(62, 'a')), not_hex(std::string(63, 'a') + "g"),
      zero(std::string(64, '0'));
  EXPECT_NE(ErrorOf(short_hex.path()).find("62 bytes"), std::string::npos)
      << ErrorOf(short_hex.path());
  EXPECT_NE(ErrorOf(not_hex.path()).find("not a signing key"), std::string::npos);
  EXPECT_NE(ErrorOf(zero.path()).find("all zero"), std::string::npos);
  EXPECT_NE(ErrorOf(zero.path()).find(zero.path()), std::string::npos);
}

}  // namespace
}  // namespace fnmpc::link
