// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/parser.hpp"

#include <algorithm>
#include <cstring>

#include "fnmpc/core/assert.hpp"
#include "fnmpc/mavlink/crc.hpp"
#include "fnmpc/mavlink/wire.hpp"

namespace fnmpc::mavlink {

void Parser::SetSigningKey(const SigningKey& key) {
  key_ = key;
  signing_ = true;
}

void Parser::ClearSigningKey() {
  key_.fill(0);
  signing_ = false;
  streams_ = {};
  newest_timestamp_ = 0;
}

void Parser::SetTimestamp(std::uint64_t timestamp) {
  newest_timestamp_ = std::max(newest_timestamp_, timestamp);
}

void Parser::NoteUnknown(std::size_t frame_length) {
  const std::uint64_t at = Offset();
  const std::uint8_t sequence = buf_[4], system = buf_[5], component = buf_[6];
  if (run_active_ && at == run_end_ && Follows(system, component, sequence)) {
    run_end_ = at + frame_length;  // the next frame of the run
    run_sequence_ = sequence;
    ++run_frames_;
    return;
  }
  if (run_active_ && at < run_end_) return;  // a false start inside the run's last frame
  run_active_ = true;
  run_start_ = at;
  run_end_ = at + frame_length;
  run_frames_ = 1;
  run_system_ = system;
  run_component_ = component;
  run_sequence_ = sequence;
  run_before_ = counters_;
}

bool Parser::Follows(std::uint8_t system, std::uint8_t component, std::uint8_t sequence) const {
  return system == run_system_ && component == run_component_ &&
         sequence == static_cast<std::uint8_t>(run_sequence_ + 1);
}

void Parser::ConfirmUnknownRun(bool datagram_end) {
  if (!run_active_) return;
  run_active_ = false;
  if (Offset() != run_end_) return;  // a valid frame elsewhere: the run was garbage
  // The next frame of the same sender (its sequence number), or the end of its datagram.
  if (!datagram_end && !Follows(buf_[5], buf_[6], buf_[4])) return;
  // Every byte of the run was discarded (a valid frame inside would have ended it) and every
  // failure since its start was a false start inside it.
  const std::uint64_t bytes = run_end_ - run_start_;
  ParserCounters& c = counters_;
  c.bytes_discarded -= bytes;
  c.bytes_in_unknown_frames += bytes;
  c.unknown_frames += run_frames_;
  c.crc_errors = run_before_.crc_errors;
  c.unknown_ids = run_before_.unknown_ids + run_frames_;
  c.bad_lengths = run_before_.bad_lengths;
  c.bad_incompat_flags = run_before_.bad_incompat_flags;
  c.signature_failures = run_before_.signature_failures;
  c.unsigned_rejected = run_before_.unsigned_rejected;
  c.bad_signatures = run_before_.bad_signatures;
  c.timestamps_rejected = run_before_.timestamps_rejected;
}

void Parser::EndOfDatagram() {
  if (!run_active_ || counters_.bytes_received != run_end_) return;
  if (emitted_) return;  // a frame was handed out after the run began: not a run's end
  if (end_ > 0) {
    Discard(end_);
    pos_ = 0;
  }
  ConfirmUnknownRun(true);
}

void Parser::Reset() {
  run_active_ = false;
  if (emitted_) {
    // The handed-out frame's bytes are counted already.
    std::memmove(buf_.data(), buf_.data() + expected_, end_ - expected_);
    end_ -= expected_;
    emitted_ = false;
  }
  Discard(end_);
  pos_ = 0;
}

void Parser::Append(std::uint8_t byte) {
  // Between calls every buffered byte is processed and belongs to an incomplete candidate,
  // which is shorter than a frame: there is room.
  FNMPC_ASSERT(!emitted_ && pos_ == end_ && end_ < buf_.size());
  buf_[end_++] = byte;
  ++counters_.bytes_received;
}

void Parser::Discard(std::size_t n) {
  std::memmove(buf_.data(), buf_.data() + n, end_ - n);
  end_ -= n;
  counters_.bytes_discarded += n;
}

void Parser::Fail(std::uint64_t* counter) {
  ++*counter;
  const auto* next = std::find(buf_.data() + 1, buf_.data() + end_, kStartByte);
  Discard(static_cast<std::size_t>(next - buf_.data()));
  pos_ = 0;
}

bool Parser::Next() {
  if (emitted_) {
    std::memmove(buf_.data(), buf_.data() + expected_, end_ - expected_);
    end_ -= expected_;
    pos_ = 0;
    emitted_ = false;
  }
  while (pos_ < end_) {
    if (pos_ == 0 && buf_[0] != kStartByte) {
      const auto* start = std::find(buf_.data(), buf_.data() + end_, kStartByte);
      Discard(static_cast<std::size_t>(start - buf_.data()));
      continue;
    }
    ++pos_;
    if (pos_ == kHeaderLength) {
      if (!HeaderOk()) continue;  // HeaderOk failed the candidate
    } else if (pos_ > kHeaderLength && pos_ == expected_) {
      if (CompleteOk()) return true;
    }
  }
  return false;
}

bool Parser::HeaderOk() {
  const std::uint8_t length = buf_[1];
  const std::uint8_t incompat = buf_[2];
  if ((incompat & ~kSupportedIncompatFlags) != 0) {
    Fail(&counters_.bad_incompat_flags);
    return false;
  }
  const auto id = static_cast<std::uint32_t>(wire::GetUint(buf_.data() + 7, 3));
  info_ = FindMessageInfo(id);
  if (info_ == nullptr) {
    NoteUnknown(kHeaderLength + length + kChecksumLength +
                ((incompat & kIncompatFlagSigned) != 0 ? kSignatureLength : 0));
    Fail(&counters_.unknown_ids);
    return false;
  }
  if (length > info_->max_length) {
    Fail(&counters_.bad_lengths);
    return false;
  }
  expected_ = kHeaderLength + length + kChecksumLength +
              ((incompat & kIncompatFlagSigned) != 0 ? kSignatureLength : 0);
  return true;
}

std::uint64_t* Parser::SignatureFailure(std::size_t crc_end) {
  if ((buf_[2] & kIncompatFlagSigned) == 0) return &counters_.unsigned_rejected;
  const std::uint8_t link_id = buf_[crc_end];
  const std::uint64_t timestamp = wire::GetUint(buf_.data() + crc_end + 1, 6);
  const auto signature = ComputeSignature(key_, std::span<const std::uint8_t>(buf_.data(), crc_end),
                                          link_id, timestamp);
  if (!std::equal(signature.begin(), signature.end(), buf_.data() + crc_end + 7)) {
    return &counters_.bad_signatures;
  }
  const std::uint8_t system_id = buf_[5];
  const std::uint8_t component_id = buf_[6];
  SigningStream* stream = nullptr;
  for (SigningStream& s : streams_) {
    if (s.used && s.link_id == link_id && s.system_id == system_id &&
        s.component_id == component_id) {
      stream = &s;
      break;
    }
  }
  if (stream != nullptr) {
    if (timestamp <= stream->timestamp) return &counters_.timestamps_rejected;
  } else {
    if (timestamp + kNewStreamTimestampWindow < newest_timestamp_) {
      return &counters_.timestamps_rejected;
    }
    // A free slot, else the stream with the oldest timestamp.
    stream = &streams_[0];
    for (SigningStream& s : streams_) {
      if (!s.used) {
        stream = &s;
        break;
      }
      if (s.timestamp < stream->timestamp) stream = &s;
    }
    *stream = SigningStream{true, link_id, system_id, component_id, 0};
  }
  stream->timestamp = timestamp;
  newest_timestamp_ = std::max(newest_timestamp_, timestamp);
  return nullptr;
}

bool Parser::CompleteOk() {
  const std::size_t length = buf_[1];
  const std::size_t crc_at = kHeaderLength + length;
  std::uint16_t crc = CrcAccumulate(std::span<const std::uint8_t>(buf_.data() + 1, crc_at - 1));
  crc = CrcAccumulate(info_->crc_extra, crc);
  std::uint16_t received = 0;
  wire::Get(buf_.data() + crc_at, &received);
  if (crc != received) {
    Fail(&counters_.crc_errors);
    return false;
  }
  if (signing_) {
    if (std::uint64_t* failure = SignatureFailure(crc_at + kChecksumLength)) {
      ++counters_.signature_failures;
      Fail(failure);
      return false;
    }
  }
  frame_.header.payload_length = buf_[1];
  frame_.header.incompat_flags = buf_[2];
  frame_.header.compat_flags = buf_[3];
  frame_.header.sequence = buf_[4];
  frame_.header.system_id = buf_[5];
  frame_.header.component_id = buf_[6];
  frame_.header.message_id = info_->id;
  frame_.checksum = received;
  frame_.is_signed = (buf_[2] & kIncompatFlagSigned) != 0;
  if (frame_.is_signed) {
    const std::size_t sig_at = crc_at + kChecksumLength;
    frame_.signature.link_id = buf_[sig_at];
    frame_.signature.timestamp = wire::GetUint(buf_.data() + sig_at + 1, 6);
    std::copy_n(buf_.data() + sig_at + 7, 6, frame_.signature.value.begin());
  } else {
    frame_.signature = FrameSignature{};
  }
  UnpackPayload(info_->id, std::span<const std::uint8_t>(buf_.data() + kHeaderLength, length),
                &frame_.message);
  frame_.bytes = std::span<const std::uint8_t>(buf_.data(), expected_);
  ConfirmUnknownRun(false);
  ++counters_.frames_ok;
  counters_.bytes_in_frames += expected_;
  emitted_ = true;
  return true;
}

}  // namespace fnmpc::mavlink
