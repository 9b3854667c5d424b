// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/signing.hpp"

#include "fnmpc/mavlink/sha256.hpp"
#include "fnmpc/mavlink/wire.hpp"

namespace fnmpc::mavlink {

std::array<std::uint8_t, 6> ComputeSignature(const SigningKey& key,
                                             std::span<const std::uint8_t> frame,
                                             std::uint8_t link_id, std::uint64_t timestamp) {
  std::array<std::uint8_t, 7> link_and_time{};
  link_and_time[0] = link_id;
  wire::PutUint(link_and_time.data() + 1, timestamp, 6);
  Sha256 sha;
  sha.Update(key);
  sha.Update(frame);
  sha.Update(link_and_time);
  const Sha256Digest digest = sha.Final();
  std::array<std::uint8_t, 6> signature{};
  for (std::size_t i = 0; i < signature.size(); ++i) signature[i] = digest[i];
  return signature;
}

}  // namespace fnmpc::mavlink
