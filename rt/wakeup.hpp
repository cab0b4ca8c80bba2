#pragma once
// Lets producers (real-time threads) wake the publisher thread without ever blocking themselves.
// Producer: push into its ring, then notify(): one seq_cst fence and a load; only when the consumer is
// actually asleep one futex(FUTEX_WAKE) system call (non-blocking). Consumer: wait_for() sleeps on the futex
// with a time-out. The sleeping_ flag + fences form a Dekker pair so a wake-up cannot be lost: either the
// producer sees sleeping_ == 1 or the consumer's re-check sees the record.
#include <linux/futex.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>

namespace torqued {

class Wakeup {
 public:
  /// Producer side; real-time safe.
  void notify() noexcept {
    std::atomic_thread_fence(std::memory_order_seq_cst);
    if (sleeping_.load(std::memory_order_relaxed) != 0) {
      word_.fetch_add(1, std::memory_order_release);
      syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word_), FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr,
              0);
    }
  }

  /// Consumer side: sleeps up to timeout_ns unless has_work() (checked after announcing the sleep) is true.
  template <class HasWork>
  void wait_for(std::int64_t timeout_ns, HasWork&& has_work) noexcept {
    const std::uint32_t w = word_.load(std::memory_order_acquire);
    sleeping_.store(1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_seq_cst);
    if (!has_work()) {
      timespec ts{static_cast<time_t>(timeout_ns / 1'000'000'000),
                  static_cast<long>(timeout_ns % 1'000'000'000)};
      syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word_), FUTEX_WAIT_PRIVATE, w, &ts, nullptr, 0);
    }
    sleeping_.store(0, std::memory_order_relaxed);
  }

 private:
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t));
  alignas(64) std::atomic<std::uint32_t> word_{0};
  std::atomic<std::uint32_t> sleeping_{0};
};

}  // namespace torqued
