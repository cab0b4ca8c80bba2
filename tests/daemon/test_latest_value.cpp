// tests/daemon/test_latest_value.cpp: the time → angle thread slot (daemon/latest_value.hpp): newest value once,
// nothing when nothing new, and no torn value under a concurrent writer (also run under TSan).
#include "latest_value.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "estimate.hpp"

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
  // The writer stores {i, i, i}; every value the reader gets must be consistent.
  LatestValue<TorqueEstimate> v;
  std::atomic<bool> done{false};
  std::thread w([&] {
    for (int i = 1; i <= 200000; ++i) v.store(TorqueEstimate{i, double(i), double(i), Health::kValid});
    done = true;
  });
  int got = 0;
  TorqueEstimate out{};
  while (!done.load()) {
    if (v.load_new(out)) {
      ++got;
      ASSERT_EQ(static_cast<double>(out.t_ns), out.torque_nm);
      ASSERT_EQ(out.torque_nm, out.uncertainty);
    }
  }
  w.join();
  EXPECT_GT(got, 0);
}

}  // namespace
}  // namespace torqued
