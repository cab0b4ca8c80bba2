// io/looping_source.hpp: replay.loop restarts a recording with its times shifted by one common period.
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "looping_source.hpp"

namespace torqued {
namespace {

// A recording in memory: fixed record times (ns), then kEnd. Base: EdgeSource or CanSource, Event its record.
template <class Base, class Event>
class VectorSource final : public Base {
 public:
  explicit VectorSource(std::vector<std::int64_t> t) : t_(std::move(t)) {}
  SourceStatus next(Event& out) noexcept override {
    if (i_ >= t_.size()) return SourceStatus::kEnd;
    out = Event{};
    out.t_ns = t_[i_++];
    ++stats_.records;
    return SourceStatus::kOk;
  }
  const SourceStats& stats() const noexcept override { return stats_; }
  std::string describe() const override { return "vector"; }

 private:
  std::vector<std::int64_t> t_;
  std::size_t i_ = 0;
  SourceStats stats_{};
};
using VectorEdgeSource = VectorSource<EdgeSource, EdgeEvent>;
using VectorCanSource = VectorSource<CanSource, CanFrame>;

const std::vector<std::int64_t> kEdges{1000, 1100, 1200, 1400};  // last gap 200 ns
const std::vector<std::int64_t> kCan{50, 1500};                  // + offset 0: spans 50 .. 1500

TEST(LoopingSource, PeriodCoversBothInputsPlusTheLastEdgeGap) {
  // GIVEN edges 1000..1400 (last gap 200) and CAN frames 50..1500 (offset 0, then offset +100)
  VectorEdgeSource e1(kEdges), e2(kEdges);
  VectorCanSource c1(kCan), c2(kCan);
  // THEN the period runs from the earliest to the latest record plus the last edge gap (exact)
  EXPECT_EQ(loop_period_ns(e1, &c1, 0), 1500 - 50 + 200);
  EXPECT_EQ(loop_period_ns(e2, &c2, 100), 1600 - 150 + 200);
  VectorEdgeSource e3(kEdges);
  EXPECT_EQ(loop_period_ns(e3, nullptr, 0), 1400 - 1000 + 200);
  VectorEdgeSource one({5});
  EXPECT_EQ(loop_period_ns(one, nullptr, 0), 0);  // nothing to loop
}

TEST(LoopingSource, EdgesRestartShiftedByThePeriodWithCumulativeCounters) {
  // GIVEN a looping edge source of period 600 ns
  int opened = 0;
  LoopingEdgeSource s(
      [&] {
        ++opened;
        return std::make_unique<VectorEdgeSource>(kEdges);
      },
      600);
  // WHEN three loops are read
  std::vector<std::int64_t> got;
  EdgeEvent e{};
  for (int i = 0; i < 12; ++i) {
    ASSERT_EQ(s.next(e), SourceStatus::kOk);
    got.push_back(e.t_ns);
  }
  // THEN the times continue loop after loop (strictly increasing), shifted by exactly 600 ns each loop
  const std::vector<std::int64_t> want{1000, 1100, 1200, 1400, 1600, 1700,
                                       1800, 2000, 2200, 2300, 2400, 2600};
  EXPECT_EQ(got, want);
  EXPECT_EQ(opened, 3);
  EXPECT_EQ(s.loops(), 2u);
  EXPECT_EQ(s.stats().records, 12u);  // counters over every loop (metrics' edges_total keeps growing)
}

TEST(LoopingSource, CanFramesUseTheSamePeriod) {
  LoopingCanSource s([] { return std::make_unique<VectorCanSource>(kCan); }, 1650);
  CanFrame f{};
  std::vector<std::int64_t> got;
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(s.next(f), SourceStatus::kOk);
    got.push_back(f.t_ns);
  }
  EXPECT_EQ(got, (std::vector<std::int64_t>{50, 1500, 1700, 3150}));
}

TEST(LoopingSource, AnEmptyRecordingEndsInsteadOfReopeningForever) {
  int opened = 0;
  LoopingEdgeSource s(
      [&] {
        ++opened;
        return std::make_unique<VectorEdgeSource>(std::vector<std::int64_t>{});
      },
      600);
  EdgeEvent e{};
  EXPECT_EQ(s.next(e), SourceStatus::kEnd);
  EXPECT_EQ(opened, 1);
}

TEST(LoopingSource, AFailedReopenIsAnError) {
  int opened = 0;
  LoopingEdgeSource s(
      [&]() -> std::unique_ptr<EdgeSource> {
        if (opened++ > 0) return nullptr;  // the file went away between loops
        return std::make_unique<VectorEdgeSource>(kEdges);
      },
      600);
  EdgeEvent e{};
  for (int i = 0; i < 4; ++i) ASSERT_EQ(s.next(e), SourceStatus::kOk);
  EXPECT_EQ(s.next(e), SourceStatus::kError);
  EXPECT_EQ(s.last_error(), "reopen failed");
}

}  // namespace
}  // namespace torqued
