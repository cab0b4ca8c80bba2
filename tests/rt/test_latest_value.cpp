// tests/rt/test_latest_value.cpp: the time → angle thread slot (rt/latest_value.hpp): newest value
// once, nothing when nothing new, and no torn value under a concurrent writer (also run under TSan).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "estimate.hpp"
#include "latest_value.hpp"

namespace torqued {
namespace {

TEST(LatestValue, NewestValueOnceThenNothing) {
  LatestValue<TorqueEstimate> v;
  TorqueEstimate out{};
  EXPECT_FALSE(v.load_new(out));
  v.store(TorqueEstimate{1, 10.0, 1.0, Health::kValid});
  v.store(TorqueEstimate{2, 20.0, 2.0, Health::kStaleInput});
  ASSERT_TRUE(v.load_new(out));
  EXPECT_EQ(out.t_ns, 2);
  EXPECT_EQ(out.torque_nm, 20.0);
  EXPECT_EQ(out.health, Health::kStaleInput);
  EXPECT_FALSE(v.load_new(out));
}

TEST(LatestValue, ConcurrentWriterNeverGivesATornValue) {
  // The writer stores {i, i, i} every ~20 µs (20x the time chain's 1 kHz) until the reader has checked 200
  // values (or 5 s passed): every value the reader gets must be consistent, and newer than the one before.
  LatestValue<TorqueEstimate> v;
  std::atomic<bool> stop{false};
  std::thread w([&] {
    for (int i = 1; !stop.load(std::memory_order_relaxed); ++i) {
      v.store(TorqueEstimate{i, double(i), double(i), Health::kValid});
      std::this_thread::sleep_for(std::chrono::microseconds(20));
    }
  });
  int got = 0;
  std::int64_t last = 0;
  TorqueEstimate out{};
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (got < 200 && std::chrono::steady_clock::now() < until) {
    if (!v.load_new(out)) continue;
    ++got;
    EXPECT_EQ(static_cast<double>(out.t_ns), out.torque_nm);
    EXPECT_EQ(out.torque_nm, out.uncertainty);
    EXPECT_GT(out.t_ns, last);
    last = out.t_ns;
  }
  stop = true;
  w.join();
  EXPECT_EQ(got, 200);
}

}  // namespace
}  // namespace torqued
