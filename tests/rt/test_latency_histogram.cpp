// tests/rt/test_latency_histogram.cpp: latency percentiles of the publisher
// (rt/latency_histogram.hpp): period and whole-run figures, and no cap at the histogram's 10 ms range.
#include <gtest/gtest.h>

#include "latency_histogram.hpp"

namespace torqued {
namespace {

TEST(LatencyHistogram, PercentilesOfAPeriodThenANewPeriod) {
  LatencyHistogram h;
  for (int i = 1; i <= 100; ++i) h.note(i * 1000);  // 1..100 µs
  LatencyFigures f = h.take_period();
  EXPECT_EQ(f.n, 100u);
  EXPECT_EQ(f.p50_ns, 50'000);
  EXPECT_EQ(f.p99_ns, 99'000);
  EXPECT_EQ(f.max_ns, 100'000);
  h.note(7'000);
  f = h.take_period();
  EXPECT_EQ(f.n, 1u);
  EXPECT_EQ(f.p50_ns, 7'000);
  EXPECT_EQ(h.run().n, 101u);  // the run keeps everything
  EXPECT_EQ(h.run().max_ns, 100'000);
}

TEST(LatencyHistogram, LatenciesBeyondTheRangeAreNotCapped) {
  // GIVEN most samples at 1.1 s (a daemon far behind) WHEN the percentiles are taken THEN p50 reports the
  // exact maximum (an upper bound), not the 10 ms edge of the histogram.
  LatencyHistogram h;
  for (int i = 0; i < 10; ++i) h.note(33'000);
  for (int i = 0; i < 90; ++i) h.note(1'100'000'000);
  const LatencyFigures f = h.take_period();
  EXPECT_EQ(f.p50_ns, 1'100'000'000);
  EXPECT_EQ(f.p99_ns, 1'100'000'000);
}

TEST(LatencyHistogram, EmptyPeriodHasNoPercentiles) {
  LatencyHistogram h;
  const LatencyFigures f = h.take_period();
  EXPECT_EQ(f.n, 0u);
  EXPECT_EQ(f.p50_ns, -1);
}

}  // namespace
}  // namespace torqued
