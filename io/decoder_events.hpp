#pragma once
// Sync-state transitions of the crank decoder, for a debug log: the decoder (real-time thread)
// pushes one DecoderEvent per transition into a fixed single-producer/single-consumer ring; another thread
// (the daemon's supervisor, torque-decode) pops them and logs them at debug level. Pushing never allocates,
// locks or blocks: a full ring drops the newest event and counts it (dropped()).
#include <array>
#include <atomic>
#include <cstdint>

#include "records.hpp"

namespace torqued {

enum class SyncLossReason : std::uint8_t;

/// What happened (the new state is in DecoderEvent::to).
enum class DecoderEventKind : std::uint8_t {
  kFirstEdge,  ///< no_signal -> syncing
  kSynced,     ///< syncing/lost/stalled -> synced (tooth = the index found)
  kLost,       ///< synced -> lost_sync (reason)
  kStalled,    ///< no edge for stall_timeout -> stalled
  kCamPhase,   ///< cam contradicted the decoded phase (counted in cam_phase_errors; phase re-set)
};

struct DecoderEvent {
  std::int64_t t_ns = 0;  ///< edge time of the transition (the edge that caused it; poll time for a stall)
  DecoderEventKind kind = DecoderEventKind::kFirstEdge;
  SyncState from = SyncState::kNoSignal, to = SyncState::kNoSignal;
  std::uint8_t reason = 0;  ///< SyncLossReason for kLost
  std::int16_t tooth = -1;  ///< tooth index (0..2T-1) for kSynced, else -1
};

[[nodiscard]] const char* to_string(DecoderEventKind k) noexcept;

class DecoderEventLog {
 public:
  static constexpr std::uint32_t kCapacity = 64;

  /// Producer (the decoder's thread). False (and counted) when full.
  bool push(const DecoderEvent& e) noexcept {
    const std::uint32_t tail = tail_.load(std::memory_order_relaxed);
    if (tail - head_.load(std::memory_order_acquire) >= kCapacity) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    slots_[tail % kCapacity] = e;
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }
  /// Consumer (one other thread). False when empty.
  bool pop(DecoderEvent& out) noexcept {
    const std::uint32_t head = head_.load(std::memory_order_relaxed);
    if (head == tail_.load(std::memory_order_acquire)) return false;
    out = slots_[head % kCapacity];
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  std::array<DecoderEvent, kCapacity> slots_{};
  alignas(64) std::atomic<std::uint32_t> tail_{0};
  alignas(64) std::atomic<std::uint32_t> head_{0};
  std::atomic<std::uint64_t> dropped_{0};
};

}  // namespace torqued
