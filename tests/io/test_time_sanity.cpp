// Time sanity of the file sources (io/time_sanity.hpp): one record far outside the recent time base (a
// flipped digit) is dropped and named file:line instead of becoming "now"; a genuine clock jump (a run of
// records in step after it) is adopted without loss; a record behind the base is dropped.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "candump_source.hpp"
#include "edge_file_source.hpp"
#include "io_test_util.hpp"
#include "synthetic_edge_csv.hpp"
#include "time_sanity.hpp"

namespace torqued {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kS = 1'000'000'000;

std::vector<EdgeEvent> read_all(EdgeSource& src) {
  std::vector<EdgeEvent> v;
  EdgeEvent e;
  while (src.next(e) == SourceStatus::kOk) v.push_back(e);
  return v;
}

/// Feeds times (ns) in order with line = index + 1; returns the accepted ones and the dropped lines.
struct Fed {
  std::vector<std::int64_t> kept;
  std::vector<std::uint64_t> dropped_lines;
};
Fed feed(const std::vector<std::int64_t>& times, TimeSanityOptions o = {}) {
  TimeSanity<std::int64_t> f(o);
  Fed r;
  auto drain = [&] {
    std::int64_t v = 0;
    while (f.pop(v)) r.kept.push_back(v);
    f.drain_drops([&](const TimeDrop& d) { r.dropped_lines.push_back(d.line); });
  };
  for (std::size_t i = 0; i < times.size(); ++i) {
    f.push(times[i], times[i], i + 1);
    drain();
  }
  f.finish();
  drain();
  return r;
}

std::vector<std::int64_t> steady(std::int64_t from, int n, std::int64_t step = kMs) {
  std::vector<std::int64_t> v;
  for (int i = 0; i < n; ++i) v.push_back(from + i * step);
  return v;
}

TEST(TimeSanity, OneRecordFarAheadIsDroppedNotAdopted) {
  auto t = steady(0, 40);
  t[20] = 100'000 * kS;  // the flipped digit
  const Fed r = feed(t);
  EXPECT_EQ(r.kept.size(), 39u);
  EXPECT_EQ(r.dropped_lines, std::vector<std::uint64_t>{21});
  for (std::size_t i = 1; i < r.kept.size(); ++i) EXPECT_LT(r.kept[i], 100 * kMs);
}

TEST(TimeSanity, AnOutlierMoreThanInt64MaxAheadIsDroppedNotTakenAsNow) {
  // GIVEN records at -5e18 ns (a negative time the parsers accept) and one corrupt record at +5e18 ns: more
  // than INT64_MAX apart, where a signed difference overflows (and wrapped to a small negative "within the
  // jump")
  auto t = steady(-5'000'000'000 * kS, 8);
  t.push_back(5'000'000'000 * kS);
  t.push_back(-5'000'000'000 * kS + 9 * kMs);
  const Fed r = feed(t);
  // THEN the corrupt record is the one dropped, and the good record after it is kept
  EXPECT_EQ(r.dropped_lines, std::vector<std::uint64_t>{9});
  ASSERT_EQ(r.kept.size(), 9u);
  EXPECT_EQ(r.kept.back(), -5'000'000'000 * kS + 9 * kMs);
}

TEST(TimeSanity, GenuineClockJumpIsAdoptedAfterEnoughRecordsInStep) {
  auto t = steady(0, 20);
  const auto after = steady(3600 * kS, 20);  // a capture resumed an hour later
  t.insert(t.end(), after.begin(), after.end());
  TimeSanity<std::int64_t> f;
  std::vector<std::int64_t> kept;
  for (std::size_t i = 0; i < t.size(); ++i) {
    f.push(t[i], t[i], i + 1);
    for (std::int64_t v = 0; f.pop(v);) kept.push_back(v);
  }
  f.finish();
  for (std::int64_t v = 0; f.pop(v);) kept.push_back(v);
  EXPECT_EQ(kept, t);  // nothing lost, order kept
  EXPECT_EQ(f.rebases(), 1u);
  EXPECT_EQ(f.outliers() + f.backwards(), 0u);
}

TEST(TimeSanity, ShortRunAfterAJumpAtTheEndIsDropped) {
  auto t = steady(0, 20);
  t.push_back(500 * kS);
  t.push_back(500 * kS + kMs);  // two records in step: fewer than the 8 a re-base needs
  const Fed r = feed(t);
  EXPECT_EQ(r.kept.size(), 20u);
  EXPECT_EQ(r.dropped_lines, (std::vector<std::uint64_t>{21, 22}));
}

TEST(TimeSanity, RecordBehindTheBaseIsDropped) {
  auto t = steady(0, 20, 10 * kMs);
  t[10] = 2 * kMs;  // a digit flipped the other way
  const Fed r = feed(t);
  EXPECT_EQ(r.kept.size(), 19u);
  EXPECT_EQ(r.dropped_lines, std::vector<std::uint64_t>{11});
}

TEST(TimeSanity, CorruptFirstRecordIsDroppedToo) {
  auto t = steady(0, 20);
  t[0] = 100'000 * kS;
  const Fed r = feed(t);
  EXPECT_EQ(r.kept.size(), 19u);
  EXPECT_EQ(r.dropped_lines, std::vector<std::uint64_t>{1});
  const Fed r2 = feed({5 * kMs, 6 * kMs});  // an input shorter than a run is taken as it is
  EXPECT_EQ(r2.kept.size(), 2u);
}

TEST(TimeSanity, SmallGapsPassUntouchedAndInOrder) {
  const auto t = steady(0, 30, 9 * kS);  // 9 s apart (a stalling engine's last edges): below the 10 s jump
  const Fed r = feed(t);
  EXPECT_EQ(r.kept, t);
  EXPECT_TRUE(r.dropped_lines.empty());
}

// The finding: one edge line of a capture at t = 100000 s was adopted as "now" and every later edge (76 %)
// was rejected as going backwards. Now that one edge is dropped and named, the rest reads.
TEST(TimeSanity, EdgeCsvWithOneFlippedDigitLosesOneEdge) {
  test::TempFile clean("");
  ASSERT_GT(test::write_edge_csv(clean.path(), test::WheelRun{3000.0, 3000.0, 1.0}), 1000);
  test::TempFile bad("");
  ASSERT_GT(test::write_edge_csv(bad.path(), test::WheelRun{3000.0, 3000.0, 1.0}), 1000);
  ASSERT_TRUE(test::corrupt_edge_csv_time(bad.path(), 1500, "100000"));
  EdgeCsvSource a(clean.path()), b(bad.path());
  ASSERT_TRUE(a.ok() && b.ok());
  const auto ea = read_all(a), eb = read_all(b);
  EXPECT_EQ(eb.size() + 1, ea.size());
  EXPECT_EQ(b.stats().time_outliers, 1u);
  EXPECT_EQ(b.stats().bad_lines, 1u);
  for (const EdgeEvent& e : eb) EXPECT_LT(e.t_ns, 2 * kS);
  ASSERT_EQ(b.input_messages().size(), 1u);
  EXPECT_NE(b.input_messages()[0].find(":1500: time 100000."), std::string::npos) << b.input_messages()[0];
  EXPECT_NE(b.input_messages()[0].find("outlier"), std::string::npos);
}

TEST(TimeSanity, EdgeCsvGenuineJumpKeepsEveryEdge) {
  test::TempFile clean("");
  ASSERT_GT(test::write_edge_csv(clean.path(), test::WheelRun{3000.0, 3000.0, 1.0}), 1000);
  test::TempFile jump("");
  ASSERT_GT(test::write_edge_csv(jump.path(), test::WheelRun{3000.0, 3000.0, 1.0}), 1000);
  ASSERT_TRUE(test::corrupt_edge_csv_time(jump.path(), 1500, "", 3600.0));
  EdgeCsvSource a(clean.path()), b(jump.path());
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(read_all(b).size(), read_all(a).size());
  EXPECT_EQ(b.stats().time_rebases, 1u);
  EXPECT_EQ(b.stats().time_outliers, 0u);
}

TEST(TimeSanity, CandumpFrameFarAheadIsDroppedAndNamed) {
  std::string log;
  for (int i = 0; i < 30; ++i) {
    char buf[80];
    std::snprintf(buf, sizeof buf, "(%d.%06d) can0 100#00\n", i == 12 ? 1800000000 : 1700000000, i * 10000);
    log += buf;
  }
  test::TempFile f(log);
  CandumpSource src(f.path());
  ASSERT_TRUE(src.ok());
  int n = 0;
  CanFrame c;
  while (src.next(c) == SourceStatus::kOk) {
    ++n;
    EXPECT_LT(c.t_ns, 1'700'000'001 * kS);
  }
  EXPECT_EQ(n, 29);
  EXPECT_EQ(src.stats().time_outliers, 1u);
  ASSERT_FALSE(src.bad_line_messages().empty());
  EXPECT_NE(src.bad_line_messages()[0].find(":13: time 1800000000.12"), std::string::npos)
      << src.bad_line_messages()[0];
}

TEST(TimeSanity, AnOutlierMessageGivesTheDistanceOfTimesMoreThanInt64MaxApart) {
  // Two times of opposite sign 1.8e19 ns apart: their difference does not fit an int64 (UBSan flagged it).
  TimeDrop d;
  d.line = 7;
  d.t_ns = 9'000'000'000'000'000'000;
  d.base_ns = -9'000'000'000'000'000'000;
  const std::string m = describe_time_drop(d, "x.log");
  EXPECT_NE(m.find("x.log:7: time 9000000000.000000000 s is 18000000000.000000000 s off the time base "
                   "(-9000000000.000000000 s)"),
            std::string::npos)
      << m;
  std::swap(d.t_ns, d.base_ns);
  EXPECT_NE(describe_time_drop(d, "x.log").find("is -18000000000.000000000 s off"), std::string::npos);
}

}  // namespace
}  // namespace torqued
