#pragma once
// A SampleSink that hands every sample to another sink on a thread of its own, through an SPSC ring
// (rt/spsc_ring.hpp), in the order emitted: the fast replay's recording (the CSV formatting and the file
// writes, ≈ 12 % of its instructions and all of its write(2) calls) runs on the second core beside the chain.
// Only the writer thread calls the inner sink between start and flush(), so the recorder and a publisher keep
// one caller.
//
// Back-pressure, never a drop: a full ring makes emit() wait until the writer has made room (spinning
// long, then yielding, then sleeping: back_off.hpp; counted in waits()); the sample is then pushed.
// drops() counts samples the ring refused after that wait: it stays 0 (one producer; the test checks it).
// This is for the fast replay, which may wait; the real-time threads of the paced runtime use try_push and
// count drops instead. Real-time notes: emit() does not allocate, lock or throw; it may wait (above) and then
// yields or sleeps.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <thread>

#include "sample.hpp"
#include "sample_sink.hpp"
#include "spsc_ring.hpp"

namespace torqued {

class SinkThread final : public SampleSink {
 public:
  static constexpr std::size_t kDefaultCapacity = 16384;  ///< samples (4.3 MB of 272-byte samples)

  /// Starts the writer thread (allocates the ring here, never afterwards).
  explicit SinkThread(SampleSink& inner, std::size_t capacity = kDefaultCapacity);
  ~SinkThread() override;  ///< flush() if not done yet
  SinkThread(const SinkThread&) = delete;
  SinkThread& operator=(const SinkThread&) = delete;

  /// Producer (one thread): queues the sample; waits while the ring is full.
  void emit(const dds::AnySample& s) noexcept override;
  /// Waits until the writer has handed every queued sample to the inner sink, ends the writer thread, then
  /// flushes the inner sink on the caller's thread. Samples emitted afterwards go to the inner sink directly.
  void flush() noexcept override;

  [[nodiscard]] std::uint64_t waits() const noexcept { return waits_; }  ///< emits that found the ring full
  [[nodiscard]] std::uint64_t drops() const noexcept { return ring_.drops(); }  ///< 0: never drops
  [[nodiscard]] std::uint64_t written()
      const noexcept {  ///< samples the writer handed on (after flush(): all)
    return written_.load(std::memory_order_acquire);
  }

 private:
  void run() noexcept;  ///< the writer thread

  SampleSink& inner_;
  SpscRing<dds::AnySample> ring_;
  std::atomic<bool> done_{false};          ///< set by flush(): the producer will push no more
  std::atomic<std::uint64_t> written_{0};  ///< written by the writer thread only
  std::uint64_t waits_ = 0;                ///< producer only
  bool joined_ = false;                    ///< producer only
  std::thread thread_;
};

}  // namespace torqued
