// tests/service/test_read_ahead_merger.cpp: service/read_ahead_merger.hpp, the fast replay's reader thread.
// Its truth is the one-thread ReplayMerger on the same files: every record (status, item, CAN frame count,
// the sources' bad lines and drops) must come out the same, in the same order, through a ring small enough to
// be full most of the time; and stopping it early must end the reader. Also run whole under ThreadSanitizer.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "candump_source.hpp"
#include "edge_file_source.hpp"
#include "read_ahead_merger.hpp"
#include "synthetic_edge_csv.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

class ReadAheadMergerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("torqued_read_ahead_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    edges_ = (dir_ / "edges.csv").string();
    ASSERT_GT(test::write_edge_csv(edges_, test::WheelRun{3000.0, 2000.0, 0.5}), 100);
    { std::ofstream(edges_, std::ios::app) << "not,a,row\n"; }
    can_ = (dir_ / "can.log").string();
    std::ofstream f(can_);
    for (int i = 0; i < 400; ++i) {  // 800 Hz of frames, a bad line every 50
      char line[96];
      std::snprintf(line, sizeof line, "(1700000000.%06d) can0 %X#%016X\n", i * 1250, 0x100 + i % 4, i);
      f << line;
      if (i % 50 == 7) f << "garbage line\n";
    }
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
  std::string edges_, can_;
};

bool same_item(const ReplayMerger::Item& a, const ReplayMerger::Item& b) {
  if (a.kind != b.kind) return false;
  if (a.kind == ReplayMerger::Kind::kEdge)
    return a.edge.t_ns == b.edge.t_ns && a.edge.channel == b.edge.channel && a.edge.level == b.edge.level;
  return a.frame.t_ns == b.frame.t_ns && a.frame.id == b.frame.id && a.frame.len == b.frame.len &&
         std::memcmp(a.frame.data.data(), b.frame.data.data(), a.frame.len) == 0;
}

TEST_F(ReadAheadMergerTest, HandsOverWhatTheOneThreadMergerGivesInOrderWithItsCounts) {
  constexpr std::int64_t kOffset = -1'700'000'000'000'000'000;
  // GIVEN the one-thread merger on the files (truth) and the reader thread on a second copy, ring of 8
  EdgeCsvSource e1(edges_, {}), e2(edges_, {});
  CandumpSource c1(can_), c2(can_);
  ReplayMerger truth(&e1, &c1, kOffset);
  ReadAheadMerger input(&e2, &c2, kOffset, 8);
  // WHEN both are read to the end
  ReplayMerger::Item a, b;
  std::uint64_t n = 0;
  for (;; ++n) {
    const SourceStatus sa = truth.next(a);
    const SourceStatus sb = input.next(b);
    ASSERT_EQ(sa, sb) << "record " << n;
    // THEN each record, the CAN frame count and the sources' bad lines as they stood then are the same
    ASSERT_EQ(truth.frames_out(), input.frames_out()) << "record " << n;
    ASSERT_EQ(e1.stats().bad_lines + c1.stats().bad_lines, input.source_drops()) << "record " << n;
    if (sa == SourceStatus::kEnd) break;
    if (sa == SourceStatus::kOk) {
      ASSERT_TRUE(same_item(a, b)) << "record " << n;
    }
  }
  input.stop();
  EXPECT_GT(n, 1000U);
  EXPECT_EQ(input.frames_out(), 400U);
  EXPECT_EQ(input.source_drops(), 9U);  // 8 garbage CAN lines and the edge CSV's last line
  EXPECT_EQ(input.drops(), 0U);         // it waited, never dropped
  EXPECT_EQ(input.next(b), SourceStatus::kEnd);
  EXPECT_TRUE(input.first_error().empty());
}

TEST_F(ReadAheadMergerTest, StopBeforeTheEndEndsTheReader) {
  // GIVEN a reader far ahead of a replay that takes 10 records, WHEN stopped THEN it ends (join returns)
  EdgeCsvSource e(edges_, {});
  CandumpSource c(can_);
  ReadAheadMerger input(&e, &c, 0, 4);
  ReplayMerger::Item item;
  for (int i = 0; i < 10; ++i) ASSERT_EQ(input.next(item), SourceStatus::kOk);
  input.stop();
  input.stop();  // idempotent
  EXPECT_EQ(input.drops(), 0U);
}

}  // namespace
}  // namespace torqued
