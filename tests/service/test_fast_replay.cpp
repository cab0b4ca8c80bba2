// tests/service/test_fast_replay.cpp: the fast replay (service/fast_replay.cpp) on a synthetic 60-2 wheel
// with known speed: per-cycle speed matches the analytic truth, output is byte-identical across runs and
// between one thread and three (replay.fast_threads), and the replay makes no heap allocation once the
// stages are built (allocation test over a full replay).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>

#include "alloc_counter.hpp"
#include "candump_source.hpp"
#include "edge_file_source.hpp"
#include "fast_replay.hpp"
#include "output_fanout.hpp"
#include "sink_thread.hpp"
#include "synthetic_edge_csv.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

class FastReplayTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("torqued_fast_replay_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    edges_ = (dir_ / "edges.csv").string();
    rising_ = test::write_edge_csv(edges_, test::WheelRun{3000.0, 3000.0, 2.0});
    ASSERT_GT(rising_, 1000);
  }
  void TearDown() override { fs::remove_all(dir_); }

  ReplayResult replay_to(const fs::path& out) {
    StageSettings s;
    s.crank_decimation = 1;
    EdgeCsvSource src(edges_, {});
    EXPECT_TRUE(src.ok()) << src.last_error();
    dds::SampleRecorder rec(out.string());
    OutputFanout sink(&rec, nullptr);
    return run_fast_replay(s, &src, nullptr, 0, nullptr, sink);
  }

  // A candump log of 199 frames, 10 ms apart; a "garbage" line after frame garbage_after (0: none).
  std::string write_can_log(int garbage_after = 0) {
    std::string path = (dir_ / "can.log").string();
    std::ofstream f(path);
    for (int k = 1; k < 200; ++k) {
      char line[64];
      std::snprintf(line, sizeof line, "(%d.%06d) can0 100#0102030405060708\n", k / 100, (k % 100) * 10000);
      f << line;
      if (k == garbage_after) f << "garbage\n";
    }
    return path;
  }

  // Fast replay recorded into `out` on one thread (recorder called directly) or on three (a reader thread,
  // and the recording written by a SinkThread as daemon_run.cpp does).
  static ReplayResult replay_on(int threads, EdgeSource& edges, CanSource& can, const fs::path& out) {
    StageSettings s;
    s.crank_decimation = 1;
    s.fast_threads = threads;
    dds::SampleRecorder rec(out.string());
    OutputFanout fanout(&rec, nullptr);
    if (threads == 1) return run_fast_replay(s, &edges, &can, 0, nullptr, fanout);
    SinkThread writer(fanout);
    ReplayResult r = run_fast_replay(s, &edges, &can, 0, nullptr, writer);
    writer.flush();
    EXPECT_EQ(writer.written(), r.samples);
    return r;
  }

  // Every file recorded in `a` is in `b` with the same bytes; returns how many.
  static int expect_same_files(const fs::path& a, const fs::path& b, const std::string& tag) {
    int files = 0;
    for (const auto& e : fs::directory_iterator(a)) {
      const auto other = b / e.path().filename();
      EXPECT_TRUE(fs::exists(other)) << tag << ": " << other;
      EXPECT_TRUE(slurp(e.path()) == slurp(other)) << tag << ": " << e.path().filename() << " differs";
      ++files;
    }
    return files;
  }

  fs::path dir_;
  std::string edges_;
  int rising_ = 0;
};

TEST_F(FastReplayTest, CycleSpeedMatchesAnalyticTruth) {
  // GIVEN 2 s of a 60-2 wheel at exactly 3000 rpm WHEN replayed THEN the decoder syncs, about 50 cycles are
  // reported and each cycle's mean speed equals 3000 rpm within 1e-6 (edge times are printed to 1 ns).
  const ReplayResult r = replay_to(dir_ / "out");
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.counters.teeth + 1, static_cast<std::uint64_t>(rising_));  // the first edge has no period
  EXPECT_EQ(r.counters.sync_losses, 0u);
  EXPECT_GE(r.counters.cycles, 45u);
  EXPECT_LE(r.counters.cycles, 50u);
  std::ifstream f(dir_ / "out" / "engine_cycle.csv");
  std::string header, line;
  std::getline(f, header);
  ASSERT_EQ(header.rfind("t_ns,", 0), 0u) << header;
  // speed_rad_s column index
  int col = -1, i = 0;
  std::stringstream hs(header);
  for (std::string c; std::getline(hs, c, ','); ++i)
    if (c == "speed_rad_s") col = i;
  ASSERT_GE(col, 0);
  int rows = 0;
  const double w = 3000.0 * 2 * std::numbers::pi / 60;
  while (std::getline(f, line)) {
    std::stringstream ls(line);
    std::string c;
    for (int k = 0; k <= col; ++k) std::getline(ls, c, ',');
    if (std::stod(c) == 0.0) continue;  // the pipeline's first window is not complete yet (speed unknown)
    EXPECT_NEAR(std::stod(c), w, w * 1e-6) << line;
    ++rows;
  }
  EXPECT_GE(rows, static_cast<int>(r.counters.cycles) - 2);
}

TEST_F(FastReplayTest, TwoRunsAreByteIdentical) {
  const ReplayResult a = replay_to(dir_ / "a");
  const ReplayResult b = replay_to(dir_ / "b");
  ASSERT_GT(a.samples, 0u);
  EXPECT_EQ(a.samples, b.samples);
  const int files = expect_same_files(dir_ / "a", dir_ / "b", "between runs");  // no multi-MB diff
  EXPECT_GE(files, 3);  // engine_cycle, crank_state, daemon_status
}

// replay.fast_threads: GIVEN 2 s of a 60-2 wheel with one bad line and a CAN log of 199 frames with one bad
// line WHEN replayed on one thread (merger and recorder on the calling thread) and on three (a reader thread,
// and the recording written by a SinkThread as daemon_run.cpp does) THEN every recorded file is
// byte-identical (daemon_status.csv: every DaemonStatus count at every period) and so are the run's counts.
TEST_F(FastReplayTest, OneThreadAndThreeGiveTheSameBytesAndCounts) {
  {
    std::ofstream f(edges_, std::ios::app);
    f << "not,a,row\n";
  }
  const std::string can_path = write_can_log(50);
  auto replay = [&](int threads, const fs::path& out) {
    EdgeCsvSource src(edges_, {});
    CandumpSource can(can_path);
    return replay_on(threads, src, can, out);
  };
  const ReplayResult one = replay(1, dir_ / "one");
  const ReplayResult three = replay(3, dir_ / "three");
  EXPECT_EQ(one.threads.threads, 1);
  EXPECT_EQ(three.threads.threads, 3);
  ASSERT_TRUE(one.error.empty()) << one.error;
  EXPECT_EQ(one.counters.can_frames, 199u);
  EXPECT_EQ(one.counters.source_drops, 2u);
  EXPECT_GT(one.counters.cycles, 40u);
  const RuntimeCounters &a = one.counters, &b = three.counters;
  EXPECT_EQ(a.edges, b.edges);
  EXPECT_EQ(a.teeth, b.teeth);
  EXPECT_EQ(a.can_frames, b.can_frames);
  EXPECT_EQ(a.cycles, b.cycles);
  EXPECT_EQ(a.sync_losses, b.sync_losses);
  EXPECT_EQ(a.source_drops, b.source_drops);
  EXPECT_EQ(a.rejected_edges, b.rejected_edges);
  EXPECT_EQ(a.flags, b.flags);
  EXPECT_EQ(one.samples, three.samples);
  EXPECT_EQ(one.input_problems, three.input_problems);
  const int files = expect_same_files(dir_ / "one", dir_ / "three", "1 vs 3 threads");
  EXPECT_GE(files, 3);  // engine_cycle, crank_state, daemon_status
  EXPECT_TRUE(fs::exists(dir_ / "one" / "daemon_status.csv"));
}

// replay.fast_threads auto resolves on the CPU count it is given (not this machine's): 3 from 2 CPUs up, 1 on
// one; 1 and 3 are taken as given whatever the count; the reason names the setting and the count.
TEST(FastThreads, AutoIsThreeFromTwoCpusAndOneBelow) {
  EXPECT_EQ(resolve_fast_threads(0, 1).threads, 1);
  EXPECT_EQ(resolve_fast_threads(0, 2).threads, 3);
  EXPECT_EQ(resolve_fast_threads(0, 64).threads, 3);
  EXPECT_EQ(resolve_fast_threads(1, 8).threads, 1);
  EXPECT_EQ(resolve_fast_threads(3, 1).threads, 3);
  EXPECT_EQ(resolve_fast_threads(0, 1).why, "replay.fast_threads auto, 1 CPU usable");
  EXPECT_EQ(resolve_fast_threads(0, 4).why, "replay.fast_threads auto, 4 CPUs usable");
  EXPECT_EQ(resolve_fast_threads(1, 4).why, "replay.fast_threads 1");
  EXPECT_GE(usable_cpus(), 1);
}

// auto's CPU count also follows a cgroup CPU quota (a container started with --cpus=1 may run on every CPU,
// but only one CPU's time in all): on fake cgroup trees, v2 (cpu.max, the smallest along the path) and v1
// (cfs files).
TEST(FastThreads, ACgroupCpuQuotaLimitsTheUsableCpus) {
  const fs::path root = fs::path(testing::TempDir()) / "fake_cgroup";
  fs::remove_all(root);
  const auto put = [](const fs::path& f, const std::string& text) {
    fs::create_directories(f.parent_path());
    std::ofstream(f) << text;
  };
  put(root / "v2" / "cpu.max", "max 100000\n");
  put(root / "v2" / "ctr" / "cpu.max", "150000 100000\n");  // 1.5 CPUs: one whole CPU
  put(root / "v2" / "ctr" / "job" / "cpu.max", "max 100000\n");
  EXPECT_EQ(cgroup_quota_cpus("0::/ctr/job\n", (root / "v2").string()), 1);
  put(root / "v2" / "ctr" / "cpu.max", "400000 100000\n");
  EXPECT_EQ(cgroup_quota_cpus("0::/ctr/job\n", (root / "v2").string()), 4);
  put(root / "v2" / "ctr" / "job" / "cpu.max", "200000 100000\n");  // the smaller, lower down
  EXPECT_EQ(cgroup_quota_cpus("0::/ctr/job\n", (root / "v2").string()), 2);
  EXPECT_EQ(cgroup_quota_cpus("0::/\n", (root / "v2").string()), 0);            // no quota at the root
  EXPECT_EQ(cgroup_quota_cpus("0::/nosuch\n", (root / "v2").string()), 0);      // unreadable: none
  put(root / "v1" / "cpu,cpuacct" / "docker" / "cpu.cfs_quota_us", "50000\n");  // half a CPU: at least 1
  put(root / "v1" / "cpu,cpuacct" / "docker" / "cpu.cfs_period_us", "100000\n");
  put(root / "v1" / "cpu,cpuacct" / "cpu.cfs_quota_us", "-1\n");
  put(root / "v1" / "cpu,cpuacct" / "cpu.cfs_period_us", "100000\n");
  const std::string v1 = "12:pids:/docker\n3:cpu,cpuacct:/docker\n1:name=systemd:/docker\n";
  EXPECT_EQ(cgroup_quota_cpus(v1, (root / "v1").string()), 1);
  EXPECT_EQ(cgroup_quota_cpus("3:cpu,cpuacct:/\n", (root / "v1").string()), 0);
  EXPECT_EQ(cgroup_quota_cpus("garbage\n", (root / "v1").string()), 0);
  fs::remove_all(root);
}

/// Counts samples and keeps the last one, allocation-free.
class NullSink final : public SampleSink {
 public:
  void emit(const dds::AnySample& s) noexcept override {
    ++n;
    last = s;
  }
  std::uint64_t n = 0;
  dds::AnySample last;
};

TEST_F(FastReplayTest, NoAllocationPerRecord) {
  // GIVEN a replay of 1 s and one of 2 s WHEN counting heap allocations THEN both make the same number
  // (construction only): nothing on the per-edge path allocates.
  auto count = [&](double dur) {
    const std::string path = (dir_ / std::string("e").append(std::to_string(dur)).append(".csv")).string();
    test::write_edge_csv(path, test::WheelRun{2000.0, 4000.0, dur});
    StageSettings s;
    NullSink sink;
    torqued::test::AllocationScope scope;
    {
      EdgeCsvSource src(path, {});
      const ReplayResult r = run_fast_replay(s, &src, nullptr, 0, nullptr, sink);
      EXPECT_GT(r.counters.cycles, 10u);
    }
    return scope.count();
  };
  count(0.5);  // the first construction also fills the start-up memos (tooth table, Fourier check)
  const auto a1 = count(1.0), a2 = count(2.0);
  EXPECT_EQ(a1, a2) << "allocations grow with the replay length";
}

// Bad input: bad lines are named with file:line at the end of the run, and an input with no record says so.
TEST_F(FastReplayTest, BadLinesAndAnEmptyInputAreNamed) {
  {
    std::ofstream f(edges_, std::ios::app);
    f << "not,a,row\n";
  }
  const std::string can_path = (dir_ / "empty.log").string();
  { std::ofstream f(can_path); }
  StageSettings s;
  EdgeCsvSource src(edges_, {});
  CandumpSource can(can_path);
  NullSink sink;
  const ReplayResult r = run_fast_replay(s, &src, &can, 0, nullptr, sink);
  ASSERT_EQ(r.input_problems.size(), 2u);
  EXPECT_NE(r.input_problems[0].find("edges: " + edges_ + ":"), std::string::npos) << r.input_problems[0];
  EXPECT_NE(r.input_problems[1].find("can: "), std::string::npos) << r.input_problems[1];
  EXPECT_NE(r.input_problems[1].find("no frame"), std::string::npos) << r.input_problems[1];
  EXPECT_EQ(r.counters.source_drops, 1u);
}

TEST_F(FastReplayTest, CleanInputsHaveNoProblems) {
  StageSettings s;
  EdgeCsvSource src(edges_, {});
  NullSink sink;
  EXPECT_TRUE(run_fast_replay(s, &src, nullptr, 0, nullptr, sink).input_problems.empty());
}

// Hostile input (the finding: one edge line at t = 100000 s became "now": 76 % of the later edges were
// rejected and fast replay wrote 40 M time-method samples, 2 GB, to fill the gap). GIVEN the same capture
// with one flipped digit THEN the replay loses that one edge, names its line, and writes as many samples as
// the clean capture (within 1 %).
TEST_F(FastReplayTest, FlippedDigitCostsOneEdgeAndNoExtraOutput) {
  StageSettings s;
  auto run = [&](const std::string& path, NullSink& sink) {
    EdgeCsvSource src(path, {});
    return run_fast_replay(s, &src, nullptr, 0, nullptr, sink);
  };
  NullSink clean_sink, bad_sink;
  const ReplayResult clean = run(edges_, clean_sink);
  const std::string bad = (dir_ / "flipped.csv").string();
  fs::copy_file(edges_, bad);
  ASSERT_TRUE(test::corrupt_edge_csv_time(bad, 3000, "100000"));
  const ReplayResult r = run(bad, bad_sink);
  EXPECT_EQ(r.counters.edges + 1, clean.counters.edges);
  EXPECT_EQ(r.counters.source_drops, 1u);
  EXPECT_EQ(r.counters.sync_losses, 0u);
  EXPECT_NEAR(static_cast<double>(r.samples), static_cast<double>(clean.samples), 0.01 * clean.samples);
  EXPECT_LT(r.last_t_ns, 3'000'000'000);
  ASSERT_EQ(r.input_problems.size(), 1u);
  EXPECT_NE(r.input_problems[0].find(":3000: time 100000."), std::string::npos) << r.input_problems[0];
}

// A genuine clock jump (the capture resumes an hour later) is adopted without losing an edge, and the output
// across the silent hour is bounded by max_input_gap_ns (10 s) instead of an hour of 1 kHz time steps.
TEST_F(FastReplayTest, GenuineClockJumpKeepsEveryEdgeAndBoundsTheOutput) {
  StageSettings s;
  const std::string jump = (dir_ / "jump.csv").string();
  fs::copy_file(edges_, jump);
  ASSERT_TRUE(test::corrupt_edge_csv_time(jump, 3000, "", 3600.0));
  NullSink clean_sink, jump_sink;
  EdgeCsvSource a(edges_, {}), b(jump, {});
  const ReplayResult clean = run_fast_replay(s, &a, nullptr, 0, nullptr, clean_sink);
  const ReplayResult r = run_fast_replay(s, &b, nullptr, 0, nullptr, jump_sink);
  EXPECT_EQ(r.counters.edges, clean.counters.edges);
  EXPECT_EQ(r.counters.source_drops, 0u);
  EXPECT_GT(r.last_t_ns, 3600'000'000'000);
  // 10 s of extra time steps at most (10 000 steps / decimation 10 for each time method, status samples):
  // about 3800 samples here, not the 1.4 M of 3600 s.
  EXPECT_LT(r.samples, clean.samples + 5000) << clean.samples;
}

/// A file source that fails (kError, as a read error does) after `ok_records` records, the rest unread.
template <class Base, class Record>
class FailsAfter final : public Base {
 public:
  FailsAfter(Base& inner, std::uint64_t ok_records, std::string error)
      : inner_(inner), left_(ok_records), error_(std::move(error)) {}
  SourceStatus next(Record& out) noexcept override {
    if (failed_) return SourceStatus::kEnd;
    if (left_ == 0) {
      failed_ = true;
      return SourceStatus::kError;
    }
    --left_;
    return inner_.next(out);
  }
  [[nodiscard]] const SourceStats& stats() const noexcept override { return inner_.stats(); }
  [[nodiscard]] std::string describe() const override { return "fails after some records"; }
  [[nodiscard]] std::string last_error() const override { return failed_ ? error_ : std::string(); }

 private:
  Base& inner_;
  std::uint64_t left_;
  std::string error_;
  bool failed_ = false;
};

// GIVEN the 2 s 60-2 wheel and a CAN log of 199 frames WHEN the edge source fails part of the way in (or
// the CAN source half way) on one thread and on three THEN both replays report the same error message, keep
// going with the other source to its end, and record the same bytes and counts.
TEST_F(FastReplayTest, ASourceErrorIsReportedAndReplayedAlikeOnOneThreadAndThree) {
  const std::string can_path = write_can_log();
  for (const bool edge_fails : {true, false}) {
    auto replay = [&](int threads, const fs::path& out) {
      EdgeCsvSource src(edges_, {});
      CandumpSource can(can_path);
      FailsAfter<EdgeSource, EdgeEvent> edges(src, edge_fails ? static_cast<std::uint64_t>(rising_) : ~0ull,
                                              "edges.csv: read error: Input/output error");
      FailsAfter<CanSource, CanFrame> frames(can, edge_fails ? ~0ull : 100u, "can.log: read error: EIO");
      return replay_on(threads, edges, frames, out);
    };
    const std::string tag = edge_fails ? "edges" : "can";
    const ReplayResult one = replay(1, dir_ / ("one_" + tag));
    const ReplayResult three = replay(3, dir_ / ("three_" + tag));
    EXPECT_EQ(one.error,
              edge_fails ? "edges.csv: read error: Input/output error" : "can.log: read error: EIO");
    EXPECT_EQ(three.error, one.error);
    EXPECT_EQ(one.counters.can_frames, edge_fails ? 199u : 100u) << tag << ": the other source to its end";
    EXPECT_EQ(one.counters.edges, three.counters.edges) << tag;
    EXPECT_EQ(one.counters.can_frames, three.counters.can_frames) << tag;
    EXPECT_EQ(one.counters.cycles, three.counters.cycles) << tag;
    EXPECT_EQ(one.samples, three.samples) << tag;
    EXPECT_EQ(one.last_t_ns, three.last_t_ns) << tag;
    expect_same_files(dir_ / ("one_" + tag), dir_ / ("three_" + tag), tag);
  }
}

}  // namespace
}  // namespace torqued
