// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/sha256.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "tests/mavlink/sample_messages.hpp"

namespace fnmpc::mavlink {
namespace {

using testing::Hex;

std::span<const std::uint8_t> Bytes(std::string_view s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

TEST(Sha256Test, Fips180ExampleVectors) {
  // FIPS 180-4 / NIST CSRC examples: one block, two blocks, 896 bits, empty message.
  EXPECT_EQ(Hex(Sha256::Hash(Bytes("abc"))),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Hex(Sha256::Hash(Bytes("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"))),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(Hex(Sha256::Hash(Bytes("abcdefghbcdefghicdefghijdefghijkefghijklfghijklmghijklmn"
                                   "hijklmnoijklmnopjklmnopqklmnopqrlmnopqrsmnopqrstnopqrstu"))),
            "cf5b16a778af8380036ce59e7b0492370b249b11e8f07a51afac45037afee9d1");
  EXPECT_EQ(Hex(Sha256::Hash({})),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(Sha256Test, OneMillionTimesA) {
  // FIPS 180-2 appendix B.3, fed in pieces of 1000 bytes.
  const std::string thousand(1000, 'a');
  Sha256 sha;
  for (int i = 0; i < 1000; ++i) sha.Update(Bytes(thousand));
  EXPECT_EQ(Hex(sha.Final()), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Sha256Test, PaddingBoundaries) {
  // Messages whose padding ends a block exactly, spills into a second one, or fills one:
  // 'a' * n, digests from an independent implementation (Python's hashlib).
  const std::vector<std::pair<std::size_t, std::string_view>> cases = {
      {55, "9f4390f8d30c2dd92ec9f095b65e2b9ae9b0a925a5258e241c9f1e910f734318"},
      {56, "b35439a4ac6f0948b6d6f9e3c6af0f5f590ce20f1bde7090ef7970686ec6738a"},
      {63, "7d3e74a05d7db15bce4ad9ec0658ea98e3f06eeecf16b4c6fff2da457ddc2f34"},
      {64, "ffe054fe7ae0cb6dc65c3af9b61d5209f439851db43d0ba5997337df154668eb"},
      {65, "635361c48bb9eab14198e76ea8ab7f1a41685d6ad62aa9146d301d4f17eb0ae0"},
      {119, "31eba51c313a5c08226adf18d4a359cfdfd8d2e816b13f4af952f7ea6584dcfb"},
      {120, "2f3d335432c70b580af0e8e1b3674a7c020d683aa5f73aaaedfdc55af904c21c"}};
  for (const auto& [n, digest] : cases) {
    EXPECT_EQ(Hex(Sha256::Hash(Bytes(std::string(n, 'a')))), digest) << n;
  }
}

TEST(Sha256Test, AnySplitOfTheInputGivesTheSameDigestAndFinalResets) {
  // Given a 300-byte message and its one-shot digest
  std::mt19937 rng(7);
  std::vector<std::uint8_t> message(300);
  for (auto& b : message) b = static_cast<std::uint8_t>(rng());
  const Sha256Digest expected = Sha256::Hash(message);
  Sha256 sha;
  for (int trial = 0; trial < 50; ++trial) {
    // When it is fed in random pieces
    std::size_t at = 0;
    while (at < message.size()) {
      const std::size_t n = std::min<std::size_t>(rng() % 80, message.size() - at);
      sha.Update(std::span(message).subspan(at, n));
      at += n;
    }
    // Then the digest is the same, and Final leaves an empty message behind
    EXPECT_EQ(sha.Final(), expected);
  }
  EXPECT_EQ(Hex(sha.Final()), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

}  // namespace
}  // namespace fnmpc::mavlink
