// tests/rt/test_spsc_ring.cpp: SPSC ring semantics (rt/spsc_ring.hpp).
#include <gtest/gtest.h>

#include <cstdint>
#include <thread>

#include "alloc_counter.hpp"
#include "spsc_ring.hpp"

namespace torqued {
namespace {

TEST(SpscRing, RoundsCapacityToPowerOfTwo) {
  SpscRing<int> r(5);
  EXPECT_EQ(r.capacity(), 8u);
}

TEST(SpscRing, FifoOrderAndEmpty) {
  SpscRing<int> r(4);
  int v = -1;
  EXPECT_FALSE(r.try_pop(v));
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(r.try_push(i));
  EXPECT_EQ(r.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(r.try_pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(r.try_pop(v));
  EXPECT_TRUE(r.empty());
}

TEST(SpscRing, FullDropsNewestAndCounts) {
  // GIVEN a ring of 4 filled to capacity WHEN two more are pushed THEN both are dropped and counted and the
  // four oldest come out unchanged.
  SpscRing<int> r(4);
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(r.try_push(i));
  EXPECT_FALSE(r.try_push(100));
  EXPECT_FALSE(r.try_push(101));
  EXPECT_EQ(r.drops(), 2u);
  int v = -1;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(r.try_pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_TRUE(r.try_push(7));  // space again after pops
  ASSERT_TRUE(r.try_pop(v));
  EXPECT_EQ(v, 7);
}

TEST(SpscRing, ClaimAndPublishFillInPlaceAndAFullRingClaimsNothing) {
  // GIVEN a ring of 4 WHEN four slots are claimed, written and published THEN full() holds, a fifth claim
  // gives nullptr without counting a drop, and the four come out in order; after a pop a claim succeeds.
  SpscRing<int> r(4);
  for (int i = 0; i < 4; ++i) {
    EXPECT_FALSE(r.full());
    int* slot = r.claim();
    ASSERT_NE(slot, nullptr);
    *slot = 10 + i;
    r.publish();
  }
  EXPECT_TRUE(r.full());
  EXPECT_EQ(r.claim(), nullptr);
  EXPECT_EQ(r.drops(), 0u);
  int v = -1;
  ASSERT_TRUE(r.try_pop(v));
  EXPECT_EQ(v, 10);
  EXPECT_FALSE(r.full());
  ASSERT_NE(r.claim(), nullptr);
  for (int i = 1; i < 4; ++i) {
    ASSERT_TRUE(r.try_pop(v));
    EXPECT_EQ(v, 10 + i);
  }
  EXPECT_FALSE(r.try_pop(v));  // the claimed slot was never published
}

TEST(SpscRing, FrontAndPopFront) {
  SpscRing<int> r(2);
  EXPECT_EQ(r.front(), nullptr);
  ASSERT_TRUE(r.try_push(42));
  ASSERT_NE(r.front(), nullptr);
  EXPECT_EQ(*r.front(), 42);
  r.pop_front();
  EXPECT_EQ(r.front(), nullptr);
}

TEST(SpscRing, PeekReadsQueuedRecordsInOrderWithoutRemovingThem) {
  SpscRing<int> r(4);
  EXPECT_EQ(r.peek(0), nullptr);
  for (int v : {1, 2, 3}) ASSERT_TRUE(r.try_push(v));
  ASSERT_NE(r.peek(2), nullptr);
  EXPECT_EQ(*r.peek(0), 1);
  EXPECT_EQ(*r.peek(2), 3);
  EXPECT_EQ(r.peek(3), nullptr);
  r.pop_front();
  EXPECT_EQ(*r.peek(0), 2);
  EXPECT_EQ(*r.peek(1), 3);
  EXPECT_EQ(r.peek(2), nullptr);
  ASSERT_TRUE(r.try_push(4));
  ASSERT_TRUE(r.try_push(5));  // wraps around the 4 slots
  EXPECT_EQ(*r.peek(3), 5);
  EXPECT_EQ(r.size(), 4u);
}

TEST(SpscRing, PushPopDoNotAllocate) {
  SpscRing<std::uint64_t> r(64);
  torqued::test::AllocationScope scope;
  std::uint64_t v = 0;
  for (std::uint64_t i = 0; i < 10000; ++i) {
    (void)r.try_push(i);
    (void)r.try_pop(v);
  }
  EXPECT_EQ(scope.count(), 0u);
}

TEST(SpscRing, TwoThreadsEveryRecordInOrderOrCountedAsDrop) {
  // GIVEN a small ring and a producer faster than the consumer WHEN a million records pass THEN every record
  // arrives exactly once in increasing order or is counted as a drop: received + drops == sent.
  constexpr std::uint64_t kN = 1'000'000;
  SpscRing<std::uint64_t> r(256);
  std::uint64_t received = 0, last = 0, sum_ok = 1;
  std::atomic<bool> done{false};
  std::thread consumer([&] {
    std::uint64_t v = 0;
    for (;;) {
      if (r.try_pop(v)) {
        if (received > 0 && v <= last) sum_ok = 0;
        last = v;
        ++received;
      } else if (done.load(std::memory_order_acquire)) {
        while (r.try_pop(v)) {
          if (v <= last) sum_ok = 0;
          last = v;
          ++received;
        }
        break;
      }
    }
  });
  for (std::uint64_t i = 1; i <= kN; ++i) (void)r.try_push(i);
  done.store(true, std::memory_order_release);
  consumer.join();
  EXPECT_EQ(sum_ok, 1u) << "records out of order";
  EXPECT_EQ(received + r.drops(), kN);
  EXPECT_GT(received, 0u);
}

}  // namespace
}  // namespace torqued
