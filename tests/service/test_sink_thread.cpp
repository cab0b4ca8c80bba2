// tests/service/test_sink_thread.cpp: service/sink_thread.hpp, the fast replay's recording thread. The inner
// sink must receive every sample once, in the order emitted, from one thread, with flush() after the last
// one; a full ring makes the producer wait (counted), never drop. Also run whole under ThreadSanitizer (label
// tsan).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#include "sink_thread.hpp"

namespace torqued {
namespace {

dds::AnySample numbered(std::uint64_t i) {
  dds::AnySample s;
  s.topic = dds::Topic::kEstimatorTorque;
  s.u.estimator.source_t_ns = static_cast<std::int64_t>(i);
  return s;
}

/// Keeps the order of what it receives and the thread it runs on; sleeps now and then (a slow disk).
class SlowSink final : public SampleSink {
 public:
  void emit(const dds::AnySample& s) noexcept override {
    seen_.push_back(s.u.estimator.source_t_ns);
    if (flushed_) emits_after_flush_ = true;
    threads_.push_back(std::this_thread::get_id());
    if (seen_.size() % 5000 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  void flush() noexcept override { flushed_ = true; }
  std::vector<std::int64_t> seen_;
  std::vector<std::thread::id> threads_;
  bool flushed_ = false;
  bool emits_after_flush_ = false;
};

TEST(SinkThread, EverySampleArrivesOnceInOrderAndAFullRingWaitsInsteadOfDropping) {
  // GIVEN a slow inner sink behind a 64-sample ring
  SlowSink inner;
  constexpr std::uint64_t kN = 40'000;
  std::uint64_t waits = 0, drops = 0, written = 0;
  {
    SinkThread t(inner, 64);
    // WHEN 40 000 numbered samples are emitted as fast as possible, then flushed
    for (std::uint64_t i = 0; i < kN; ++i) t.emit(numbered(i));
    EXPECT_FALSE(inner.flushed_);
    t.flush();
    waits = t.waits();
    drops = t.drops();
    written = t.written();
    // THEN the inner sink was flushed once everything reached it; later samples go to it directly
    ASSERT_TRUE(inner.flushed_);
    EXPECT_FALSE(inner.emits_after_flush_);
    t.emit(numbered(kN));
  }
  ASSERT_EQ(inner.seen_.size(), kN + 1);
  for (std::uint64_t i = 0; i <= kN; ++i) ASSERT_EQ(inner.seen_[i], static_cast<std::int64_t>(i)) << i;
  EXPECT_EQ(written, kN);
  EXPECT_EQ(drops, 0U);
  EXPECT_GT(waits, 0U);  // the ring filled while the inner sink slept: the producer waited
  // ... and every sample before flush() was handed on by one thread, not the producer's
  for (std::uint64_t i = 1; i < kN; ++i) ASSERT_EQ(inner.threads_[i], inner.threads_[0]);
  EXPECT_NE(inner.threads_[0], std::this_thread::get_id());
  EXPECT_EQ(inner.threads_[kN], std::this_thread::get_id());
}

TEST(SinkThread, DestructorWithoutFlushStillDeliversEverything) {
  SlowSink inner;
  {
    SinkThread t(inner, 8);
    for (std::uint64_t i = 0; i < 1000; ++i) t.emit(numbered(i));
  }
  ASSERT_EQ(inner.seen_.size(), 1000U);
  EXPECT_EQ(inner.seen_.back(), 999);
  EXPECT_TRUE(inner.flushed_);
}

}  // namespace
}  // namespace torqued
