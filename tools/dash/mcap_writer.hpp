#pragma once
// MCAP recording (https://mcap.dev/spec, major version 0), laid out as the MCAP readers expect:
//   magic, Header, Schema and Channel records, then Chunks (zstd-compressed through libzstd, the chunk's
//   CRC32), each followed by one MessageIndex record per channel in it; DataEnd with the data section's
//   CRC32; a summary section (Schemas, Channels, Statistics, one ChunkIndex per chunk), SummaryOffset
//   records, the Footer with the summary CRC32, magic.
// A chunk is closed, written and flushed when it holds McapOptions::chunk_period_ns of log time or
// chunk_bytes of records, and by tick() once its first message is chunk_period_ns old: a writer killed (kill
// -9) loses at most the open chunk; every complete chunk before it reads with a streamed reader, and
// torque-mcap-recover rewrites such a file with its summary. For torque-dash: one JSON Schema and one channel
// (message encoding "json") per topic (foxglove.hpp); log_time = receive time (CLOCK_REALTIME ns),
// publish_time = the sample's publish_t_ns (its source_t_ns when 0: fast replay). Not real-time code:
// torque-dash calls it from its DDS subscriber thread (never the daemon's), which compresses each chunk
// inline (zstd level 1: about 0.3 % of one core at the demo's 1x data rate; docs/dashboard.md). Buffered
// stdio, flushed per chunk.
#include <array>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "qos.hpp"
#include "sample.hpp"

struct ZSTD_CCtx_s;

namespace torqued::dash {

struct McapOptions {
  std::string compression = "zstd";  ///< "zstd" or "" (chunks stored uncompressed)
  int zstd_level = 1;  ///< level 1: as small as 3-9 on these JSON messages, the cheapest (docs/dashboard.md)
  std::uint64_t chunk_period_ns = 500'000'000;  ///< log time one chunk spans at most
  std::size_t chunk_bytes = 4u << 20;           ///< uncompressed records that close a chunk
  std::string library = "torqued";              ///< the Header's library field
};

class McapWriter {
 public:
  /// Opens `path` and writes the magic and the header. Check ok()/error().
  explicit McapWriter(const std::string& path, McapOptions opt = {});
  /// torque-dash's recording: also one schema and one channel per DDS topic.
  McapWriter(const std::string& path, const dds::DdsSettings& settings, McapOptions opt = {});
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  /// Schema and Channel records go to the data section at once (outside chunks) and again to the summary.
  void add_schema(std::uint16_t id, std::string_view name, std::string_view encoding, std::string_view data);
  void add_channel(std::uint16_t id, std::uint16_t schema_id, std::string_view topic,
                   std::string_view encoding,
                   const std::vector<std::pair<std::string, std::string>>& metadata);
  /// One Message record into the open chunk. No-op after an error.
  void write_message(std::uint16_t channel, std::uint32_t sequence, std::uint64_t log_time,
                     std::uint64_t publish_time, std::string_view data);
  /// One sample (payload: foxglove::sample_json) on its topic's channel.
  void write(const dds::AnySample& s, std::uint64_t receive_time_ns);
  /// Closes the open chunk when its first message is chunk_period_ns older than `now_ns` (log-time clock).
  void tick(std::uint64_t now_ns);
  /// Last chunk, data end, summary, footer, closing magic; closes the file. Idempotent.
  void close();

  [[nodiscard]] std::uint64_t messages() const noexcept { return messages_; }
  [[nodiscard]] std::uint64_t chunks() const noexcept { return chunk_index_.size(); }
  [[nodiscard]] std::uint64_t bytes() const noexcept { return offset_; }
  /// Thread CPU time spent closing chunks (CRC, compression, write, flush), ns.
  [[nodiscard]] std::uint64_t chunk_cpu_ns() const noexcept { return chunk_cpu_ns_; }

 private:
  struct ChannelIndex {
    std::uint16_t id;
    std::vector<std::pair<std::uint64_t, std::uint64_t>> entries;  ///< (log time, offset in the chunk)
  };
  void flush_chunk();
  void write_summary();
  ChannelIndex& index_of(std::uint16_t channel);
  void record(std::uint8_t opcode, std::string_view body);
  void put(const void* p, std::size_t n);

  std::FILE* f_ = nullptr;
  std::string error_;
  McapOptions opt_;
  ZSTD_CCtx_s* zstd_ = nullptr;
  std::uint64_t offset_ = 0, chunk_cpu_ns_ = 0;
  std::uint32_t crc_ = 0;  ///< running CRC32: the data section, then the summary section
  std::vector<std::string> schemas_, channels_;
  std::uint64_t messages_ = 0, start_ns_ = 0, end_ns_ = 0;
  std::vector<std::pair<std::uint16_t, std::uint64_t>> per_channel_;  ///< message counts
  // The open chunk: its records (uncompressed), times, and the message index per channel.
  std::string chunk_, packed_;
  std::uint64_t chunk_start_ns_ = 0, chunk_end_ns_ = 0;
  std::vector<ChannelIndex> chunk_channels_;
  std::vector<std::string> chunk_index_;  ///< ChunkIndex record bodies for the summary
  std::array<std::uint32_t, dds::kTopicCount> seq_{};
  std::string scratch_;
};

}  // namespace torqued::dash
