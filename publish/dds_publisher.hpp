#pragma once
// The only code of the daemon that calls DDS (docs/architecture.md: the real-time threads never wait for
// DDS). Owns the participant, the five topics and their writers, QoS from dds::DdsSettings (idl/qos.hpp,
// filled from the Config). Used by the publisher thread (paced/live) or inline by the fast replay.
#include <array>
#include <cstdint>
#include <string>

#include "dds/dds.h"
#include "qos.hpp"
#include "sample.hpp"

namespace torqued {

class DdsPublisher {
 public:
  /// Creates participant, topics, writers. Check ok()/error(). stamp_times: set publish_t_ns (CLOCK_REALTIME)
  /// on each write; off in fast replay so that recorded output is byte-identical across runs.
  DdsPublisher(const dds::DdsSettings& settings, bool stamp_times);
  ~DdsPublisher();
  DdsPublisher(const DdsPublisher&) = delete;
  DdsPublisher& operator=(const DdsPublisher&) = delete;

  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  /// Stamps engine_id and publish_t_ns, then dds_write. Returns false (counted) on a DDS error.
  bool write(dds::AnySample& s) noexcept;
  [[nodiscard]] std::uint64_t written() const noexcept { return written_; }
  [[nodiscard]] std::uint64_t write_errors() const noexcept { return write_errors_; }
  /// Samples written through a loan of iceoryx shared memory (same host: no serialisation, no socket).
  [[nodiscard]] std::uint64_t loaned_writes() const noexcept { return loaned_; }
  /// Topics whose writer delivers through shared memory, e.g. "EngineTorque CrankState" ("" when none):
  /// Cyclone's SharedMemory enabled, RouDi running, QoS eligible (volatile, keep-last, no deadline).
  [[nodiscard]] std::string shared_memory_topics() const;
  /// Number of matched readers of a topic (for tests and the startup log).
  [[nodiscard]] int matched_readers(dds::Topic t) const noexcept;

  [[nodiscard]] static std::int64_t realtime_ns() noexcept;

 private:
  dds::DdsSettings settings_;
  bool stamp_times_;
  dds_entity_t participant_ = 0;
  std::array<dds_entity_t, dds::kTopicCount> writers_{};
  std::array<bool, dds::kTopicCount> shm_{}, loan_{};  ///< through shared memory / lends samples
  std::string error_;
  std::uint64_t written_ = 0, write_errors_ = 0, loaned_ = 0;
};

}  // namespace torqued
