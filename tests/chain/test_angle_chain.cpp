// tests/chain/test_angle_chain.cpp: the angle chain (chain/angle_chain.cpp) on a synthetic 60-2 wheel with
// known speed: one record per decoded tooth, one segment per firing in firing order with its 720° window, the
// learned-state feedback (import → decoder, snapshot, rejection of a table for another wheel), and the
// time-chain fusion slot used only when fusion.time_estimate is set.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <numbers>
#include <vector>

#include "angle_chain.hpp"
#include "edge_file_source.hpp"
#include "synthetic_edge_csv.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

struct Recorder final : AngleChainSink {
  std::vector<ChainTooth> teeth;
  std::vector<ChainSegment> segments;
  std::vector<CycleOutput> outs;
  std::vector<Health>
      kalman;  ///< in-cycle Kalman health of each tooth with estimates (taken in the callback:
               ///< ChainTooth::estimates points into the pipeline and is only valid then)
  void on_tooth(const ChainTooth& t) noexcept override {
    teeth.push_back(t);
    if (t.estimates) kalman.push_back(t.estimates->kalman_ind.health);
  }
  void on_segment(const ChainSegment& s) noexcept override {
    segments.push_back(s);
    outs.push_back(*s.out);
  }
};

struct ToothCounter final : ToothSink {
  int n = 0;
  void tooth(const ToothSample&) noexcept override { ++n; }
};

class AngleChainTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("torqued_angle_chain_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    edges_ = (dir_ / "edges.csv").string();
    ASSERT_GT(test::write_edge_csv(edges_, test::WheelRun{3000.0, 3000.0, 2.0}), 1000);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Feeds the whole file; `before_edge` runs before each edge (time-chain hand-off in the tests).
  template <class F>
  void run(AngleChain& chain, F&& before_edge) {
    EdgeCsvSource src(edges_, {});
    ASSERT_TRUE(src.ok()) << src.last_error();
    EdgeEvent e{};
    for (;;) {
      const SourceStatus st = src.next(e);
      if (st == SourceStatus::kEnd) break;
      if (st != SourceStatus::kOk) continue;
      before_edge(chain);
      chain.on_edge(e);
    }
  }
  void run(AngleChain& chain) {
    run(chain, [](AngleChain&) {});
  }

  fs::path dir_;
  std::string edges_;
};

TEST_F(AngleChainTest, OneRecordPerToothAndOneSegmentPerFiringInOrder) {
  // GIVEN 2 s of a 60-2 wheel at 3000 rpm (50 cycles) and no CAN WHEN the chain runs THEN every decoded tooth
  // is one record and one sample for the time chain, segments follow the firing order 1-3-4-2, each (once a
  // whole cycle was seen) with a 720° window of 40 ms, and the cycle count matches the cycle-end segments.
  StageSettings s;
  Recorder rec;
  ToothCounter time;
  AngleChain chain(s, nullptr, rec, &time);
  ASSERT_TRUE(chain.ok()) << chain.error();
  run(chain);
  EXPECT_EQ(rec.teeth.size(), chain.decoder().stats().teeth);
  EXPECT_EQ(time.n, static_cast<int>(rec.teeth.size()));
  ASSERT_GT(rec.segments.size(), 150u);
  int cycle_ends = 0;
  for (std::size_t i = 1; i < rec.segments.size(); ++i) {
    const ChainSegment& a = rec.segments[i - 1];
    const ChainSegment& b = rec.segments[i];
    const int order[] = {1, 3, 4, 2};
    int ia = 0;
    while (order[ia] != a.cylinder) ++ia;
    EXPECT_EQ(b.cylinder, order[(ia + 1) % 4]) << "segment " << i;
    EXPECT_TRUE(b.status.synced);
    if (i >= 4) {  // the first segments come before a whole 720° window was seen (speed 0, empty window)
      EXPECT_NEAR(static_cast<double>(b.source_t_ns - b.window_start_t_ns) * 1e-9, 0.040, 1e-5)
          << "segment " << i;
    }
    if (rec.outs[i].cycle_end) ++cycle_ends;
  }
  EXPECT_NEAR(static_cast<double>(cycle_ends), static_cast<double>(chain.cycles()), 1.0);
  EXPECT_NEAR(rec.outs.back().speed_mean_rad_s * 30.0 / std::numbers::pi, 3000.0, 0.01);
}

TEST_F(AngleChainTest, ImportedToothTableReachesTheDecoderAndTheSnapshot) {
  // GIVEN a persisted tooth table for this wheel (58 corrections) and a friction law WHEN imported THEN the
  // snapshot holds exactly that table and law for the next save.
  StageSettings s;
  Recorder rec;
  AngleChain chain(s, nullptr, rec, nullptr);
  LearnedState st;
  for (int i = 0; i < 58; ++i) st.tooth_corrections_rad.push_back(1e-4 * ((i % 7) - 3));
  st.friction = std::array<double, 4>{10.0, 0.001, 1e-6, 0.0};
  const std::string what = chain.import_state(st);
  EXPECT_NE(what.find("58 tooth corrections"), std::string::npos) << what;
  LearnedState back;
  ASSERT_TRUE(chain.snapshot(back));
  ASSERT_EQ(back.tooth_corrections_rad.size(), 58u);
  EXPECT_EQ(back.tooth_corrections_rad, st.tooth_corrections_rad);
  ASSERT_TRUE(back.friction.has_value());
  EXPECT_EQ((*back.friction)[0], 10.0);
  run(chain);
  EXPECT_EQ(chain.decoder().stats().sync_losses, 0u);  // the imported table does not break the decoding
}

TEST_F(AngleChainTest, ImportedBurnPhaseOffsetReachesTheGasModelAndTheSnapshotAndABadOneIsRejected) {
  // GIVEN the burn-phasing learner on (the default) WHEN a persisted offset within its bounds is imported
  // THEN the pipeline's gas model takes it (feedback (6)) and the snapshot holds it with its cycles; WHEN one
  // beyond kalman.burn_phase_max_offset_deg THEN the message says REJECTED and nothing is applied.
  StageSettings s;
  Recorder rec;
  AngleChain chain(s, nullptr, rec, nullptr);
  ASSERT_NE(chain.burn_phase(), nullptr);
  LearnedState st;
  st.burn_phase = std::array<double, 2>{4.25, 300.0};
  EXPECT_NE(chain.import_state(st).find("burn phase offset 4.25"), std::string::npos);
  EXPECT_EQ(chain.pipeline()->burn_offset_deg(), 4.25);
  LearnedState back;
  ASSERT_TRUE(chain.snapshot(back));
  ASSERT_TRUE(back.burn_phase.has_value());
  EXPECT_EQ((*back.burn_phase)[0], 4.25);
  EXPECT_EQ((*back.burn_phase)[1], 300.0);
  AngleChain other(s, nullptr, rec, nullptr);
  st.burn_phase = std::array<double, 2>{30.0, 10.0};
  EXPECT_NE(other.import_state(st).find("burn phase offset REJECTED"), std::string::npos);
  EXPECT_EQ(other.pipeline()->burn_offset_deg(), 0.0);
}

TEST_F(AngleChainTest, UnlearnedWheelIsSaidUntilATableIsLearnedOrImported) {
  // GIVEN tooth learning on WHEN no table was learned or imported THEN the in-cycle Kalman estimate is not
  // converged until the learner's table is applied (≥ 20 cycles of 50: ≥ 40 % of the teeth); WHEN a table for
  // this wheel is imported THEN only the observer's own start-up (one cycle) is.
  for (const bool imported : {false, true}) {
    StageSettings s;
    Recorder rec;
    AngleChain chain(s, nullptr, rec, nullptr);
    if (imported) {
      LearnedState st;
      st.tooth_corrections_rad.assign(58, 0.0);
      ASSERT_NE(chain.import_state(st).find("58 tooth corrections"), std::string::npos);
    }
    run(chain);
    ASSERT_GT(rec.kalman.size(), 2000u);
    const auto nc = std::count(rec.kalman.begin(), rec.kalman.end(), Health::kNotConverged);
    if (imported) {
      EXPECT_LT(nc, 150);  // one cycle (116 teeth) of observer start-up
    } else {
      EXPECT_GT(nc, static_cast<long>(rec.kalman.size() * 4 / 10));
      EXPECT_EQ(rec.kalman.back(), Health::kValid) << "valid once the learned table is applied";
    }
  }
}

TEST_F(AngleChainTest, ToothTableOfAnotherWheelIsRejectedLoudly) {
  // GIVEN 30 corrections for a 58-tooth wheel WHEN imported THEN the message says REJECTED with both counts,
  // and nothing is applied or snapshotted.
  StageSettings s;
  Recorder rec;
  AngleChain chain(s, nullptr, rec, nullptr);
  LearnedState st;
  st.tooth_corrections_rad.assign(30, 1e-4);
  const std::string what = chain.import_state(st);
  EXPECT_NE(what.find("REJECTED (30 values for a wheel of 58 teeth)"), std::string::npos) << what;
  LearnedState snap;
  EXPECT_FALSE(chain.snapshot(snap));
  EXPECT_TRUE(snap.tooth_corrections_rad.empty());
}

TEST_F(AngleChainTest, TimeEstimateReachesTheFusionOnlyWhenConfigured) {
  // GIVEN a valid time-chain estimate handed in before every edge, blending on and a wide gate WHEN
  // fusion.time_estimate is off THEN the external source is never used; WHEN on THEN it is used.
  for (const bool on : {false, true}) {
    StageSettings s;
    s.angle.fusion.blend = true;
    s.angle.fusion.gate_sigma = 1e3;
    s.angle.fusion.time_estimate = on;
    Recorder rec;
    AngleChain chain(s, nullptr, rec, nullptr);
    run(chain, [](AngleChain& c) {
      c.set_time_estimate(TorqueEstimate{0, 0.0, 1000.0, Health::kValid}, /*uses_can=*/false);
    });
    int used = 0;
    for (const CycleOutput& o : rec.outs)
      if (o.fused.used_mask & (1u << static_cast<int>(FusionSourceId::kExternal))) ++used;
    if (on) {
      EXPECT_GT(used, 0);
    } else {
      EXPECT_EQ(used, 0);
    }
  }
}

}  // namespace
}  // namespace torqued

namespace torqued {
namespace {
TEST(AngleChainSpark, SparkPhasedTablesOnlyWhenTheSparkAdvanceIsMapped) {
  // GIVEN a DBC with a spark advance signal WHEN the chain maps it THEN the in-cycle gas model gets its
  // spark-phased tables (3..22 at the default 10° centroid); without the mapping, or without any DBC, only
  // the base table it reads (LoadRls::ripple_first/last)
  const char* kDbc =
      "VERSION \"\"\n\nBU_: ECU\n\nBO_ 257 ENGINE_2: 8 ECU\n"
      " SG_ SparkAdvance : 39|8@0- (0.5,0) [-64|63.5] \"deg\" Vector__XXX\n";
  auto r = DbcDatabase::parse_string(kDbc, "spark.dbc");
  ASSERT_TRUE(r.db.has_value()) << (r.errors.empty() ? "" : r.errors.front());
  Recorder rec;
  StageSettings s;
  s.signals[static_cast<std::size_t>(Quantity::kSparkAdvance)] = {"ENGINE_2", "SparkAdvance", 100'000'000};
  const AngleChain mapped(s, &*r.db, rec, nullptr);
  ASSERT_TRUE(mapped.pipeline());
  EXPECT_EQ(mapped.pipeline()->load_rls().ripple_first(), 3);
  EXPECT_EQ(mapped.pipeline()->load_rls().ripple_last(), LoadRls::kRippleTables - 1);
  const AngleChain no_dbc(s, nullptr, rec, nullptr);
  s.signals[static_cast<std::size_t>(Quantity::kSparkAdvance)] = {};
  const AngleChain unmapped(s, &*r.db, rec, nullptr);
  for (const AngleChain* c : {&no_dbc, &unmapped}) {
    ASSERT_TRUE(c->pipeline());
    EXPECT_EQ(c->pipeline()->load_rls().ripple_first(), LoadRls::kRippleBase);
    EXPECT_EQ(c->pipeline()->load_rls().ripple_last(), LoadRls::kRippleBase);
  }
}
}  // namespace
}  // namespace torqued
