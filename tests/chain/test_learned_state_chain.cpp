// tests/chain/test_learned_state_chain.cpp: the learned state (friction law, tooth table, fuel model,
// measured crank-only error variance) survives the trip chain → LearnedState → state file text → parse →
// bounds check → a fresh chain, so that a second replay from the file gives exactly the outputs of a replay
// from the state in memory (a vehicle run starts from what a bench run learned). Uses the bundled
// demo recording: a learn run with the load signal (config/demo.yaml), then the vehicle configuration
// (config/demo_vehicle.yaml).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "config_loader.hpp"
#include "fast_replay.hpp"
#include "replay_inputs.hpp"
#include "state_store.hpp"

namespace torqued {
namespace {

const std::string kDir = std::string(TORQUED_SOURCE_DIR) + "/config/";

struct NoSink final : SampleSink {
  void emit(const dds::AnySample&) noexcept override {}
};

/// Every cycle-end record's values, as raw bytes of the doubles (exact comparison).
struct CycleTap final : AngleChainSink {
  std::vector<double> v;
  void on_tooth(const ChainTooth&) noexcept override {}
  void on_segment(const ChainSegment& s) noexcept override {
    const CycleOutput& o = *s.out;
    for (const TorqueEstimate* e : {&o.brake, &o.indicated, &o.friction, &o.load, &o.indicated_crank}) {
      v.push_back(e->torque_nm);
      v.push_back(e->uncertainty);
    }
    v.push_back(o.fused.brake_nm);
  }
};

struct ReplayRun {
  ReplayResult r;
  LearnedState out;
  std::vector<double> values;
};

/// Replays `config` from `state` (in: the state to start from; out: what the run learned) into `tap`.
ReplayResult replay_into(const std::string& config, LearnedState& state, AngleChainSink& tap) {
  const LoadResult lr = load_config(config);
  EXPECT_TRUE(lr.config.has_value()) << config;
  if (!lr.config) return {};
  RunInputs inputs = open_inputs(*lr.config);
  EXPECT_TRUE(inputs.ok()) << inputs.error;
  NoSink sink;
  return run_fast_replay(inputs.settings, inputs.edges.get(), inputs.can.get(), inputs.can_offset_ns,
                         inputs.dbc_ptr(), sink, nullptr, &state, &tap);
}

ReplayRun replay(const std::string& config, const LearnedState* in) {
  ReplayRun run;
  CycleTap tap;
  if (in) run.out = *in;
  run.r = replay_into(config, run.out, tap);
  run.values = std::move(tap.v);
  return run;
}

TEST(LearnedStateChain, FileRoundTripGivesIdenticalOutputsOnTheSecondReplay) {
  // GIVEN a learn run on the demo recording with its load signal
  const ReplayRun learn = replay(kDir + "demo.yaml", nullptr);
  ASSERT_TRUE(learn.r.learned);
  const LearnedState& st = learn.out;
  ASSERT_TRUE(st.friction && st.fuel && st.crank_error_var && st.inertia);
  EXPECT_EQ(st.tooth_corrections_rad.size(), 58u);
  // The demo's spec J is the simulator's own: the learned scale must find 1 (its 1σ is what it claims).
  EXPECT_NEAR((*st.inertia)[0], 1.0, 3.0 / std::sqrt((*st.inertia)[1])) << "inertia scale";
  EXPECT_GT(st.fuel->references, 30u) << "the fuel model learned from reference cycles";
  EXPECT_GT(*st.crank_error_var, 0.0);
  // WHEN it is written as a state file and read back (format, checksum, identity, physical bounds)
  const LoadResult lr = load_config(kDir + "demo_vehicle.yaml");
  ASSERT_TRUE(lr.config);
  const StateContext ctx = state_context_from(*lr.config);
  // (a bench run's fuel model has no driveline-open reference: a cross-covariance with the accessories' bias
  // is set so that the round trip has one to carry)
  LearnedState st_b = st;
  st_b.fuel->pxb = {1e-4, -2e-5, 3.5, -7.25};
  const std::string text = serialize_state(st_b, ctx.identity);
  std::string err;
  const auto parsed = parse_state(text, "round-trip", &err);
  ASSERT_TRUE(parsed) << err;
  ASSERT_TRUE(check_state(*parsed, ctx, "round-trip", &err)) << err;
  ASSERT_TRUE(parsed->fuel && parsed->crank_error_var && parsed->inertia);
  EXPECT_EQ(*parsed->inertia, *st.inertia);
  {  // exact round trip (%.17g), field by field (the struct has padding)
    const FuelTorqueState &a = *parsed->fuel, &b = *st_b.fuel;
    EXPECT_TRUE(a.physics);
    EXPECT_EQ(a.theta, b.theta);
    EXPECT_EQ(a.p, b.p);
    EXPECT_EQ(a.pxb, b.pxb);
    EXPECT_EQ(a.cells, b.cells);
    EXPECT_EQ(a.resid_var, b.resid_var);
    EXPECT_EQ(a.references, b.references);
    EXPECT_EQ(a.cover.sd, b.cover.sd);
    EXPECT_EQ(a.cover.n, b.cover.n);
    EXPECT_EQ(a.eta_ref, b.eta_ref);
    EXPECT_EQ(a.p_exh_nm, b.p_exh_nm);
    EXPECT_EQ(a.p2, b.p2);
  }
  EXPECT_EQ(*parsed->crank_error_var, *st.crank_error_var);
  // THEN a vehicle run (no load signal) from the parsed file equals one from the state in memory, exactly,
  const ReplayRun mem = replay(kDir + "demo_vehicle.yaml", &st_b);
  const ReplayRun file = replay(kDir + "demo_vehicle.yaml", &*parsed);
  EXPECT_NE(mem.r.imported.find("fuel model"), std::string::npos) << mem.r.imported;
  EXPECT_NE(mem.r.imported.find("crank-only error variance"), std::string::npos) << mem.r.imported;
  EXPECT_NE(mem.r.imported.find("inertia scale"), std::string::npos) << mem.r.imported;
  ASSERT_GT(mem.values.size(), 1000u);
  ASSERT_EQ(mem.values.size(), file.values.size());
  EXPECT_EQ(std::memcmp(mem.values.data(), file.values.data(), mem.values.size() * sizeof(double)), 0);
  // AND the fuel part of the state is what makes the difference: without it the outputs change.
  LearnedState no_fuel = *parsed;
  no_fuel.fuel.reset();
  const ReplayRun without = replay(kDir + "demo_vehicle.yaml", &no_fuel);
  ASSERT_EQ(without.values.size(), mem.values.size());
  EXPECT_NE(std::memcmp(mem.values.data(), without.values.data(), mem.values.size() * sizeof(double)), 0);
  // AND the state learned by the second run carries the fuel model forward (references keep counting or
  // stay).
  ASSERT_TRUE(file.out.fuel);
  EXPECT_GE(file.out.fuel->references, parsed->fuel->references);
}

/// Per cycle end: whether the fused brake torque was published (valid) and its claimed 1σ.
struct FusedTap final : AngleChainSink {
  int cycles = 0, published = 0;
  double sd_sum = 0.0;
  void on_tooth(const ChainTooth&) noexcept override {}
  void on_segment(const ChainSegment& s) noexcept override {
    if (!s.out->cycle_end) return;
    ++cycles;
    if (s.out->fused.health != Health::kValid) return;
    ++published;
    sd_sum += s.out->fused.sd_nm;
  }
};

FusedTap replay_fused(const std::string& config, const LearnedState& in) {
  FusedTap tap;
  LearnedState st = in;
  (void)replay_into(config, st, tap);
  return tap;
}

TEST(LearnedStateChain, ALearnedFuelModelOnAFrictionLawShortOfItsObservationsIsPublishedNotWithheld) {
  // GIVEN the state a bench run learned (fuel model with its references, friction law), and the same state
  // whose friction law was saved after fewer motoring observations than friction.min_observations (a
  // vehicle's few coast-down cycles: restored "not converged")
  const ReplayRun learn = replay(kDir + "demo.yaml", nullptr);
  ASSERT_TRUE(learn.r.learned);
  ASSERT_TRUE(learn.out.fuel && learn.out.friction);
  ASSERT_GE(learn.out.fuel->references, 30u);
  LearnedState partial = learn.out;
  partial.friction_observations = 2.0;
  // WHEN the vehicle configuration (no load signal) replays from each
  const FusedTap full = replay_fused(kDir + "demo_vehicle.yaml", learn.out);
  const FusedTap part = replay_fused(kDir + "demo_vehicle.yaml", partial);
  // THEN the fused brake torque is published on as many cycles from the partial law (it was withheld on
  // nearly all of them: the fuel model's slot took the friction's "not converged"), with the friction's 1σ
  // added to its claim.
  ASSERT_GT(full.cycles, 300);
  EXPECT_EQ(part.cycles, full.cycles);
  EXPECT_GE(full.published, 95 * full.cycles / 100);
  EXPECT_GE(part.published, 95 * part.cycles / 100);
  ASSERT_GT(part.published, 0);
  EXPECT_GT(part.sd_sum / part.published, full.sd_sum / full.published);
}

/// Per tooth the in-cycle Kalman value (NaN unless its health is valid: the in-cycle quality the daemon
/// publishes as METHOD_KALMAN health); per segment whether it was valid at the segment's last tooth.
struct QualityTap final : AngleChainSink {
  std::vector<double> kalman;
  std::vector<int> incycle_valid;
  int last_valid = 0;
  void on_tooth(const ChainTooth& t) noexcept override {
    last_valid = t.estimates != nullptr && t.estimates->kalman_ind.health == Health::kValid ? 1 : 0;
    kalman.push_back(last_valid != 0 ? t.estimates->kalman_ind.torque_nm : std::nan(""));
  }
  void on_segment(const ChainSegment&) noexcept override { incycle_valid.push_back(last_valid); }
};

struct QualityRun {
  ReplayResult r;
  LearnedState out;
  QualityTap tap;
};

void replay_quality(const std::string& config, const LearnedState* in, QualityRun& run) {
  const LoadResult lr = load_config(config);
  ASSERT_TRUE(lr.config.has_value()) << config;
  RunInputs inputs = open_inputs(*lr.config);
  ASSERT_TRUE(inputs.ok()) << inputs.error;
  NoSink sink;
  if (in) run.out = *in;
  run.r = run_fast_replay(inputs.settings, inputs.edges.get(), inputs.can.get(), inputs.can_offset_ns,
                          inputs.dbc_ptr(), sink, nullptr, &run.out, &run.tap);
}

/// RMS of a − b over the entries from `from` on where both are valid (finite).
double rms_diff(const std::vector<double>& a, const std::vector<double>& b, std::size_t from) {
  double ss = 0.0;
  std::size_t n = 0;
  for (std::size_t i = from; i < a.size() && i < b.size(); ++i) {
    if (!std::isfinite(a[i]) || !std::isfinite(b[i])) continue;
    ss += (a[i] - b[i]) * (a[i] - b[i]);
    ++n;
  }
  return n > 0 ? std::sqrt(ss / static_cast<double>(n)) : 1e300;
}

TEST(LearnedStateChain, ImportedToothTableTheEngineContradictsIsDistrustedAndRelearned) {
  // GIVEN the demo's clean learned tooth table and a plausible corrupt one: every correction at 0.9 x the
  // bound the state check enforces (alternating in sign per tooth with a pseudo-random size of 0.6 .. 1),
  // written as a state file with a valid checksum, which parses and passes check_state.
  const std::string cfg = kDir + "demo.yaml";
  QualityRun fresh, clean, corrupt;
  replay_quality(cfg, nullptr, fresh);
  ASSERT_TRUE(fresh.r.learned);
  ASSERT_EQ(fresh.out.tooth_corrections_rad.size(), 58u);
  const LoadResult lr = load_config(cfg);
  ASSERT_TRUE(lr.config);
  const StateContext ctx = state_context_from(*lr.config);
  LearnedState bad;
  bad.identity = ctx.identity;
  bad.tooth_corrections_rad.assign(58, 0.0);
  std::uint32_t lcg = 12345u;
  for (std::size_t p = 1; p < 58; ++p) {
    lcg = lcg * 1664525u + 1013904223u;
    const double u = 0.6 + 0.4 * static_cast<double>(lcg >> 8) / 16777216.0;
    bad.tooth_corrections_rad[p] = (p % 2 == 0 ? 0.9 : -0.9) * u * ctx.max_tooth_corr_rad;
  }
  std::string err;
  const auto parsed = parse_state(serialize_state(bad, ctx.identity), "corrupt", &err);
  ASSERT_TRUE(parsed) << err;
  ASSERT_TRUE(check_state(*parsed, ctx, "corrupt", &err)) << err;
  LearnedState clean_teeth;  // the clean table alone, the same comparison for the clean case
  clean_teeth.tooth_corrections_rad = fresh.out.tooth_corrections_rad;
  // WHEN the demo is replayed from each
  replay_quality(cfg, &clean_teeth, clean);
  replay_quality(cfg, &*parsed, corrupt);
  EXPECT_NE(corrupt.r.imported.find("58 tooth corrections"), std::string::npos) << corrupt.r.imported;
  const std::size_t n = fresh.tap.incycle_valid.size();
  ASSERT_GT(n, 200u);
  ASSERT_EQ(corrupt.tap.incycle_valid.size(), n);
  const std::size_t teeth = fresh.tap.kalman.size();
  ASSERT_EQ(corrupt.tap.kalman.size(), teeth);
  ASSERT_EQ(clean.tap.kalman.size(), teeth);
  // THEN the clean table is kept (no false alarm),
  EXPECT_EQ(clean.r.counters.tooth_tables_distrusted, 0u);
  // AND the corrupt one is flagged within the check's cycles: the in-cycle quality goes to "not converged"
  // (relearning) at a segment within the first 20 cycles (4 segments each) and is valid again later,
  EXPECT_EQ(corrupt.r.counters.tooth_tables_distrusted, 1u);
  std::size_t flagged_at = n;
  for (std::size_t i = 1; i < n && flagged_at == n; ++i)
    if (corrupt.tap.incycle_valid[i - 1] == 1 && corrupt.tap.incycle_valid[i] == 0) flagged_at = i;
  EXPECT_LT(flagged_at, 4u * 20u + 8u) << "segment at which the in-cycle quality dropped";
  std::printf("in-cycle quality dropped at segment %zu of %zu\n", flagged_at, n);
  EXPECT_EQ(corrupt.tap.incycle_valid[n - 1], 1);
  // AND the in-cycle Kalman torque over the second half returns to the fresh run's (15.9 N m RMS against
  // the tooth truth, docs/daemon.md; the corrupt table kept gave 58 N m), as close as the clean table's run
  // (which differs from the fresh one by its head start only).
  const double d_corrupt = rms_diff(corrupt.tap.kalman, fresh.tap.kalman, teeth / 2);
  const double d_clean = rms_diff(clean.tap.kalman, fresh.tap.kalman, teeth / 2);
  std::printf(
      "in-cycle Kalman RMS vs the fresh run, second half: corrupt table %.4f N m, clean table %.4f N m\n",
      d_corrupt, d_clean);
  EXPECT_LT(d_corrupt, std::max(2.0, 2.0 * d_clean));
  // AND the state saved at the end no longer holds the corrupt table (the relearned one, or none).
  ASSERT_EQ(corrupt.out.tooth_corrections_rad.size(), fresh.out.tooth_corrections_rad.size());
  double max_dev = 0.0;
  for (std::size_t p = 0; p < 58; ++p)
    max_dev = std::max(max_dev,
                       std::abs(corrupt.out.tooth_corrections_rad[p] - fresh.out.tooth_corrections_rad[p]));
  EXPECT_LT(max_dev, 0.1 * ctx.max_tooth_corr_rad);
}

TEST(LearnedStateChain, OutOfBoundsFuelModelIsRejected) {
  // GIVEN a fuel model with an efficiency above the Otto cycle's at r = 10.5 (0.61) or a non-PSD covariance
  // THEN check_state rejects it naming the value; older version 2 files without the new lines still load.
  const LoadResult lr = load_config(kDir + "demo_vehicle.yaml");
  ASSERT_TRUE(lr.config);
  const StateContext ctx = state_context_from(*lr.config);
  EXPECT_NEAR(ctx.max_eta, 1.0 - std::pow(10.5, -0.4), 1e-12);
  LearnedState s;
  s.identity = ctx.identity;
  FuelTorqueState f;  // the two-parameter view (what an older file holds; the physics model keeps it current)
  f.physics = false;
  f.eta_ref = 0.4;
  f.p_exh_nm = 10.0;
  f.p2 = {1e-4, 0.0, 0.0, 1.0};
  f.resid_var = 4.0;
  f.references = 100;
  s.fuel = f;
  std::string err;
  EXPECT_TRUE(check_state(s, ctx, "ok", &err)) << err;
  s.fuel->eta_ref = 0.7;
  EXPECT_FALSE(check_state(s, ctx, "eta", &err));
  EXPECT_NE(err.find("efficiency 0.7"), std::string::npos) << err;
  s.fuel = f;
  s.fuel->p2 = {1e-4, 1.0, 1.0, 1.0};  // |P01|^2 > P00 P11
  EXPECT_FALSE(check_state(s, ctx, "psd", &err));
  EXPECT_NE(err.find("positive semi-definite"), std::string::npos) << err;
  s.fuel = f;
  s.fuel->cover.sd = 1e5;  // the residual scale beyond any torque of this engine
  EXPECT_FALSE(check_state(s, ctx, "cover", &err));
  EXPECT_NE(err.find("residual scale 100000"), std::string::npos) << err;
  // The residual scale round-trips exactly; a fuel_model line without it (older files) loads with none.
  s.fuel = f;
  s.fuel->cover.sd = 0.73456789012345678;
  s.fuel->cover.n = 321;
  const auto rt = parse_state(serialize_state(s, ctx.identity), "rt", &err);
  ASSERT_TRUE(rt && rt->fuel) << err;
  EXPECT_EQ(rt->fuel->cover.sd, s.fuel->cover.sd);
  EXPECT_EQ(rt->fuel->cover.n, 321u);
  const std::string old_fuel = "torqued-state 1\nfuel_model 0.4 10 1e-4 0 0 1 4 100\n";
  const auto of = parse_state(old_fuel, "old_fuel", &err);
  ASSERT_TRUE(of && of->fuel) << err;
  EXPECT_EQ(of->fuel->cover.sd, 0.0);
  EXPECT_EQ(of->fuel->references, 100u);
  // ... and the fuel model takes it: the physics model from the old efficiency and pumping term.
  EXPECT_FALSE(of->fuel->physics);
  EXPECT_TRUE(check_state(*of, ctx, "old_fuel", &err)) << err;
  FuelTorque ft(lr.config->engine, FuelTorqueParams{});
  ASSERT_TRUE(ft.import_state(*of->fuel));
  EXPECT_TRUE(ft.state().physics);
  EXPECT_NEAR(ft.state().eta_ref, 0.4, 1e-12);
  EXPECT_NEAR(ft.state().p_exh_nm, 10.0, 1e-9);
  EXPECT_EQ(ft.state().references, 100u);
  // A physics line (as written now) round-trips exactly, with its cell counts.
  LearnedState ph;
  ph.identity = ctx.identity;
  FuelTorqueState g = ft.state();
  g.cells[5] = 17;
  g.theta[3] = 12345.678901234567;
  ph.fuel = g;
  const auto pr = parse_state(serialize_state(ph, ctx.identity), "physics", &err);
  ASSERT_TRUE(pr && pr->fuel) << err;
  EXPECT_TRUE(pr->fuel->physics);
  EXPECT_EQ(pr->fuel->theta, g.theta);
  EXPECT_EQ(pr->fuel->p, g.p);
  EXPECT_EQ(pr->fuel->cells, g.cells);
  s.fuel = f;
  s.crank_error_var = -1.0;
  EXPECT_FALSE(check_state(s, ctx, "var", &err));
  // An older version 2 text (no fuel_model, no crank_error_var) parses.
  LearnedState old;
  old.friction = std::array<double, 4>{1.0, 0.0, 0.0, 0.0};
  const auto p = parse_state(serialize_state(old, ctx.identity), "old", &err);
  ASSERT_TRUE(p) << err;
  EXPECT_FALSE(p->fuel);
  EXPECT_FALSE(p->crank_error_var);
}

}  // namespace
}  // namespace torqued
