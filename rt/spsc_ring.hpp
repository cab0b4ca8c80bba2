#pragma once
// Fixed-capacity single-producer/single-consumer lock-free ring (after rigtorp/SPSCQueue,
// github.com/rigtorp/SPSCQueue). Why our own and not moodycamel/Boost: a full ring must drop the NEWEST
// record and count it, never allocate and never block; the benchmark tests/rt/bench_ring.cpp compares it with
// both libraries.
//
// Layout: the producer writes tail_, the consumer writes head_; each index sits on its own cache line with
// a cached copy of the other side's index, so in the steady state a push or pop touches only one shared
// cache line (the slot) and re-reads the other index only when the ring looks full/empty.
// Memory ordering: the producer stores the slot then publishes tail_ with release; the consumer acquires
// tail_ before reading the slot (and symmetrically for head_), so a popped record is always complete.
// All functions below are real-time safe (no allocation, no lock, no system call) except the constructor.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>

namespace torqued {

inline constexpr std::size_t kCacheLine = 64;

template <class T>
class SpscRing {
  static_assert(std::is_trivially_copyable_v<T>, "ring records are fixed-size, trivially copyable");

 public:
  /// capacity is rounded up to a power of two (>= 2). Allocates here, never afterwards.
  explicit SpscRing(std::size_t capacity) : mask_(round_up(capacity) - 1), slots_(new T[mask_ + 1]) {
    // Touch every slot now so the pages are resident (prefault) before real-time threads use them.
    for (std::size_t i = 0; i <= mask_; ++i) slots_[i] = T{};
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  /// Producer side. Returns false (and counts a drop) when full; the record is dropped (drop-newest policy).
  [[nodiscard]] bool try_push(const T& v) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail - head_cache_ > mask_) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (tail - head_cache_ > mask_) {
        drops_.store(drops_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
        return false;
      }
    }
    slots_[tail & mask_] = v;
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  /// Producer side: true when a try_push now would be refused (re-reads the consumer's index first). For a
  /// producer that may wait (back-pressure, service/sink_thread.hpp) instead of dropping.
  [[nodiscard]] bool full() noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail - head_cache_ <= mask_) return false;
    head_cache_ = head_.load(std::memory_order_acquire);
    return tail - head_cache_ > mask_;
  }

  /// Producer side, in two steps: the slot the next push would fill (nullptr when full), to be written in
  /// place (only the bytes the record uses: fewer cache lines cross to the consumer's core), then publish()
  /// it.
  [[nodiscard]] T* claim() noexcept {
    return full() ? nullptr : &slots_[tail_.load(std::memory_order_relaxed) & mask_];
  }
  void publish() noexcept {
    tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }

  /// Consumer side. Returns false when empty.
  [[nodiscard]] bool try_pop(T& out) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head == tail_cache_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head == tail_cache_) return false;
    }
    out = slots_[head & mask_];
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  /// Consumer side: pointer to the oldest record without removing it (nullptr when empty).
  [[nodiscard]] const T* front() noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head == tail_cache_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head == tail_cache_) return nullptr;
    }
    return &slots_[head & mask_];
  }
  /// Consumer side: pointer to the i-th oldest record (0 = front()), nullptr when fewer are queued.
  [[nodiscard]] const T* peek(std::size_t i) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (tail_cache_ - head <= i) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (tail_cache_ - head <= i) return nullptr;
    }
    return &slots_[(head + i) & mask_];
  }
  /// Consumer side: removes the record returned by front().
  void pop_front() noexcept {
    head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }

  /// Records currently queued (approximate when called from a third thread).
  [[nodiscard]] std::size_t size() const noexcept {
    return tail_.load(std::memory_order_acquire) - head_.load(std::memory_order_acquire);
  }
  [[nodiscard]] bool empty() const noexcept { return size() == 0; }
  [[nodiscard]] std::size_t capacity() const noexcept { return mask_ + 1; }
  /// Records dropped because the ring was full (readable from any thread).
  [[nodiscard]] std::uint64_t drops() const noexcept { return drops_.load(std::memory_order_relaxed); }

 private:
  static std::size_t round_up(std::size_t n) noexcept {
    std::size_t c = 2;
    while (c < n) c <<= 1;
    return c;
  }

  const std::size_t mask_;
  const std::unique_ptr<T[]> slots_;
  alignas(kCacheLine) std::atomic<std::size_t> tail_{0};  ///< written by the producer
  std::size_t head_cache_ = 0;                            ///< producer's copy of head_
  std::atomic<std::uint64_t> drops_{0};                   ///< written by the producer only
  alignas(kCacheLine) std::atomic<std::size_t> head_{0};  ///< written by the consumer
  std::size_t tail_cache_ = 0;                            ///< consumer's copy of tail_
  char pad_[kCacheLine - sizeof(std::size_t) * 2];
};

}  // namespace torqued
