#pragma once
// The fast replay's input on a thread of its own: a ReplayMerger (io/replay_merger.hpp) runs there, reading
// and parsing both input files and merging them by time, and hands its results through an SPSC ring
// (rt/spsc_ring.hpp) to the replay, which takes them with next() as it would from the merger (≈ 14 % of the
// replay's instructions move to the second core). Each record carries what the replay reads besides the item:
// the merger's status, its CAN frame count and the sources' bad lines and drops as they stood right after
// that merger.next(), so DaemonStatus counts are those of the one-thread replay (determinism: same bytes).
//
// Back-pressure, never a drop: the reader sleeps while the ring is full (rest(), back_off.hpp) until half of
// it is free, the replay waits (back_off()) while it is empty (counted in waits()); drops() counts records
// the ring refused after that wait and stays 0. Only the reader thread touches the sources until stop() (or
// the end), which joins it: read their stats and errors after that.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include "replay_merger.hpp"
#include "source.hpp"
#include "spsc_ring.hpp"

namespace torqued {

/// What a replay reports when a source fails: the edge source's last error, else the CAN source's ("" when
/// the message could not be copied). Both replays (one thread, read-ahead) take it at the first kError.
std::string source_error_message(const EdgeSource* edges, const CanSource* can) noexcept;

class ReadAheadMerger {
 public:
  static constexpr std::size_t kDefaultCapacity =
      16384;  ///< records (2.5 MB of 192 bytes, ≈ 2.6 ms of replay)

  /// Starts the reader thread (allocates the ring here, never afterwards). Sources must outlive this.
  ReadAheadMerger(EdgeSource* edges, CanSource* can, std::int64_t can_offset_ns,
                  std::size_t capacity = kDefaultCapacity);
  ~ReadAheadMerger();  ///< stop()
  ReadAheadMerger(const ReadAheadMerger&) = delete;
  ReadAheadMerger& operator=(const ReadAheadMerger&) = delete;

  /// Consumer (one thread): as ReplayMerger::next; waits while the reader is behind. kEnd after the last.
  [[nodiscard]] SourceStatus next(ReplayMerger::Item& out) noexcept;
  /// Ends the reader (at once if the replay stops early) and joins it. Idempotent.
  void stop() noexcept;

  /// As of the last record next() returned.
  [[nodiscard]] std::uint64_t frames_out() const noexcept { return frames_out_; }
  [[nodiscard]] std::uint64_t source_drops() const noexcept { return source_drops_; }
  /// After stop(): the message of the first source error ("" = none), as the one-thread replay took it.
  [[nodiscard]] const std::string& first_error() const noexcept { return first_error_; }
  [[nodiscard]] std::uint64_t waits() const noexcept { return waits_; }
  [[nodiscard]] std::uint64_t drops() const noexcept { return ring_.drops(); }

 private:
  /// An edge record uses its first 48 bytes only (one cache line to carry to the replay's core when the slot
  /// is line-aligned); a CAN frame's follows.
  struct alignas(64) Record {
    SourceStatus status = SourceStatus::kEnd;
    ReplayMerger::Kind kind = ReplayMerger::Kind::kEdge;
    std::uint64_t frames_out = 0;    ///< merger.frames_out() after this next()
    std::uint64_t source_drops = 0;  ///< bad lines + drops of both sources after this next()
    EdgeEvent edge;                  ///< kind == kEdge
    CanFrame frame;                  ///< kind == kCan
  };
  void run() noexcept;  ///< the reader thread

  EdgeSource* edges_;
  CanSource* can_;
  ReplayMerger merger_;
  SpscRing<Record> ring_;
  std::atomic<bool> quit_{false};  ///< set by stop(): the reader ends without reading further
  std::string first_error_;        ///< reader thread until joined
  std::uint64_t frames_out_ = 0, source_drops_ = 0, waits_ = 0;  ///< consumer only
  bool ended_ = false;                                           ///< consumer only: kEnd seen
  bool joined_ = false;                                          ///< consumer only
  std::thread thread_;
};

}  // namespace torqued
