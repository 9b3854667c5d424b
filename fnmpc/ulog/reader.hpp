// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

/// A streaming reader of PX4 ULog files (`.ulg`), written after the ULog file-format
/// specification in PX4's documentation ("ULog File Format", docs/ulog.md): header, flag bits
/// (appended data), format definitions with nested types and arrays, information and
/// multi-information messages, parameters and default parameters, subscriptions with multi-id
/// instances, logged data, logged strings (plain and tagged), dropouts and synchronisation.
///
/// The file is read through one buffer (at least the 64 KiB a message can take): a 100 MB log
/// is never in memory, and a data message reaches the callback as a view into that buffer,
/// without an allocation per message.
namespace fnmpc::ulog {

/// A file that is not a ULog file, or whose definitions or data are corrupt in a way the
/// reader cannot recover from (an unknown incompatible flag bit, a malformed format, a corrupt
/// message in strict mode). what() names the file and the byte offset.
class FormatError : public std::runtime_error {
 public:
  FormatError(const std::string& file, std::uint64_t offset, const std::string& what);
  /// Byte offset (0-based) of the message or header the error is about.
  [[nodiscard]] std::uint64_t offset() const { return offset_; }
  /// What is wrong, without the file and offset.
  [[nodiscard]] const std::string& detail() const { return detail_; }

 private:
  std::uint64_t offset_;
  std::string detail_;
};

/// The basic binary types of the specification, and kNested for a field whose type is another
/// format definition.
enum class BasicType : std::uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kInt64,
  kUint64,
  kFloat,
  kDouble,
  kBool,
  kChar,
  kNested,
};

/// Size in bytes of a basic type (0 for kNested).
std::size_t BasicSize(BasicType type);
/// The specification's name of a basic type ("float", "uint64_t", ...; "" for kNested).
std::string_view BasicTypeName(BasicType type);
/// The basic type named `name`, or nullopt when it is not one (then it names a format).
std::optional<BasicType> ParseBasicType(std::string_view name);

/// One field of a format definition: `type name` or `type[array_length] name`.
struct Field {
  std::string type_name;  ///< as written ("float", "esc_report")
  BasicType type = BasicType::kNested;
  std::string name;
  bool is_array = false;
  std::uint32_t array_length = 0;  ///< elements of an array (0 is allowed)
  int nested = -1;                 ///< index of the nested format (Reader::formats())
  std::size_t offset = 0;          ///< byte offset in the format's record
  std::size_t element_size = 0;    ///< bytes of one element

  [[nodiscard]] std::size_t count() const { return is_array ? array_length : 1; }
  /// A `_padding...` field: alignment bytes a reader ignores.
  [[nodiscard]] bool padding() const { return name.starts_with("_padding"); }
};

/// A format definition ('F' message): `message_name:field0;field1;...`.
struct Format {
  std::string name;
  std::vector<Field> fields;
  std::size_t size = 0;              ///< record size, every field and padding included
  std::size_t trailing_padding = 0;  ///< size of a last `_padding` field, which a writer may omit
  std::uint64_t file_offset = 0;     ///< of the 'F' message
  std::string text;                  ///< the definition as written
  bool resolved = false;             ///< offsets and sizes computed (nested types known)
};

/// A leaf value of a record, nested types and arrays flattened: "x", "q[0]",
/// "esc[2].esc_rpm". A char array is one column (a string) of `length` bytes.
struct Column {
  std::string name;
  BasicType type = BasicType::kUint8;
  std::size_t offset = 0;  ///< in the record
  std::size_t length = 1;  ///< elements: 1, or the length of a char array
  bool string = false;     ///< a char array (text)
  [[nodiscard]] bool is_string() const { return string; }
};

/// A subscription ('A' message): a topic instance and the id of its data messages, with the
/// statistics of its data messages (filled while ReadData runs).
struct Subscription {
  std::uint16_t msg_id = 0;
  std::uint8_t multi_id = 0;
  std::string name;  ///< the topic (format name)
  int format = -1;   ///< index into Reader::formats()
  std::size_t timestamp_offset = 0;
  std::size_t min_size = 0;  ///< record size without an omitted trailing padding
  std::vector<Column> columns;
  std::uint64_t file_offset = 0;  ///< of the 'A' message

  std::uint64_t count = 0;             ///< data messages read
  std::uint64_t first_timestamp = 0;   ///< [us]
  std::uint64_t last_timestamp = 0;    ///< [us]
  std::uint64_t max_interval = 0;      ///< largest step between consecutive timestamps [us]
  std::uint64_t max_interval_end = 0;  ///< timestamp at the end of that step [us]
  std::uint64_t non_monotonic = 0;     ///< data messages whose timestamp went backwards

  /// The flattened column `name`, or nullptr.
  [[nodiscard]] const Column* FindColumn(std::string_view column) const;
};

/// A logged data message ('D') as the callback of Reader::ReadData sees it. `data` points into
/// the reader's buffer and is valid only during the call.
struct DataMessage {
  const Subscription* subscription = nullptr;
  std::uint64_t timestamp = 0;  ///< [us]
  std::uint64_t file_offset = 0;
  std::span<const std::uint8_t> data;  ///< the record (its trailing padding may be missing)

  /// A numeric column as a double (64-bit integers rounded to the nearest double; a bool
  /// 0 or 1; a char its code). NaN for a string column.
  [[nodiscard]] double Value(const Column& column) const;
  /// The column's bytes in the record (little endian, as logged; for exact comparisons).
  [[nodiscard]] std::span<const std::uint8_t> Bytes(const Column& column) const;
};

/// An information ('I') or multi-information ('M') message: `key` is `type name`.
struct Info {
  std::string key;   ///< as written, e.g. "char[5] sys_name"
  std::string name;  ///< "sys_name"
  BasicType type = BasicType::kChar;
  bool is_array = false;
  std::uint32_t array_length = 0;
  std::vector<std::uint8_t> value;  ///< raw bytes
  bool is_continued = false;        ///< 'M' only: part of the previous message with this key
  bool in_data_section = false;
  std::uint64_t file_offset = 0;

  /// The value of a char array as text (bytes as they are).
  [[nodiscard]] std::string AsString() const;
  /// The value of a numeric scalar (nullopt for arrays, strings or a short value).
  [[nodiscard]] std::optional<double> AsNumber() const;
};

/// A parameter ('P') or default parameter ('Q'): int32_t or float.
struct Parameter {
  std::string name;
  bool is_float = false;
  double value = 0.0;              ///< int32 exact, float widened
  std::uint8_t default_types = 0;  ///< 'Q' only: bit 0 system default, bit 1 configuration
  std::uint64_t file_offset = 0;
  std::uint64_t last_timestamp = 0;  ///< data section: timestamp of the last data message before
};

/// A logged string ('L', or 'C' with a tag).
struct LogMessage {
  std::uint8_t level = 0;  ///< as logged: '0' (EMERG) ... '7' (DEBUG)
  bool tagged = false;
  std::uint16_t tag = 0;
  std::uint64_t timestamp = 0;  ///< [us]
  std::string text;
  std::uint64_t file_offset = 0;
};

/// A dropout mark ('O'): logging lost messages for `duration_ms`.
struct Dropout {
  std::uint16_t duration_ms = 0;
  std::uint64_t last_timestamp = 0;  ///< of the last data message before the mark [us]
  std::uint64_t file_offset = 0;
};

/// Something the reader skipped or could not read, with its byte offset.
struct Warning {
  std::uint64_t offset = 0;
  std::string what;
};

struct ReaderOptions {
  /// Bytes of the read buffer (raised to 128 KiB: a message can take 64 KiB + 3).
  std::size_t buffer_size = std::size_t{1} << 20;
  /// Throw FormatError on a corrupt data message instead of skipping to the next sync
  /// message (or the end of the data) with a warning.
  bool strict = false;
};

/// Reads a ULog file: the constructor reads the header and the definitions section
/// (formats, information, parameters); ReadData streams the data section.
///
/// Errors: FormatError (file and offset) for a file that is not ULog, an unknown incompatible
/// flag bit (the specification says to refuse such a log), malformed definitions, and, in
/// strict mode, a corrupt data message. A file that ends inside a message (a truncated log)
/// is not an error: what was read is kept and warnings() names the offset where it ends. A
/// corrupt data message (unknown msg_id, a size that does not fit its format, a non-letter
/// message type, a bad sync magic) is skipped to the next sync message, or to the end of
/// the data when there is none, with a warning naming both offsets.
class Reader {
 public:
  explicit Reader(std::string path, ReaderOptions options = {});
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  // ---- header and definitions (available after construction) ----
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] std::uint64_t file_size() const { return file_size_; }
  [[nodiscard]] std::uint8_t version() const { return version_; }
  /// Header timestamp: when logging started [us].
  [[nodiscard]] std::uint64_t start_timestamp() const { return start_timestamp_; }
  [[nodiscard]] const std::array<std::uint8_t, 8>& compat_flags() const { return compat_; }
  [[nodiscard]] const std::array<std::uint8_t, 8>& incompat_flags() const { return incompat_; }
  [[nodiscard]] const std::array<std::uint64_t, 3>& appended_offsets() const { return appended_; }
  /// Offset of the first message of the data section.
  [[nodiscard]] std::uint64_t data_offset() const { return data_offset_; }

  [[nodiscard]] const std::vector<Format>& formats() const { return formats_; }
  /// The format named `name`, or nullptr.
  [[nodiscard]] const Format* FindFormat(std::string_view name) const;
  /// Information messages ('I'), in file order (definitions and data section).
  [[nodiscard]] const std::vector<Info>& info() const { return info_; }
  /// The information message named `name` (the last one), or nullptr.
  [[nodiscard]] const Info* FindInfo(std::string_view name) const;
  /// Multi-information messages ('M') in file order.
  [[nodiscard]] const std::vector<Info>& multi_info() const { return multi_info_; }
  /// Multi-information `name` with continued pieces joined, one entry per message series.
  [[nodiscard]] std::vector<std::string> MultiInfoStrings(std::string_view name) const;
  /// Parameters of the definitions section (values when logging started), by name.
  [[nodiscard]] const std::map<std::string, Parameter, std::less<>>& parameters() const {
    return parameters_;
  }
  /// The value of parameter `name` when logging started, or nullopt.
  [[nodiscard]] std::optional<double> ParameterValue(std::string_view name) const;
  /// Default parameters ('Q'), in file order.
  [[nodiscard]] const std::vector<Parameter>& default_parameters() const { return defaults_; }

  // ---- data section (filled by ReadData) ----
  using DataCallback = std::function<void(const DataMessage&)>;
  /// Reads the data section from its start (each call starts over), calling `on_data` for
  /// every logged data message in file order; subscriptions, logged strings, dropouts,
  /// parameter changes and warnings are collected on the way.
  void ReadData(const DataCallback& on_data);

  /// Subscriptions in the order they were added.
  [[nodiscard]] const std::vector<Subscription>& subscriptions() const { return subs_; }
  [[nodiscard]] const std::vector<LogMessage>& logs() const { return logs_; }
  [[nodiscard]] const std::vector<Dropout>& dropouts() const { return dropouts_; }
  /// Parameters that changed during the log ('P' in the data section).
  [[nodiscard]] const std::vector<Parameter>& parameter_changes() const { return changes_; }
  [[nodiscard]] std::uint64_t sync_count() const { return syncs_; }
  /// Everything skipped or cut: truncated tail, corrupt messages, unknown message types.
  [[nodiscard]] const std::vector<Warning>& warnings() const { return warnings_; }
  /// True when the file ends inside a message (the last message was discarded).
  [[nodiscard]] bool truncated() const { return truncated_; }
  /// Messages of unknown (letter) types skipped.
  [[nodiscard]] std::uint64_t unknown_messages() const { return unknown_; }

 private:
  class Stream;
  void ReadHeader();
  void ReadDefinitions();
  void HandleFlagBits(std::span<const std::uint8_t> p, std::uint64_t at);
  void HandleFormat(std::span<const std::uint8_t> p, std::uint64_t at);
  Info ParseInfo(std::span<const std::uint8_t> p, std::uint64_t at, bool multi);
  Parameter ParseParameter(std::span<const std::uint8_t> p, std::uint64_t at, bool with_default);
  void Resolve(int index, int depth);
  void Flatten(const Format& f, std::size_t base, const std::string& prefix,
               std::vector<Column>& out) const;
  /// Handles one data-section message; returns an empty string or what is corrupt about it.
  std::string HandleData(char type, std::span<const std::uint8_t> p, std::uint64_t at,
                         const DataCallback& on_data);
  void Warn(std::uint64_t offset, std::string what);

  std::string path_;
  ReaderOptions options_;
  std::FILE* file_ = nullptr;
  std::uint64_t file_size_ = 0;
  std::unique_ptr<Stream> stream_;

  std::uint8_t version_ = 0;
  std::uint64_t start_timestamp_ = 0;
  std::array<std::uint8_t, 8> compat_{};
  std::array<std::uint8_t, 8> incompat_{};
  std::array<std::uint64_t, 3> appended_{};
  std::uint64_t data_offset_ = 0;
  bool definitions_truncated_ = false;

  std::vector<Format> formats_;
  std::map<std::string, int, std::less<>> format_index_;
  std::vector<Info> info_;
  std::vector<Info> multi_info_;
  std::map<std::string, Parameter, std::less<>> parameters_;
  std::vector<Parameter> defaults_;

  std::vector<Subscription> subs_;
  std::vector<int> sub_by_id_;  ///< msg_id -> index into subs_, -1 when none
  std::vector<LogMessage> logs_;
  std::vector<Dropout> dropouts_;
  std::vector<Parameter> changes_;
  std::vector<Warning> warnings_;
  std::vector<Warning> definition_warnings_;
  std::uint64_t syncs_ = 0;
  std::uint64_t unknown_ = 0;
  std::uint64_t last_timestamp_ = 0;
  bool truncated_ = false;
};

}  // namespace fnmpc::ulog
