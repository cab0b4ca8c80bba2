// Replay merger (one time-ordered stream from edges + CAN, deterministic ties) and pacing.
#include <gtest/gtest.h>

#include <deque>

#include "replay_merger.hpp"

namespace torqued {
namespace {

class VecEdges final : public EdgeSource {
 public:
  explicit VecEdges(std::deque<EdgeEvent> e) : e_(std::move(e)) {}
  SourceStatus next(EdgeEvent& out) noexcept override {
    if (e_.empty()) return SourceStatus::kEnd;
    out = e_.front();
    e_.pop_front();
    ++stats_.records;
    return SourceStatus::kOk;
  }
  const SourceStats& stats() const noexcept override { return stats_; }
  std::string describe() const override { return "vec"; }

 private:
  std::deque<EdgeEvent> e_;
  SourceStats stats_;
};

class VecCan final : public CanSource {
 public:
  explicit VecCan(std::deque<CanFrame> f, bool fail_at_end = false) : f_(std::move(f)), fail_(fail_at_end) {}
  SourceStatus next(CanFrame& out) noexcept override {
    if (f_.empty()) return fail_ ? SourceStatus::kError : SourceStatus::kEnd;
    out = f_.front();
    f_.pop_front();
    return SourceStatus::kOk;
  }
  const SourceStats& stats() const noexcept override { return stats_; }
  std::string describe() const override { return "vec"; }

 private:
  std::deque<CanFrame> f_;
  bool fail_;
  SourceStats stats_;
};

CanFrame can_at(std::int64_t t) {
  CanFrame f;
  f.t_ns = t;
  return f;
}

TEST(ReplayMerger, OrdersByTimeEdgesFirstOnTiesAndAppliesOffset) {
  VecEdges e({{10, 0, 1}, {20, 0, 1}, {30, 0, 1}});
  VecCan c({can_at(1000 + 5), can_at(1000 + 20), can_at(1000 + 40)});
  ReplayMerger m(&e, &c, -1000);
  std::vector<std::pair<int, std::int64_t>> got;
  ReplayMerger::Item it;
  while (m.next(it) == SourceStatus::kOk) got.emplace_back(static_cast<int>(it.kind), it.t_ns());
  const std::vector<std::pair<int, std::int64_t>> want = {{1, 5},  {0, 10}, {0, 20},
                                                          {1, 20}, {0, 30}, {1, 40}};
  EXPECT_EQ(got, want);
  EXPECT_EQ(m.edges_out(), 3u);
  EXPECT_EQ(m.frames_out(), 3u);
  EXPECT_EQ(m.out_of_order(), 0u);
}

TEST(ReplayMerger, OneSourceOnlyAndErrorReportedOnce) {
  VecEdges e({{1, 0, 1}, {2, 0, 1}});
  ReplayMerger only_edges(&e, nullptr);
  ReplayMerger::Item it;
  int n = 0;
  while (only_edges.next(it) == SourceStatus::kOk) ++n;
  EXPECT_EQ(n, 2);

  VecEdges e2({{1, 0, 1}, {2, 0, 1}, {3, 0, 1}});
  VecCan c2({can_at(2)}, /*fail_at_end=*/true);
  ReplayMerger m(&e2, &c2);
  std::vector<SourceStatus> st;
  for (SourceStatus s = m.next(it); s != SourceStatus::kEnd; s = m.next(it)) st.push_back(s);
  // edge 1, then CAN error (once) while CAN frame 2 ... the frame at t=2 is delivered before the error shows
  int errors = 0, oks = 0;
  for (auto s : st) (s == SourceStatus::kError ? errors : oks)++;
  EXPECT_EQ(errors, 1);
  EXPECT_EQ(oks, 4);
}

}  // namespace
}  // namespace torqued
