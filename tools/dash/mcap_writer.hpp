#pragma once
// MCAP recording of the torque topics (https://mcap.dev/spec, major version 0): one schema (JSON Schema,
// foxglove.hpp) and one channel (message encoding "json") per topic, one Message record per sample,
// unchunked, with a summary section (schemas, channels, statistics) and summary offsets, so Foxglove and the
// MCAP readers open it. Messages are written in arrival order; log_time = receive time (CLOCK_REALTIME ns),
// publish_time = the sample's publish_t_ns (its source_t_ns when 0: fast replay). CRCs are written as 0
// ("not available" in the spec). The footer is written by close()/the destructor: a recording cut by kill -9
// is readable record by record up to its last complete record but has no summary or footer.
// Not real-time code (the subscriber's own thread); buffered stdio.
#include <array>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

#include "qos.hpp"
#include "sample.hpp"

namespace torqued::dash {

class McapWriter {
 public:
  /// Opens `path` and writes the magic, header, schemas and channels. Check ok()/error().
  McapWriter(const std::string& path, const dds::DdsSettings& settings);
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  /// One sample as a Message record (payload: foxglove::sample_json). No-op after an error.
  void write(const dds::AnySample& s, std::uint64_t receive_time_ns);
  /// Data end, summary, footer, closing magic; closes the file. Idempotent.
  void close();
  [[nodiscard]] std::uint64_t messages() const noexcept { return messages_; }

 private:
  void record(std::uint8_t opcode, const std::string& body);
  void put(const void* p, std::size_t n);
  std::string schema_record(int i) const;
  std::string channel_record(int i) const;
  std::string statistics_record() const;
  std::FILE* f_ = nullptr;
  std::string error_;
  dds::DdsSettings settings_;
  std::uint64_t offset_ = 0;
  std::uint64_t messages_ = 0, start_ns_ = 0, end_ns_ = 0;
  std::array<std::uint64_t, dds::kTopicCount> per_channel_{};
  std::array<std::uint32_t, dds::kTopicCount> seq_{};
  std::string scratch_;
};

}  // namespace torqued::dash
