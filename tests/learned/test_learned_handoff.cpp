// tests/learned/test_learned_handoff.cpp: the learned state's hand-off from the angle thread to the
// supervisor (LatestValue<LearnedState>, learned/learned_state.hpp, publish/angle_stage.hpp): a reader never
// sees a torn state under a concurrent writer (also run under TSan: tsan.test_learned_handoff), and the angle
// stage publishes what the chain holds.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

#include "angle_stage.hpp"
#include "latest_value.hpp"
#include "learned_state.hpp"

namespace torqued {
namespace {

/// State number i: every field a known function of k = i % 16, each optional one present on its own pattern,
/// the tooth table 1..720 long; saved_at_t_ns = i.
LearnedState pattern(std::int64_t i) {
  const std::int64_t k = i % 16;
  const double x = static_cast<double>(k) + 0.25;
  LearnedState s;
  if (k % 2 == 0) s.friction = std::array<double, 4>{x, x + 1, x + 2, x + 3};
  if (k % 3 == 0) s.friction_idle = std::array<double, 2>{-x, 2 * x};
  if (k % 5 != 0) s.friction_residual = std::array<double, 2>{x / 4, x};
  const std::size_t n = k == 15 ? kMaxToothCorrections : 1 + 45 * static_cast<std::size_t>(k);
  for (std::size_t j = 0; j < n; ++j) s.tooth_corrections_rad.push_back(x * 1000.0 + static_cast<double>(j));
  if (k % 7 != 0) {
    FuelTorqueState f;
    f.theta = {x, -x};
    f.p = {x, x + 0.5, x + 0.5, x + 1};
    f.resid_var = 3 * x;
    f.references = static_cast<std::uint32_t>(k);
    f.cover.sd = x / 8;
    f.cover.n = static_cast<std::uint32_t>(2 * k);
    s.fuel = f;
  }
  if (k % 4 != 1) s.crank_error_var = x * x;
  if (k % 6 != 5) s.inertia = std::array<double, 3>{x, 1 / (x + 1), x / 2};
  s.saved_at_t_ns = i;
  char id[64];
  std::snprintf(id, sizeof id, "state %lld", static_cast<long long>(k));
  s.identity = id;
  s.version = static_cast<int>(k % 3);
  return s;
}

/// Every field of `got` equals state number got.saved_at_t_ns's: nothing mixed from two states.
void expect_consistent(const LearnedState& got) {
  const LearnedState want = pattern(got.saved_at_t_ns);
  EXPECT_EQ(got.friction, want.friction);
  EXPECT_EQ(got.friction_idle, want.friction_idle);
  EXPECT_EQ(got.friction_residual, want.friction_residual);
  EXPECT_EQ(got.tooth_corrections_rad, want.tooth_corrections_rad);
  ASSERT_EQ(got.fuel.has_value(), want.fuel.has_value());
  if (want.fuel) {
    EXPECT_EQ(got.fuel->theta, want.fuel->theta);
    EXPECT_EQ(got.fuel->p, want.fuel->p);
    EXPECT_EQ(got.fuel->resid_var, want.fuel->resid_var);
    EXPECT_EQ(got.fuel->references, want.fuel->references);
    EXPECT_EQ(got.fuel->cover.sd, want.fuel->cover.sd);
    EXPECT_EQ(got.fuel->cover.n, want.fuel->cover.n);
  }
  EXPECT_EQ(got.crank_error_var, want.crank_error_var);
  EXPECT_EQ(got.inertia, want.inertia);
  EXPECT_EQ(got.identity, want.identity);
  EXPECT_EQ(got.version, want.version);
}

TEST(LearnedHandoff, ConcurrentWriterNeverGivesATornState) {
  // GIVEN a writer storing states 1, 2, 3, ... (6 kB each, 16 patterns) with gaps from none to 1.75 times a
  // store's duration (the angle stage stores one per cycle: 20 ms at 6000 rpm) WHEN the reader takes 2000 of
  // them (or 2 s passed) THEN each is one whole state (every field consistent with its number), newer than
  // the one before. (A reader without the sequence re-check after its copy fails here in most runs, even on a
  // loaded machine; the TSan tier checks the hand-off for data races.)
  LatestValue<LearnedState> slot;
  std::array<LearnedState, 16> states;
  for (std::size_t k = 0; k < states.size(); ++k) states[k] = pattern(static_cast<std::int64_t>(k));
  std::atomic<bool> stop{false};
  std::thread w([&] {
    using Clock = std::chrono::steady_clock;
    for (std::int64_t i = 1; !stop.load(std::memory_order_relaxed); ++i) {
      LearnedState& s = states[static_cast<std::size_t>(i % 16)];
      s.saved_at_t_ns = i;
      const auto t0 = Clock::now();
      slot.store(s);
      // A gap of 0 to 1.75 times this store's duration (so also under TSan, where stores are much slower): a
      // reader's copy can start in one and be overtaken by the next store.
      const auto t1 = Clock::now();
      const auto until = t1 + (t1 - t0) * (i % 8) / 4;
      while (Clock::now() < until) {
      }
    }
  });
  int got = 0;
  std::int64_t last = 0;
  LearnedState out;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (got < 2000 && std::chrono::steady_clock::now() < until) {
    if (!slot.load_new(out)) continue;
    ++got;
    EXPECT_GT(out.saved_at_t_ns, last);
    last = out.saved_at_t_ns;
    expect_consistent(out);
    if (::testing::Test::HasFailure()) break;
  }
  stop = true;
  w.join();
  RecordProperty("states_read", got);
  EXPECT_GE(got, 30) << "the reader got too few states to say anything";
}

TEST(LearnedHandoff, AngleStagePublishesTheImportedStateOnce) {
  // GIVEN an angle stage WHEN a tooth table and a friction law are imported THEN the supervisor's slot holds
  // exactly them, once; nothing before.
  struct NoSink final : SampleSink {
    void emit(const dds::AnySample&) noexcept override {}
  } sink;
  StageSettings s;
  AngleStage stage(s, nullptr, sink, nullptr);
  LearnedState out;
  EXPECT_FALSE(stage.learned().load_new(out)) << "nothing learned or imported yet";
  LearnedState st;
  for (int i = 0; i < 58; ++i) st.tooth_corrections_rad.push_back(1e-4 * ((i % 7) - 3));
  st.friction = std::array<double, 4>{10.0, 0.001, 1e-6, 0.0};
  ASSERT_NE(stage.import_state(st).find("58 tooth corrections"), std::string::npos);
  ASSERT_TRUE(stage.learned().load_new(out));
  EXPECT_EQ(out.tooth_corrections_rad, st.tooth_corrections_rad);
  EXPECT_EQ(out.friction, st.friction);
  EXPECT_FALSE(stage.learned().load_new(out)) << "each snapshot once";
}

}  // namespace
}  // namespace torqued
