#pragma once
// MCAP (https://mcap.dev/spec, major version 0) building blocks shared by the recorder (mcap_writer.hpp), the
// recovery tool (torque-mcap-recover) and the tests: record opcodes, little-endian field encoding, CRC32
// (zlib's, the spec's CRC-32/ISO-HDLC), a bounds-checked field reader, splitting a byte range into records
// (stopping at the first incomplete one, as after a kill -9) and chunk decompression (zstd through libzstd,
// or none) with the chunk's CRC checked. Not real-time code.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace torqued::dash::mcap {

inline constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};
enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F
};
inline constexpr std::size_t kRecordHead = 9;  ///< opcode (1) + content length (8)

/// CRC32 of `n` bytes continuing `crc` (0 to start), as the spec's CRC fields.
std::uint32_t crc32(const void* p, std::size_t n, std::uint32_t crc = 0);

template <class T>
void put_le(std::string& out, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i)
    out += static_cast<char>(static_cast<std::uint64_t>(v) >> (8 * i));
}
/// The spec's String / Bytes with a uint32 length prefix.
void put_str(std::string& out, std::string_view s);

/// Reads little-endian fields from a record body; any read past the end clears ok() and returns zeros.
class Fields {
 public:
  explicit Fields(std::string_view b) : b_(b) {}
  std::uint8_t u8() { return static_cast<std::uint8_t>(num(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(num(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(num(4)); }
  std::uint64_t u64() { return num(8); }
  std::string_view str() { return bytes(u32()); }  ///< uint32-prefixed String or Bytes
  std::string_view bytes(std::uint64_t n);
  std::string_view rest() { return bytes(b_.size() - pos_); }
  [[nodiscard]] bool ok() const noexcept { return ok_; }
  [[nodiscard]] std::size_t pos() const noexcept { return pos_; }
  [[nodiscard]] std::size_t remaining() const noexcept { return b_.size() - pos_; }

 private:
  std::uint64_t num(int n);
  std::string_view b_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

struct RecordView {
  std::uint8_t op = 0;
  std::uint64_t offset = 0;  ///< of the opcode, relative to the start of the split range
  std::string_view body;
};
struct Split {
  std::vector<RecordView> records;  ///< every complete record, in order
  std::uint64_t end = 0;            ///< offset just after the last complete record
  bool truncated = false;           ///< bytes were left that do not form a complete record
};
/// Splits `data` (records back to back) into records; stops at the first incomplete one.
Split split_records(std::string_view data);

/// A whole file: leading magic, top-level records, and whether it ends with Footer + magic.
struct FileView {
  bool magic = false;   ///< starts with the MCAP magic
  bool closed = false;  ///< a Footer record followed by the closing magic ends the file
  Split split;          ///< offsets are file offsets
};
FileView split_file(std::string_view file);

struct MessageView {
  std::uint16_t channel = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0, publish_time = 0;
  std::string_view data;
};
std::optional<MessageView> parse_message(std::string_view body);

struct ChunkView {
  std::uint64_t start_time = 0, end_time = 0, uncompressed_size = 0;
  std::uint32_t uncompressed_crc = 0;
  std::string_view compression, records;  ///< records: compressed bytes
};
std::optional<ChunkView> parse_chunk(std::string_view body);
/// Decompresses a chunk's records into `out` and checks the size and (when not 0) the CRC.
/// Returns "" or what is wrong.
std::string decompress_chunk(const ChunkView& c, std::string& out);

}  // namespace torqued::dash::mcap
