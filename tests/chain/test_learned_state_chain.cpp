// tests/chain/test_learned_state_chain.cpp: the learned state (friction law, tooth table, fuel model,
// measured crank-only error variance) survives the trip chain → LearnedState → state file text → parse →
// bounds check → a fresh chain, so that a second replay from the file gives exactly the outputs of a replay
// from the state in memory (a vehicle run starts from what a bench run learned). Uses the bundled
// demo recording: a learn run with the load signal (config/demo.yaml), then the vehicle configuration
// (config/demo_vehicle.yaml).
#include <gtest/gtest.h>

#include <cmath>
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

ReplayRun replay(const std::string& config, const LearnedState* in) {
  ReplayRun run;
  const LoadResult lr = load_config(config);
  EXPECT_TRUE(lr.config.has_value()) << config;
  if (!lr.config) return run;
  RunInputs inputs = open_inputs(*lr.config);
  EXPECT_TRUE(inputs.ok()) << inputs.error;
  NoSink sink;
  CycleTap tap;
  if (in) run.out = *in;
  run.r = run_fast_replay(inputs.settings, inputs.edges.get(), inputs.can.get(), inputs.can_offset_ns,
                          inputs.dbc_ptr(), sink, nullptr, &run.out, &tap);
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
  const std::string text = serialize_state(st, ctx.identity);
  std::string err;
  const auto parsed = parse_state(text, "round-trip", &err);
  ASSERT_TRUE(parsed) << err;
  ASSERT_TRUE(check_state(*parsed, ctx, "round-trip", &err)) << err;
  ASSERT_TRUE(parsed->fuel && parsed->crank_error_var && parsed->inertia);
  EXPECT_EQ(*parsed->inertia, *st.inertia);
  {  // exact round trip (%.17g), field by field (the struct has padding)
    const FuelTorqueState &a = *parsed->fuel, &b = *st.fuel;
    EXPECT_TRUE(a.physics);
    EXPECT_EQ(a.theta, b.theta);
    EXPECT_EQ(a.p, b.p);
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
  const ReplayRun mem = replay(kDir + "demo_vehicle.yaml", &st);
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
