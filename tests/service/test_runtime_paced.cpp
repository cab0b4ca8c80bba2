// tests/service/test_runtime_paced.cpp: a paced replay (threads, wake-ups at due times) gives the same
// angle-chain values as the fast replay (one thread, no clock) of the same recording: when and how often the
// angle thread wakes must not change what the decoder and the estimators see. The angle thread takes cam
// edges and the falling crank edges at the next tooth edge's wake-up (not at their own due time): it must
// still hand them to the decoder in order. Checked on a 60-2 wheel with a cam, with and without the decoder's
// debounce (with it, the falling edge is the one that releases each tooth).
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "edge_file_source.hpp"
#include "fast_replay.hpp"
#include "runtime.hpp"
#include "synthetic_edge_csv.hpp"

namespace torqued {
namespace {

/// Keeps every sample (paced: called by the publisher thread only).
class VectorSink final : public SampleSink {
 public:
  void emit(const dds::AnySample& s) noexcept override { v.push_back(s); }
  std::vector<dds::AnySample> v;
};

/// The angle chain's own samples, with the wall-clock stamps cleared and without those fed by the time thread
/// (time methods at its timer ticks; fusion, which takes the time chain's newest UIO estimate).
std::vector<dds::AnySample> angle_values(const std::vector<dds::AnySample>& in) {
  std::vector<dds::AnySample> out;
  for (dds::AnySample s : in) {
    if (s.topic == dds::Topic::kDaemonStatus) continue;
    if (s.topic == dds::Topic::kEstimatorTorque &&
        (s.u.estimator.method <= torque_METHOD_ADAPTIVE || s.u.estimator.method == torque_METHOD_FUSED))
      continue;
    s.visit([](auto& v) { v.ingest_t_ns = v.publish_t_ns = 0; });
    if (s.topic == dds::Topic::kEngineTorque) {
      s.u.engine.fused_nm = 0.0;
      s.u.engine.quality = 0;
      s.u.engine.fused_source = 0;
      s.u.engine.input_age_ns = 0;
      s.u.engine.validity = 0;
    }
    out.push_back(s);
  }
  return out;
}

struct PacedRun {
  std::vector<dds::AnySample> samples;
  RuntimeCounters counters;
  std::vector<StageStamps> trace;
};

PacedRun run_paced(const std::string& path, const StageSettings& s, double speed,
                   std::size_t stage_trace = 0) {
  RuntimeOptions o;
  o.speed = speed;
  o.stage_trace = stage_trace;
  o.lock_memory = false;
  o.angle.fifo = o.time.fifo = o.source.fifo = o.publisher.fifo = false;  // unprivileged test
  o.publisher_spin_ns = 150'000;
  std::atomic<std::size_t> stack_min{~std::size_t{0}}, stack_max{0};
  o.rt_thread_hook = [&](const char*, bool exiting) {
    if (exiting) return;
    const std::size_t n = current_thread_stack_size();
    for (std::size_t m = stack_min.load(); n < m && !stack_min.compare_exchange_weak(m, n);) {
    }
    for (std::size_t m = stack_max.load(); n > m && !stack_max.compare_exchange_weak(m, n);) {
    }
  };
  EdgeCsvSource src(path, {});
  EXPECT_TRUE(src.ok());
  VectorSink sink;
  sink.v.reserve(200'000);
  Runtime rt(s, o, &src, nullptr, 0, nullptr, sink);
  EXPECT_TRUE(rt.ok()) << rt.error();
  EXPECT_TRUE(rt.start()) << rt.error();
  for (int i = 0; i < 500 && !rt.input_done(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_TRUE(rt.input_done());
  EXPECT_TRUE(rt.stop_and_drain(2'000'000'000));
  // Runtime::start sizes the stacks of the threads it creates (not RLIMIT_STACK's 8 MiB, which mlockall would
  // make resident).
  EXPECT_EQ(stack_min.load(), kThreadStackBytes);
  EXPECT_EQ(stack_max.load(), kThreadStackBytes);
  return {sink.v, rt.counters(), rt.stage_trace()};
}

void expect_same_values(const std::vector<dds::AnySample>& paced, const std::vector<dds::AnySample>& fast) {
  const auto a = angle_values(paced), b = angle_values(fast);
  ASSERT_EQ(a.size(), b.size()) << "paced and fast replay emitted different numbers of angle-chain samples";
  int cycles = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].topic, b[i].topic) << "sample " << i;
    if (a[i].topic == dds::Topic::kEngineTorque && a[i].u.engine.kind == 1) ++cycles;
    // Bit-identical: same inputs in the same order through the same code. AnySample zero-fills its union,
    // padding included, so comparing its bytes is meaningful.
    // NOLINTNEXTLINE(bugprone-suspicious-memory-comparison)
    ASSERT_EQ(0, std::memcmp(&a[i].u, &b[i].u, sizeof a[i].u))
        << "sample " << i << " (topic " << static_cast<int>(a[i].topic) << ", t "
        << a[i].visit([](const auto& v) { return v.source_t_ns; })
        << ") differs between paced and fast replay";
  }
  EXPECT_GT(cycles, 20) << "per-cycle EngineTorque samples compared";
}

class PacedEqualsFast : public ::testing::TestWithParam<double> {};

TEST_P(PacedEqualsFast, SameAngleChainValuesAndAboutOneWakeUpPerTooth) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("torqued_paced_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "edges.csv").string();
  const int teeth = test::write_edge_csv(path, test::WheelRun{2000.0, 4000.0, 1.5});
  ASSERT_GT(teeth, 1000);

  StageSettings s;
  s.decoder.min_pulse_us = GetParam();  // 0: rising edges emit; > 0: the falling edge confirms each tooth
  VectorSink fast;
  fast.v.reserve(200'000);
  {
    EdgeCsvSource src(path, {});
    ASSERT_TRUE(src.ok());
    const ReplayResult r = run_fast_replay(s, &src, nullptr, 0, nullptr, fast);
    ASSERT_TRUE(r.error.empty()) << r.error;
  }
  const PacedRun paced = run_paced(path, s, 5.0);
  expect_same_values(paced.samples, fast.v);
  const RuntimeCounters& c = paced.counters;
  EXPECT_EQ(c.ring_drops_edge + c.ring_drops_out, 0u);
  EXPECT_GT(c.edges, 2 * static_cast<std::uint64_t>(teeth)) << "rising + falling crank edges and cam edges";
  // About one sleep per tooth edge, not one per edge (before: 2 per tooth + cam edges): the falling crank
  // edges and the cam edges ride on the tooth edges' wake-ups. The margin covers the few other sleeps (start,
  // end, a read-ahead batch ending on a non-tooth edge, the 50 ms bound).
  EXPECT_GT(c.angle_wakeups, 0u);
  EXPECT_LT(c.angle_wakeups, static_cast<std::uint64_t>(teeth) * 11 / 10 + 20)
      << c.angle_wakeups << " angle-thread wake-ups for " << teeth << " teeth and " << c.edges << " edges";
  RecordProperty("angle_wakeups", static_cast<int>(c.angle_wakeups));
  RecordProperty("teeth", teeth);
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Debounce, PacedEqualsFast, ::testing::Values(0.0, 20.0));

// torqued --stage-trace: GIVEN a paced replay (5x) with the stage trace on THEN every CrankState the
// publisher wrote has one row, in order, with its seq and ingest stamp, and its stamps follow the sample's
// way through the daemon (edge due <= angle thread takes it <= pushed <= publisher takes it <= written); the
// trace does not change the values (same as the fast replay).
TEST(PacedStageTrace, OneRowPerCrankStateWithStampsInTheOrderOfItsWay) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("torqued_paced_trace_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "edges.csv").string();
  ASSERT_GT(test::write_edge_csv(path, test::WheelRun{2000.0, 4000.0, 1.5}), 1000);
  StageSettings s;
  VectorSink fast;
  fast.v.reserve(200'000);
  {
    EdgeCsvSource src(path, {});
    ASSERT_TRUE(src.ok());
    ASSERT_TRUE(run_fast_replay(s, &src, nullptr, 0, nullptr, fast).error.empty());
  }
  const PacedRun paced = run_paced(path, s, 5.0, 1 << 16);
  expect_same_values(paced.samples, fast.v);
  std::vector<const torque_CrankState*> crank;
  for (const auto& x : paced.samples)
    if (x.topic == dds::Topic::kCrankState) crank.push_back(&x.u.crank);
  ASSERT_GT(crank.size(), 50u);
  ASSERT_EQ(paced.trace.size(), crank.size());
  for (std::size_t i = 0; i < crank.size(); ++i) {
    const StageStamps& t = paced.trace[i];
    ASSERT_EQ(t.seq, crank[i]->seq) << "row " << i;
    ASSERT_EQ(t.ingest_ns, crank[i]->ingest_t_ns) << "row " << i;
    EXPECT_GT(t.ingest_ns, 0) << "row " << i;
    EXPECT_LE(t.ingest_ns, t.angle_ns) << "row " << i;
    EXPECT_LE(t.angle_ns, t.pushed_ns) << "row " << i;
    EXPECT_LE(t.pushed_ns, t.taken_ns) << "row " << i;
    EXPECT_LE(t.taken_ns, t.written_ns) << "row " << i;
  }
  fs::remove_all(dir);
}

// Hostile input (the finding: a paced replay with one edge at t = 100000 s waited for that edge, its status
// failed for the rest of the run; one daemon sat 25 minutes). GIVEN the capture with one flipped digit, paced
// at 5x THEN the input ends within the 10 s the run allows, one edge is dropped and the decoder never lost
// sync.
TEST(PacedHostileInput, FlippedDigitDoesNotStallThePacedReplay) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("torqued_paced_flip_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "edges.csv").string();
  ASSERT_GT(test::write_edge_csv(path, test::WheelRun{2000.0, 2000.0, 1.0}), 500);
  StageSettings s;
  std::uint64_t clean_edges = 0;
  {
    EdgeCsvSource src(path, {});
    VectorSink fast;
    clean_edges = run_fast_replay(s, &src, nullptr, 0, nullptr, fast).counters.edges;
  }
  ASSERT_TRUE(test::corrupt_edge_csv_time(path, 1000, "100000"));
  const PacedRun paced = run_paced(path, s, 5.0);
  EXPECT_EQ(paced.counters.edges + 1, clean_edges);
  EXPECT_EQ(paced.counters.source_drops, 1u);
  EXPECT_EQ(paced.counters.sync_losses, 0u);
  EXPECT_TRUE(paced.counters.synced);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace torqued
