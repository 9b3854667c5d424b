// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/ulog/reader.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <utility>

namespace fnmpc::ulog {

namespace {

constexpr std::array<std::uint8_t, 7> kMagic{0x55, 0x4c, 0x6f, 0x67, 0x01, 0x12, 0x35};
constexpr std::array<std::uint8_t, 8> kSyncMagic{0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12};
constexpr std::size_t kHeaderSize = 16;
constexpr std::size_t kMessageHeader = 3;
constexpr std::size_t kMaxMessage = kMessageHeader + 0xFFFF;
constexpr int kMaxNesting = 32;           ///< deeper nesting is refused (no format needs it)
constexpr std::size_t kMaxWarnings = 64;  ///< further warnings are counted in the last one

template <class T>
T Load(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));  // fields are not aligned (spec); little endian host assumed
  return v;
}

std::string Hex(std::uint8_t b) {
  constexpr char kDigits[] = "0123456789abcdef";
  return {'0', 'x', kDigits[b >> 4], kDigits[b & 15]};
}

std::string TypeText(char type) {
  if (std::isprint(static_cast<unsigned char>(type))) return std::string("'") + type + "'";
  return Hex(static_cast<std::uint8_t>(type));
}

bool IsDataSectionType(char t) {
  return t == 'A' || t == 'R' || t == 'D' || t == 'L' || t == 'C' || t == 'S' || t == 'O';
}

bool IsLetter(char t) { return (t >= 'A' && t <= 'Z') || (t >= 'a' && t <= 'z'); }

bool ValidName(std::string_view s, bool allow_slash_dash) {
  if (s.empty()) return false;
  for (char c : s) {
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '_' ||
                    (allow_slash_dash && (c == '-' || c == '/'));
    if (!ok) return false;
  }
  return true;
}

/// `type name` or `type[n] name` -> (type, n, name); false when malformed.
bool SplitTypedName(std::string_view text, std::string& type, bool& is_array, std::uint32_t& length,
                    std::string& name) {
  const std::size_t space = text.find(' ');
  if (space == std::string_view::npos || space == 0) return false;
  std::string_view t = text.substr(0, space);
  std::string_view n = text.substr(space + 1);
  length = 0;
  is_array = false;
  const std::size_t bracket = t.find('[');
  if (bracket != std::string_view::npos) {
    if (t.back() != ']') return false;
    const std::string_view digits = t.substr(bracket + 1, t.size() - bracket - 2);
    if (digits.empty() || digits.size() > 5) return false;
    std::uint32_t v = 0;
    for (char c : digits) {
      if (c < '0' || c > '9') return false;
      v = v * 10 + static_cast<std::uint32_t>(c - '0');
    }
    if (v > 0xFFFF) return false;
    length = v;  // char[0] occurs (an empty multi-information value in PX4 1.9 logs)
    is_array = true;
    t = t.substr(0, bracket);
  }
  if (t.empty() || n.empty()) return false;
  type.assign(t);
  name.assign(n);
  return true;
}

}  // namespace

FormatError::FormatError(const std::string& file, std::uint64_t offset, const std::string& what)
    : std::runtime_error(file + ": offset " + std::to_string(offset) + ": " + what),
      offset_(offset),
      detail_(what) {}

std::size_t BasicSize(BasicType type) {
  switch (type) {
    case BasicType::kInt8:
    case BasicType::kUint8:
    case BasicType::kBool:
    case BasicType::kChar:
      return 1;
    case BasicType::kInt16:
    case BasicType::kUint16:
      return 2;
    case BasicType::kInt32:
    case BasicType::kUint32:
    case BasicType::kFloat:
      return 4;
    case BasicType::kInt64:
    case BasicType::kUint64:
    case BasicType::kDouble:
      return 8;
    case BasicType::kNested:
      return 0;
  }
  return 0;
}

std::string_view BasicTypeName(BasicType type) {
  switch (type) {
    case BasicType::kInt8:
      return "int8_t";
    case BasicType::kUint8:
      return "uint8_t";
    case BasicType::kInt16:
      return "int16_t";
    case BasicType::kUint16:
      return "uint16_t";
    case BasicType::kInt32:
      return "int32_t";
    case BasicType::kUint32:
      return "uint32_t";
    case BasicType::kInt64:
      return "int64_t";
    case BasicType::kUint64:
      return "uint64_t";
    case BasicType::kFloat:
      return "float";
    case BasicType::kDouble:
      return "double";
    case BasicType::kBool:
      return "bool";
    case BasicType::kChar:
      return "char";
    case BasicType::kNested:
      return "";
  }
  return "";
}

std::optional<BasicType> ParseBasicType(std::string_view name) {
  for (int i = 0; i < static_cast<int>(BasicType::kNested); ++i) {
    const auto t = static_cast<BasicType>(i);
    if (BasicTypeName(t) == name) return t;
  }
  return std::nullopt;
}

namespace {
double ScalarAsDouble(const std::uint8_t* p, BasicType type) {
  switch (type) {
    case BasicType::kInt8:
      return Load<std::int8_t>(p);
    case BasicType::kUint8:
      return Load<std::uint8_t>(p);
    case BasicType::kInt16:
      return Load<std::int16_t>(p);
    case BasicType::kUint16:
      return Load<std::uint16_t>(p);
    case BasicType::kInt32:
      return Load<std::int32_t>(p);
    case BasicType::kUint32:
      return Load<std::uint32_t>(p);
    case BasicType::kInt64:
      return static_cast<double>(Load<std::int64_t>(p));
    case BasicType::kUint64:
      return static_cast<double>(Load<std::uint64_t>(p));
    case BasicType::kFloat:
      return Load<float>(p);
    case BasicType::kDouble:
      return Load<double>(p);
    case BasicType::kBool:
      return p[0] != 0 ? 1.0 : 0.0;
    case BasicType::kChar:
      return p[0];
    case BasicType::kNested:
      break;
  }
  return std::numeric_limits<double>::quiet_NaN();
}
}  // namespace

const Column* Subscription::FindColumn(std::string_view column) const {
  for (const Column& c : columns) {
    if (c.name == column) return &c;
  }
  return nullptr;
}

double DataMessage::Value(const Column& column) const {
  if (column.is_string()) return std::numeric_limits<double>::quiet_NaN();
  if (column.offset + BasicSize(column.type) > data.size()) {
    return std::numeric_limits<double>::quiet_NaN();  // only possible inside omitted padding
  }
  return ScalarAsDouble(data.data() + column.offset, column.type);
}

std::span<const std::uint8_t> DataMessage::Bytes(const Column& column) const {
  const std::size_t n = column.length * BasicSize(column.type);
  if (column.offset + n > data.size()) return {};
  return data.subspan(column.offset, n);
}

std::string Info::AsString() const {
  return {reinterpret_cast<const char*>(value.data()), value.size()};
}

std::optional<double> Info::AsNumber() const {
  if (is_array || type == BasicType::kNested || type == BasicType::kChar) {
    return std::nullopt;
  }
  if (value.size() < BasicSize(type)) return std::nullopt;
  return ScalarAsDouble(value.data(), type);
}

// ---- the buffered byte stream ----

/// A window onto the file: Fill(n, limit) makes n bytes from the current position available
/// (fewer at the end of the file or at `limit`), moving the unread rest to the front of the
/// buffer before reading more. One allocation, in the constructor.
class Reader::Stream {
 public:
  Stream(std::FILE* f, std::size_t capacity) : file_(f), buffer_(capacity) {}

  [[nodiscard]] std::uint64_t pos() const { return buffer_pos_ + begin_; }
  [[nodiscard]] const std::uint8_t* data() const { return buffer_.data() + begin_; }
  [[nodiscard]] std::size_t capacity() const { return buffer_.size(); }

  void Seek(std::uint64_t offset) {
    if (offset >= buffer_pos_ && offset <= buffer_pos_ + end_) {
      begin_ = static_cast<std::size_t>(offset - buffer_pos_);
      return;
    }
    buffer_pos_ = offset;
    begin_ = end_ = 0;
    file_pos_valid_ = false;
  }

  std::size_t Fill(std::size_t n, std::uint64_t limit) {
    // Never past `limit`, even when the buffer already holds bytes beyond it.
    const std::uint64_t room_now = limit > pos() ? limit - pos() : 0;
    n = static_cast<std::size_t>(std::min<std::uint64_t>(n, room_now));
    if (end_ - begin_ >= n) return n;
    if (begin_ > 0) {
      std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
      buffer_pos_ += begin_;
      end_ -= begin_;
      begin_ = 0;
    }
    const std::uint64_t read_at = buffer_pos_ + end_;
    if (!file_pos_valid_ || read_at != file_pos_) {
      if (fseeko(file_, static_cast<off_t>(read_at), SEEK_SET) != 0) return end_;
      file_pos_ = read_at;
      file_pos_valid_ = true;
    }
    while (end_ < n) {
      std::size_t want = buffer_.size() - end_;
      const std::uint64_t room = limit > buffer_pos_ + end_ ? limit - (buffer_pos_ + end_) : 0;
      want = static_cast<std::size_t>(std::min<std::uint64_t>(want, room));
      if (want == 0) break;
      const std::size_t got = std::fread(buffer_.data() + end_, 1, want, file_);
      if (got == 0) break;
      end_ += got;
      file_pos_ += got;
    }
    return std::min(end_ - begin_, n);
  }

  void Advance(std::size_t n) { begin_ += n; }

 private:
  std::FILE* file_;
  std::vector<std::uint8_t> buffer_;
  std::uint64_t buffer_pos_ = 0;  ///< file offset of buffer_[0]
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  std::uint64_t file_pos_ = 0;
  bool file_pos_valid_ = false;
};

// ---- reader ----

Reader::Reader(std::string path, ReaderOptions options)
    : path_(std::move(path)), options_(options) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path_, ec)) {
    throw std::runtime_error(path_ + ": not a regular file (or it does not exist)");
  }
  file_size_ = std::filesystem::file_size(path_, ec);
  if (ec) throw std::runtime_error(path_ + ": " + ec.message());
  file_ = std::fopen(path_.c_str(), "rb");
  if (file_ == nullptr) throw std::runtime_error(path_ + ": cannot open: " + std::strerror(errno));
  stream_ = std::make_unique<Stream>(file_, std::max(options_.buffer_size, 2 * kMaxMessage));
  try {
    ReadHeader();
    ReadDefinitions();
    warnings_ = definition_warnings_;
  } catch (...) {
    std::fclose(file_);
    file_ = nullptr;
    throw;
  }
}

Reader::~Reader() {
  if (file_ != nullptr) std::fclose(file_);
}

void Reader::Warn(std::uint64_t offset, std::string what) {
  if (warnings_.size() < kMaxWarnings) {
    warnings_.push_back({offset, std::move(what)});
  } else if (warnings_.size() == kMaxWarnings) {
    warnings_.push_back({offset, "further warnings not listed"});
  }
}

void Reader::ReadHeader() {
  Stream& s = *stream_;
  s.Seek(0);
  if (s.Fill(kHeaderSize, file_size_) < kHeaderSize) {
    throw FormatError(path_, 0, "not a ULog file: shorter than the 16-byte header");
  }
  if (!std::equal(kMagic.begin(), kMagic.end(), s.data())) {
    throw FormatError(path_, 0, "not a ULog file: the file magic is not 'ULog' 01 12 35");
  }
  version_ = s.data()[7];
  start_timestamp_ = Load<std::uint64_t>(s.data() + 8);
  s.Advance(kHeaderSize);
  if (version_ > 1) {
    // Later versions are read as version 1 (the spec asks parsers to try).
    definition_warnings_.push_back(
        {7, "file format version " + std::to_string(version_) + " (read as version 1)"});
  }
}

void Reader::ReadDefinitions() {
  Stream& s = *stream_;
  bool first = true;
  for (;;) {
    const std::uint64_t at = s.pos();
    const std::size_t have = s.Fill(kMessageHeader, file_size_);
    if (have < kMessageHeader) {
      if (have > 0) {
        definitions_truncated_ = true;
        definition_warnings_.push_back(
            {at, "file ends inside a message header in the definitions section (no data)"});
      }
      break;
    }
    const std::uint16_t size = Load<std::uint16_t>(s.data());
    const char type = static_cast<char>(s.data()[2]);
    if (IsDataSectionType(type)) break;
    if (s.Fill(kMessageHeader + size, file_size_) < kMessageHeader + size) {
      definitions_truncated_ = true;
      definition_warnings_.push_back({at, "file ends inside a " + TypeText(type) + " message of " +
                                              std::to_string(size) +
                                              " bytes in the definitions section (no data)"});
      break;
    }
    const std::span<const std::uint8_t> p(s.data() + kMessageHeader, size);
    switch (type) {
      case 'B':
        if (first) {
          HandleFlagBits(p, at);
        } else {
          definition_warnings_.push_back({at, "flag bits message not first: ignored"});
        }
        break;
      case 'F':
        HandleFormat(p, at);
        break;
      case 'I':
        info_.push_back(ParseInfo(p, at, false));
        break;
      case 'M':
        multi_info_.push_back(ParseInfo(p, at, true));
        break;
      case 'P': {
        Parameter prm = ParseParameter(p, at, false);
        parameters_[prm.name] = prm;
        break;
      }
      case 'Q':
        defaults_.push_back(ParseParameter(p, at, true));
        break;
      default:
        if (!IsLetter(type)) {
          throw FormatError(path_, at,
                            "corrupt definitions section: message type " + TypeText(type));
        }
        ++unknown_;
        definition_warnings_.push_back({at, "unknown message type " + TypeText(type) + " (" +
                                                std::to_string(size) + " bytes) skipped"});
        break;
    }
    first = false;
    s.Advance(kMessageHeader + size);
  }
  data_offset_ = s.pos();
  // Appended data: the spec lets a parser assume every offset lies after the definitions.
  if (incompat_[0] & 1) {
    for (std::uint64_t off : appended_) {
      if (off != 0 && off < data_offset_ && !definitions_truncated_) {
        throw FormatError(path_, 24,
                          "appended-data offset " + std::to_string(off) +
                              " lies inside the definitions section (ends at " +
                              std::to_string(data_offset_) + ")");
      }
    }
  }
}

void Reader::HandleFlagBits(std::span<const std::uint8_t> p, std::uint64_t at) {
  if (p.size() < 40) {
    throw FormatError(path_, at,
                      "flag bits message of " + std::to_string(p.size()) + " bytes (40 expected)");
  }
  std::copy_n(p.begin(), 8, compat_.begin());
  std::copy_n(p.begin() + 8, 8, incompat_.begin());
  for (int i = 0; i < 3; ++i) appended_[i] = Load<std::uint64_t>(p.data() + 16 + 8 * i);
  // Only DATA_APPENDED (bit 0 of byte 0) is defined; any other incompatible bit means a log
  // this reader cannot understand, which the spec says to refuse.
  for (int i = 0; i < 8; ++i) {
    const std::uint8_t unknown = i == 0 ? (incompat_[0] & ~1u) : incompat_[i];
    if (unknown != 0) {
      throw FormatError(path_, at + 3 + 8 + i,
                        "unknown incompatible flag bits " + Hex(unknown) + " in byte " +
                            std::to_string(i) + ": this log cannot be read (ULog spec)");
    }
  }
  if ((incompat_[0] & 1) == 0) appended_ = {0, 0, 0};  // offsets mean nothing without the bit
}

void Reader::HandleFormat(std::span<const std::uint8_t> p, std::uint64_t at) {
  const std::string text(reinterpret_cast<const char*>(p.data()), p.size());
  const std::size_t colon = text.find(':');
  auto bad = [&](const std::string& what) {
    throw FormatError(path_, at, "format definition '" + text + "': " + what);
  };
  if (colon == std::string::npos) bad("no ':' after the message name");
  Format f;
  f.name = text.substr(0, colon);
  f.text = text;
  f.file_offset = at;
  if (!ValidName(f.name, true) || ParseBasicType(f.name)) bad("invalid message name");
  std::size_t start = colon + 1;
  while (start < text.size()) {
    std::size_t end = text.find(';', start);
    if (end == std::string::npos) end = text.size();
    const std::string_view item(text.data() + start, end - start);
    start = end + 1;
    if (item.empty()) continue;
    Field field;
    if (!SplitTypedName(item, field.type_name, field.is_array, field.array_length, field.name)) {
      bad("malformed field '" + std::string(item) + "'");
    }
    if (!ValidName(field.name, false)) bad("invalid field name '" + field.name + "'");
    const auto basic = ParseBasicType(field.type_name);
    field.type = basic.value_or(BasicType::kNested);
    f.fields.push_back(std::move(field));
  }
  if (f.fields.empty()) bad("no fields");
  if (format_index_.contains(f.name)) {
    definition_warnings_.push_back({at, "format '" + f.name + "' defined again: the later wins"});
    formats_[format_index_[f.name]] = std::move(f);
    return;
  }
  format_index_[f.name] = static_cast<int>(formats_.size());
  formats_.push_back(std::move(f));
}

void Reader::Resolve(int index, int depth) {
  Format& f = formats_[index];
  if (f.resolved) return;
  if (depth > kMaxNesting) {
    throw FormatError(path_, f.file_offset,
                      "format '" + f.name + "': nested types form a cycle or nest deeper than " +
                          std::to_string(kMaxNesting));
  }
  std::size_t offset = 0;
  for (std::size_t i = 0; i < formats_[index].fields.size(); ++i) {
    Field& field = formats_[index].fields[i];
    if (field.type == BasicType::kNested) {
      const auto it = format_index_.find(field.type_name);
      if (it == format_index_.end()) {
        throw FormatError(path_, formats_[index].file_offset,
                          "format '" + formats_[index].name + "': field '" + field.name +
                              "' has unknown type '" + field.type_name + "'");
      }
      field.nested = it->second;
      Resolve(it->second, depth + 1);  // formats_ is not resized here: references stay valid
      field.element_size = formats_[it->second].size;
    } else {
      field.element_size = BasicSize(field.type);
    }
    field.offset = offset;
    offset += field.element_size * field.count();
    if (offset > (std::size_t{1} << 24)) {  // far beyond any message; keeps sizes from overflowing
      throw FormatError(path_, formats_[index].file_offset,
                        "format '" + formats_[index].name + "' is larger than 16 MiB");
    }
  }
  Format& g = formats_[index];
  g.size = offset;
  g.trailing_padding = 0;
  if (!g.fields.empty() && g.fields.back().padding()) {
    g.trailing_padding = g.fields.back().element_size * g.fields.back().count();
  }
  g.resolved = true;
}

void Reader::Flatten(const Format& f, std::size_t base, const std::string& prefix,
                     std::vector<Column>& out) const {
  for (const Field& field : f.fields) {
    if (field.padding()) continue;
    const std::string name = prefix + field.name;
    if (field.type == BasicType::kNested) {
      const Format& nested = formats_[field.nested];
      for (std::size_t i = 0; i < field.count(); ++i) {
        const std::string element =
            !field.is_array ? name + "." : name + "[" + std::to_string(i) + "].";
        Flatten(nested, base + field.offset + i * field.element_size, element, out);
      }
    } else if (field.type == BasicType::kChar && field.is_array) {
      out.push_back({name, field.type, base + field.offset, field.array_length, true});
    } else if (field.is_array) {
      for (std::size_t i = 0; i < field.count(); ++i) {
        out.push_back({name + "[" + std::to_string(i) + "]", field.type,
                       base + field.offset + i * field.element_size, 1, false});
      }
    } else {
      out.push_back({name, field.type, base + field.offset, 1, false});
    }
  }
}

Info Reader::ParseInfo(std::span<const std::uint8_t> p, std::uint64_t at, bool multi) {
  const std::size_t head = multi ? 2 : 1;
  const char* what = multi ? "multi-information" : "information";
  if (p.size() < head) throw FormatError(path_, at, std::string("empty ") + what + " message");
  Info info;
  info.file_offset = at;
  info.is_continued = multi && p[0] != 0;
  const std::size_t key_len = p[head - 1];
  if (head + key_len > p.size()) {
    throw FormatError(path_, at,
                      std::string(what) + " message: key length " + std::to_string(key_len) +
                          " exceeds the message");
  }
  info.key.assign(reinterpret_cast<const char*>(p.data() + head), key_len);
  std::string type;
  if (!SplitTypedName(info.key, type, info.is_array, info.array_length, info.name)) {
    throw FormatError(path_, at, std::string(what) + " key '" + info.key + "' is not 'type name'");
  }
  const auto basic = ParseBasicType(type);
  info.type = basic.value_or(BasicType::kNested);
  info.value.assign(p.begin() + static_cast<std::ptrdiff_t>(head + key_len), p.end());
  return info;
}

Parameter Reader::ParseParameter(std::span<const std::uint8_t> p, std::uint64_t at,
                                 bool with_default) {
  const std::size_t head = with_default ? 2 : 1;
  if (p.size() < head) throw FormatError(path_, at, "empty parameter message");
  Parameter prm;
  prm.file_offset = at;
  prm.default_types = with_default ? p[0] : 0;
  const std::size_t key_len = p[head - 1];
  if (head + key_len > p.size()) {
    throw FormatError(
        path_, at,
        "parameter message: key length " + std::to_string(key_len) + " exceeds the message");
  }
  const std::string key(reinterpret_cast<const char*>(p.data() + head), key_len);
  std::string type;
  std::uint32_t length = 0;
  bool is_array = false;
  if (!SplitTypedName(key, type, is_array, length, prm.name) || is_array ||
      (type != "int32_t" && type != "float")) {
    throw FormatError(path_, at,
                      "parameter key '" + key + "' is not 'int32_t name' or 'float name'");
  }
  if (p.size() - head - key_len < 4) {
    throw FormatError(path_, at, "parameter '" + prm.name + "': value shorter than 4 bytes");
  }
  const std::uint8_t* v = p.data() + head + key_len;
  prm.is_float = type == "float";
  prm.value = prm.is_float ? static_cast<double>(Load<float>(v)) : Load<std::int32_t>(v);
  prm.last_timestamp = last_timestamp_;
  return prm;
}

const Format* Reader::FindFormat(std::string_view name) const {
  const auto it = format_index_.find(name);
  return it == format_index_.end() ? nullptr : &formats_[it->second];
}

const Info* Reader::FindInfo(std::string_view name) const {
  for (auto it = info_.rbegin(); it != info_.rend(); ++it) {
    if (it->name == name) return &*it;
  }
  return nullptr;
}

std::vector<std::string> Reader::MultiInfoStrings(std::string_view name) const {
  std::vector<std::string> out;
  for (const Info& m : multi_info_) {
    if (m.name != name) continue;
    if (m.is_continued && !out.empty()) {
      out.back() += m.AsString();
    } else {
      out.push_back(m.AsString());
    }
  }
  return out;
}

std::optional<double> Reader::ParameterValue(std::string_view name) const {
  const auto it = parameters_.find(name);
  if (it == parameters_.end()) return std::nullopt;
  return it->second.value;
}

std::string Reader::HandleData(char type, std::span<const std::uint8_t> p, std::uint64_t at,
                               const DataCallback& on_data) {
  switch (type) {
    case 'D': {
      if (p.size() < 2) return "data message shorter than its msg_id";
      const std::uint16_t id = Load<std::uint16_t>(p.data());
      const int index = sub_by_id_[id];
      if (index < 0) return "data message for msg_id " + std::to_string(id) + " not subscribed";
      Subscription& sub = subs_[index];
      const Format& f = formats_[sub.format];
      const std::size_t n = p.size() - 2;
      if (n < sub.min_size || n > f.size) {
        return "data message of " + std::to_string(n) + " bytes for '" + sub.name + "' (msg_id " +
               std::to_string(id) + ") whose format has " + std::to_string(f.size) + " bytes";
      }
      DataMessage m;
      m.subscription = &sub;
      m.data = p.subspan(2);
      m.file_offset = at;
      m.timestamp = Load<std::uint64_t>(m.data.data() + sub.timestamp_offset);
      if (sub.count == 0) {
        sub.first_timestamp = m.timestamp;
      } else if (m.timestamp < sub.last_timestamp) {
        ++sub.non_monotonic;
      } else if (m.timestamp - sub.last_timestamp > sub.max_interval) {
        sub.max_interval = m.timestamp - sub.last_timestamp;
        sub.max_interval_end = m.timestamp;
      }
      ++sub.count;
      sub.last_timestamp = m.timestamp;
      last_timestamp_ = std::max(last_timestamp_, m.timestamp);
      if (on_data) on_data(m);
      return {};
    }
    case 'A': {
      if (p.size() < 4) return "subscription message shorter than 4 bytes";
      Subscription sub;
      sub.multi_id = p[0];
      sub.msg_id = Load<std::uint16_t>(p.data() + 1);
      sub.name.assign(reinterpret_cast<const char*>(p.data() + 3), p.size() - 3);
      sub.file_offset = at;
      const auto it = format_index_.find(sub.name);
      if (it == format_index_.end()) return "subscription to unknown format '" + sub.name + "'";
      if (sub_by_id_[sub.msg_id] >= 0) {
        return "msg_id " + std::to_string(sub.msg_id) + " subscribed twice ('" +
               subs_[sub_by_id_[sub.msg_id]].name + "', '" + sub.name + "')";
      }
      sub.format = it->second;
      Resolve(sub.format, 0);  // a bad nested type is a FormatError naming its definition
      const Format& f = formats_[sub.format];
      if (f.size - f.trailing_padding > 0xFFFF - 2) {
        return "subscribed format '" + sub.name + "' has " + std::to_string(f.size) +
               " bytes, more than a data message can hold";
      }
      bool has_timestamp = false;
      for (const Field& field : f.fields) {
        if (field.name == "timestamp" && field.type == BasicType::kUint64 && !field.is_array) {
          sub.timestamp_offset = field.offset;
          has_timestamp = true;
          break;
        }
      }
      if (!has_timestamp) return "subscribed format '" + sub.name + "' has no uint64_t timestamp";
      sub.min_size = f.size - f.trailing_padding;
      Flatten(f, 0, "", sub.columns);
      sub_by_id_[sub.msg_id] = static_cast<int>(subs_.size());
      subs_.push_back(std::move(sub));
      return {};
    }
    case 'R': {
      if (p.size() < 2) return "unsubscription message shorter than 2 bytes";
      sub_by_id_[Load<std::uint16_t>(p.data())] = -1;
      return {};
    }
    case 'L':
    case 'C': {
      const bool tagged = type == 'C';
      const std::size_t head = tagged ? 11 : 9;
      if (p.size() < head) return "logged string message shorter than its header";
      LogMessage log;
      log.level = p[0];
      log.tagged = tagged;
      if (tagged) log.tag = Load<std::uint16_t>(p.data() + 1);
      log.timestamp = Load<std::uint64_t>(p.data() + head - 8);
      log.text.assign(reinterpret_cast<const char*>(p.data() + head), p.size() - head);
      log.file_offset = at;
      logs_.push_back(std::move(log));
      return {};
    }
    case 'S':
      if (p.size() < kSyncMagic.size() ||
          !std::equal(kSyncMagic.begin(), kSyncMagic.end(), p.data())) {
        return "sync message with a wrong magic";
      }
      ++syncs_;
      return {};
    case 'O':
      if (p.size() < 2) return "dropout message shorter than 2 bytes";
      dropouts_.push_back({Load<std::uint16_t>(p.data()), last_timestamp_, at});
      return {};
    case 'I':
    case 'M':
    case 'P':
    case 'Q':
      // Shared with the definitions section; a malformed one here is a corrupt message.
      try {
        if (type == 'I' || type == 'M') {
          Info info = ParseInfo(p, at, type == 'M');
          info.in_data_section = true;
          (type == 'I' ? info_ : multi_info_).push_back(std::move(info));
        } else {
          (type == 'P' ? changes_ : defaults_).push_back(ParseParameter(p, at, type == 'Q'));
        }
      } catch (const FormatError& e) {
        return e.detail();
      }
      return {};
    case 'F':
      // Formats belong to the definitions section; one here could change a subscribed layout.
      Warn(at, "format definition in the data section: ignored");
      return {};
    case 'B':
      Warn(at, "flag bits message in the data section: ignored");
      return {};
    default:
      if (!IsLetter(type)) return "message type " + TypeText(type) + " is not a ULog message type";
      ++unknown_;
      Warn(at, "unknown message type " + TypeText(type) + " (" + std::to_string(p.size()) +
                   " bytes) skipped");
      return {};
  }
}

void Reader::ReadData(const DataCallback& on_data) {
  // Start over: the data-section state is rebuilt on every pass.
  subs_.clear();
  sub_by_id_.assign(0x10000, -1);
  logs_.clear();
  dropouts_.clear();
  changes_.clear();
  syncs_ = 0;
  last_timestamp_ = 0;
  truncated_ = definitions_truncated_;
  warnings_ = definition_warnings_;
  // Info, multi info and defaults of the data section come back on each pass.
  auto in_data = [](const Info& i) { return i.in_data_section; };
  info_.erase(std::remove_if(info_.begin(), info_.end(), in_data), info_.end());
  multi_info_.erase(std::remove_if(multi_info_.begin(), multi_info_.end(), in_data),
                    multi_info_.end());
  defaults_.erase(std::remove_if(defaults_.begin(), defaults_.end(),
                                 [&](const Parameter& q) { return q.file_offset >= data_offset_; }),
                  defaults_.end());
  if (definitions_truncated_) return;

  // Segments of the data section: up to the first appended offset, then each appended part.
  // A message cut at a segment's end (a log that stopped mid-message before data was
  // appended) is discarded; reading goes on at the next segment.
  std::vector<std::uint64_t> bounds{data_offset_};
  for (std::uint64_t off : appended_) {
    if (off == 0) continue;
    if (off > file_size_) {
      Warn(24, "appended-data offset " + std::to_string(off) + " beyond the end of the file (" +
                   std::to_string(file_size_) + " bytes): ignored");
      continue;
    }
    if (off > bounds.back()) bounds.push_back(off);
  }
  bounds.push_back(file_size_);

  Stream& s = *stream_;
  for (std::size_t seg = 0; seg + 1 < bounds.size(); ++seg) {
    const std::uint64_t limit = bounds[seg + 1];
    const bool last = seg + 2 == bounds.size();
    s.Seek(bounds[seg]);
    while (s.pos() < limit) {
      const std::uint64_t at = s.pos();
      const std::size_t have = s.Fill(kMessageHeader, limit);
      std::uint16_t size = 0;
      char type = 0;
      if (have >= kMessageHeader) {
        size = Load<std::uint16_t>(s.data());
        type = static_cast<char>(s.data()[2]);
      }
      if (have < kMessageHeader || s.Fill(kMessageHeader + size, limit) < kMessageHeader + size) {
        const std::string cut = have < kMessageHeader ? "a message header"
                                                      : "a " + TypeText(type) + " message of " +
                                                            std::to_string(size) + " bytes";
        if (last) {
          truncated_ = true;
          Warn(at, "truncated: the file ends inside " + cut + " (" + std::to_string(limit - at) +
                       " bytes left); data up to offset " + std::to_string(at) + " kept");
        } else {
          Warn(at, "the log stops inside " + cut + " where appended data starts (offset " +
                       std::to_string(limit) + "): discarded");
        }
        s.Seek(limit);
        break;
      }
      const std::span<const std::uint8_t> p(s.data() + kMessageHeader, size);
      const std::string corrupt = HandleData(type, p, at, on_data);
      if (corrupt.empty()) {
        s.Advance(kMessageHeader + size);
        continue;
      }
      if (options_.strict) throw FormatError(path_, at, "corrupt message: " + corrupt);
      // Resynchronise: the next sync message (header 08 00 'S' and the magic) after `at`.
      std::array<std::uint8_t, 11> pattern{0x08, 0x00, 'S'};
      std::copy(kSyncMagic.begin(), kSyncMagic.end(), pattern.begin() + 3);
      s.Advance(1);
      bool found = false;
      while (s.pos() < limit) {
        const std::size_t n = s.Fill(s.capacity() / 2, limit);
        const std::uint8_t* hit =
            std::search(s.data(), s.data() + n, pattern.begin(), pattern.end());
        if (hit != s.data() + n) {
          s.Advance(static_cast<std::size_t>(hit - s.data()));
          found = true;
          break;
        }
        if (n < pattern.size()) {
          s.Advance(n);
          break;
        }
        s.Advance(n - (pattern.size() - 1));  // a pattern may straddle the window's end
        if (s.pos() + (pattern.size() - 1) >= limit) {
          s.Seek(limit);
          break;
        }
      }
      if (found) {
        Warn(at, "corrupt message (" + corrupt + "): skipped to the sync message at offset " +
                     std::to_string(s.pos()));
      } else {
        Warn(at, "corrupt message (" + corrupt + "): no sync message follows; data from offset " +
                     std::to_string(at) + " to " + std::to_string(limit) + " skipped");
        s.Seek(limit);
      }
    }
  }
}

}  // namespace fnmpc::ulog
