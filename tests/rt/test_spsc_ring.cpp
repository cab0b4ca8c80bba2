// tests/rt/test_spsc_ring.cpp: SPSC ring semantics (rt/spsc_ring.hpp).
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <deque>
#include <random>
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

/// A record of which only the first `len` bytes are written (as the fast replay's rings fill a slot in place
/// with the bytes its kind uses); the rest of the slot keeps whatever an older record left there.
struct VarRecord {
  std::uint64_t seq = 0;
  std::uint32_t len = 0;
  std::array<std::uint8_t, 52> bytes{};
};
std::uint8_t var_byte(std::uint64_t seq, std::uint32_t i) {
  return static_cast<std::uint8_t>((seq * 2654435761u) >> 7 ^ i * 31u);
}
std::uint32_t var_len(std::uint64_t seq) { return static_cast<std::uint32_t>((seq * 40503u) % 53u); }
void write_var(VarRecord* slot, std::uint64_t seq) {
  slot->seq = seq;
  slot->len = var_len(seq);
  for (std::uint32_t i = 0; i < slot->len; ++i) slot->bytes[i] = var_byte(seq, i);
}
/// 0 when r is record `seq` with its own bytes, else 1.
int var_bad(const VarRecord& r, std::uint64_t seq) {
  if (r.seq != seq || r.len != var_len(seq)) return 1;
  for (std::uint32_t i = 0; i < r.len; ++i)
    if (r.bytes[i] != var_byte(seq, i)) return 1;
  return 0;
}

TEST(SpscRing, RandomOperationsMatchAReferenceQueueAcrossManyWrapArounds) {
  // GIVEN rings of 2 to 16 slots and a reference std::deque WHEN 200 000 random operations run on each (claim
  // then publish or abandon, try_push, try_pop, front/pop_front, peek(i), full(), size()) with records
  // written in part (random lengths) THEN every answer matches the reference: a claim is refused exactly when
  // the ring holds capacity() records, a claim not published is invisible and the next claim returns the
  // same slot, every record comes out once, in order, with its own bytes, and drops counts the refused
  // pushes.
  std::mt19937_64 rng(12345);
  for (const std::size_t cap : {2u, 4u, 8u, 16u}) {
    SpscRing<VarRecord> r(cap);
    std::deque<std::uint64_t> ref;
    std::uint64_t next_seq = 1, refused = 0;
    int bad = 0;
    for (int op = 0; op < 200'000; ++op) {
      switch (rng() % 7) {
        case 0:
        case 1: {  // claim, sometimes abandoned (the next claim must return the same slot)
          VarRecord* slot = r.claim();
          if ((slot == nullptr) != (ref.size() == cap)) ++bad;
          if (slot == nullptr) break;
          if (rng() % 4 == 0 && r.claim() != slot) ++bad;
          write_var(slot, next_seq);
          if (rng() % 8 == 0) break;  // abandoned: overwritten by the next claim
          r.publish();
          ref.push_back(next_seq++);
          break;
        }
        case 2: {
          VarRecord v;
          write_var(&v, next_seq);
          const bool ok = r.try_push(v);
          if (ok != (ref.size() < cap)) ++bad;
          if (ok)
            ref.push_back(next_seq++);
          else
            ++refused;
          break;
        }
        case 3: {
          VarRecord v;
          const bool ok = r.try_pop(v);
          if (ok != !ref.empty()) ++bad;
          if (ok) {
            bad += var_bad(v, ref.front());
            ref.pop_front();
          }
          break;
        }
        case 4: {
          const VarRecord* f = r.front();
          if ((f == nullptr) != ref.empty()) ++bad;
          if (f == nullptr) break;
          bad += var_bad(*f, ref.front());
          r.pop_front();
          ref.pop_front();
          break;
        }
        case 5: {
          const std::size_t i = rng() % (cap + 1);
          const VarRecord* p = r.peek(i);
          if ((p == nullptr) != (i >= ref.size())) ++bad;
          if (p != nullptr) bad += var_bad(*p, ref[i]);
          break;
        }
        default:
          if (r.full() != (ref.size() == cap) || r.size() != ref.size()) ++bad;
          break;
      }
    }
    EXPECT_EQ(bad, 0) << "capacity " << cap;
    EXPECT_EQ(r.drops(), refused) << "capacity " << cap;
    EXPECT_GT(next_seq, 20'000u) << "capacity " << cap;  // many wrap-arounds of the index
  }
}

TEST(SpscRing, TwoThreadsClaimPublishAndFrontPopHandOverEveryPartialRecordIntact) {
  // GIVEN a ring of 4 slots, a producer that claims (waiting while full), writes a random length of the slot
  // and publishes, and a consumer that reads through front()/peek()/pop_front() and try_pop() by turns WHEN
  // 300 000 records pass (75 000 wrap-arounds, the ring full and empty often) THEN each arrives once, in
  // order, with its own bytes, and nothing is counted as a drop. (Run under TSan in the tsan tier.)
  constexpr std::uint64_t kN = 300'000;
  SpscRing<VarRecord> r(4);
  std::uint64_t bad = 0, received = 0;
  std::thread consumer([&] {
    std::uint64_t seq = 1;
    VarRecord v;
    while (seq <= kN) {
      if (seq % 3 == 0) {
        if (!r.try_pop(v)) {
          std::this_thread::yield();
          continue;
        }
        bad += static_cast<std::uint64_t>(var_bad(v, seq));
      } else {
        const VarRecord* f = r.front();
        if (f == nullptr) {
          std::this_thread::yield();
          continue;
        }
        bad += static_cast<std::uint64_t>(var_bad(*f, seq));
        if (const VarRecord* p = r.peek(1)) bad += static_cast<std::uint64_t>(var_bad(*p, seq + 1));
        r.pop_front();
      }
      ++seq;
      ++received;
    }
  });
  for (std::uint64_t seq = 1; seq <= kN; ++seq) {
    VarRecord* slot = nullptr;
    while ((slot = r.claim()) == nullptr) std::this_thread::yield();
    write_var(slot, seq);
    r.publish();
  }
  consumer.join();
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(received, kN);
  EXPECT_EQ(r.drops(), 0u);
}

}  // namespace
}  // namespace torqued
