#pragma once
// DBC (Vector CAN database) parser and signal decoding. Parsing is load-time (allocates, reports errors with
// file:line); decoding (DbcSignal::decode / raw) is real-time safe.
// Understood: VERSION, NS_ (block skipped), BS_, BU_, BO_, SG_ (Intel @1 / Motorola @0, +/- sign, factor,
// offset, [min|max], "unit", receivers, multiplexor M, multiplexed mN, extended mNM), CM_ (BU_/BO_/SG_
// comments kept), VAL_ (value tables kept), SIG_VALTYPE_ (IEEE float32/float64 signals), SG_MUL_VAL_
// (extended multiplexing ranges); VAL_TABLE_, BA_DEF_, BA_DEF_DEF_, BA_, BA_DEF_REL_, ... (ignored safely).
// Unknown keywords are skipped with a warning. Files as vehicles ship them: a bad statement is reported once
// ("file:line: what was expected") and skipped, the rest of the file loads; DbcParseResult::affecting() says
// whether a given signal was taken out by one of those errors (the daemon refuses only then).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace torqued {

struct DbcSignal {
  enum class Mux : std::uint8_t { kPlain = 0, kMultiplexor = 1, kMultiplexed = 2 };
  /// SIG_VALTYPE_: 0 integer, 1 IEEE 754 float32 (length 32), 2 IEEE 754 float64 (length 64).
  enum class ValueType : std::uint8_t { kInteger = 0, kFloat32 = 1, kFloat64 = 2 };

  std::string name;
  std::uint16_t start_bit = 0;  ///< as written in the DBC (Motorola: MSB position in sawtooth numbering)
  std::uint16_t length = 0;     ///< bits (1..64)
  bool little_endian = true;    ///< @1 Intel, @0 Motorola
  bool is_signed = false;
  double factor = 1.0;
  double offset = 0.0;
  double min = 0.0;  ///< physical range; min == max == 0 means "no range given"
  double max = 0.0;
  std::string unit;
  std::vector<std::string> receivers;
  Mux mux = Mux::kPlain;
  std::uint32_t mux_value = 0;    ///< for kMultiplexed: value of the multiplexor selecting this signal
  bool also_multiplexor = false;  ///< m<n>M: multiplexed and itself a multiplexor (extended multiplexing)
  int mux_parent = -1;  ///< for kMultiplexed: index (in the message) of the multiplexor selecting this signal
  /// SG_MUL_VAL_ ranges of the parent's raw value selecting this signal (empty: raw == mux_value).
  std::vector<std::pair<std::uint64_t, std::uint64_t>> mux_ranges;
  ValueType value_type = ValueType::kInteger;
  std::string comment;
  std::vector<std::pair<std::int64_t, std::string>> value_table;  ///< VAL_ entries

  /// Smallest payload length (bytes) that holds the signal.
  [[nodiscard]] std::size_t bytes_needed() const noexcept;
  /// Raw integer (sign-extended when is_signed; an unsigned 64-bit raw with bit 63 set comes out as its
  /// two's-complement bit pattern: use raw_bits() for the value). Precondition: len >= bytes_needed().
  /// Real-time safe.
  [[nodiscard]] std::int64_t raw(const std::uint8_t* data, std::size_t len) const noexcept;
  /// The raw bits, zero-extended (the exact value of an unsigned signal). Real-time safe.
  [[nodiscard]] std::uint64_t raw_bits(const std::uint8_t* data, std::size_t len) const noexcept;
  /// The same as raw(), bit by bit (the DBC definition, written out): reference for tests, > 8-byte case.
  [[nodiscard]] std::int64_t raw_bitwise(const std::uint8_t* data, std::size_t len) const noexcept;
  /// Raw value as a number: signed or unsigned integer (exact up to 2^53, then rounded once), or the IEEE
  /// float the bits hold (SIG_VALTYPE_). Real-time safe.
  [[nodiscard]] double raw_value(const std::uint8_t* data, std::size_t len) const noexcept;
  /// Physical value = raw × factor + offset. Real-time safe.
  [[nodiscard]] double decode(const std::uint8_t* data, std::size_t len) const noexcept {
    return raw_value(data, len) * factor + offset;
  }
  [[nodiscard]] bool has_range() const noexcept { return !(min == 0.0 && max == 0.0); }
  /// Value-table text for a raw value, or nullptr.
  [[nodiscard]] const std::string* value_name(std::int64_t raw_value) const noexcept;
};

struct DbcMessage {
  std::uint32_t id = 0;  ///< identifier without the extended flag (bit 31 of the DBC id)
  bool extended = false;
  std::string name;
  std::uint8_t dlc = 0;  ///< declared length in bytes (0..64)
  std::string transmitter;
  std::string comment;
  std::vector<DbcSignal> signals;
  int multiplexor = -1;  ///< index into signals of the (top-level) multiplexor, -1 if none

  [[nodiscard]] const DbcSignal* find(std::string_view signal_name) const noexcept;
  /// Whether a multiplexed signal is present in this payload (always true for plain signals); with extended
  /// multiplexing, every multiplexor up the chain must be present and select it.
  [[nodiscard]] bool signal_present(const DbcSignal& s, const std::uint8_t* data,
                                    std::size_t len) const noexcept;
};

struct DbcParseResult;

class DbcDatabase {
 public:
  /// Parse a DBC file. Errors name the file and line; parsing continues after a bad line to report them all.
  [[nodiscard]] static DbcParseResult parse_file(const std::string& path);
  /// Parse DBC text; `name` is used in messages in place of a file name.
  [[nodiscard]] static DbcParseResult parse_string(std::string_view text, std::string_view name = "<string>");

  [[nodiscard]] const std::string& version() const noexcept { return version_; }
  [[nodiscard]] const std::vector<std::string>& nodes() const noexcept { return nodes_; }
  [[nodiscard]] const std::vector<DbcMessage>& messages() const noexcept { return messages_; }
  [[nodiscard]] const DbcMessage* find(std::uint32_t id, bool extended) const noexcept;
  [[nodiscard]] const DbcMessage* find(std::string_view message_name) const noexcept;

 private:
  friend class DbcParser;
  std::string version_;
  std::vector<std::string> nodes_;
  std::vector<DbcMessage> messages_;
};

/// What one skipped statement took out: a whole message (signal empty) or one signal.
struct DbcSkip {
  std::size_t error = 0;  ///< index into DbcParseResult::errors
  std::string message;
  std::string signal;
};

/// Result of parsing: the database (whenever the text could be read; bad statements are skipped) plus every
/// error (one per skipped statement) and warning as "file:line: message".
struct DbcParseResult {
  std::optional<DbcDatabase> db;
  std::vector<std::string> errors;
  std::vector<std::string> warnings;
  std::vector<DbcSkip> skipped;

  /// The error that took out message.signal (or all of the message), or nullptr when it loaded intact.
  [[nodiscard]] const std::string* affecting(std::string_view message,
                                             std::string_view signal) const noexcept;
};

}  // namespace torqued
