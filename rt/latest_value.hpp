#pragma once
// Single-writer, single-reader "latest value" slot between two real-time threads (seqlock): the writer never
// waits, the reader gets the newest complete value or nothing (a torn read is retried once, then skipped).
// T must be trivially copyable; the payload is kept in relaxed atomic words so there is no data race.
#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace torqued {

template <class T>
class LatestValue {
  static_assert(std::is_trivially_copyable_v<T>);
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;

 public:
  void store(const T& v) noexcept {
    std::array<std::uint64_t, kWords> w{};
    std::memcpy(w.data(), &v, sizeof(T));
    const std::uint64_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);  // odd: writing
    std::atomic_thread_fence(std::memory_order_release);
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(w[i], std::memory_order_relaxed);
    seq_.store(s + 2, std::memory_order_release);
  }
  /// Newest value written since the last successful load(); false when none (or the writer was mid-write).
  bool load_new(T& out) noexcept {
    for (int attempt = 0; attempt < 2; ++attempt) {
      const std::uint64_t s0 = seq_.load(std::memory_order_acquire);
      if (s0 == seen_ || (s0 & 1u)) return false;
      std::array<std::uint64_t, kWords> w{};
      for (std::size_t i = 0; i < kWords; ++i) w[i] = words_[i].load(std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) != s0) continue;
      std::memcpy(static_cast<void*>(&out), w.data(), sizeof(T));
      seen_ = s0;
      return true;
    }
    return false;
  }

 private:
  std::atomic<std::uint64_t> seq_{0};
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
  std::uint64_t seen_ = 0;  ///< reader's last sequence (reader thread only)
};

}  // namespace torqued
