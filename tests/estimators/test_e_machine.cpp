// estimators/core/e_machine.hpp: the electric machine's CAN torque folded into the net load (the hybrid
// input), and the time pipeline fed the folded load. Analytic truth: T_net = T_load − sign · ratio · T_em
// (exact, 1e-12).
#include <gtest/gtest.h>

#include "e_machine.hpp"
#include "time_pipeline.hpp"

namespace torqued {
namespace {

EMachineParams bound(double ratio, double sign, bool sole) {
  EMachineParams p;
  p.bound = true;
  p.ratio = ratio;
  p.sign = sign;
  p.sole_load = sole;
  return p;
}

TEST(EMachine, NotBoundIsTheLoadSignalAlone) {
  // GIVEN no machine signal mapped WHEN a load and a machine value are offered THEN the machine is ignored.
  const NetLoad n = fold_e_machine(EMachineParams{}, 42.0, true, 100.0, true);
  EXPECT_DOUBLE_EQ(n.torque_nm, 42.0);
  EXPECT_TRUE(n.known);
  EXPECT_FALSE(n.em_stale);
  EXPECT_FALSE(fold_e_machine(EMachineParams{}, 42.0, false, 100.0, true).known);
}

TEST(EMachine, SoleLoadGivesMinusRatioTimesMachineTorque) {
  // GIVEN a machine through a 2.5:1 gear, sole load WHEN it generates 20 N m at its shaft (CAN −20, sign +1)
  // THEN the crank sees 50 N m of absorbing load, with no load signal at all.
  const NetLoad n = fold_e_machine(bound(2.5, 1.0, true), 0.0, false, -20.0, true);
  EXPECT_TRUE(n.known);
  EXPECT_NEAR(n.torque_nm, 50.0, 1e-12);
  EXPECT_NEAR(n.em_crank_nm, -50.0, 1e-12);
  // Motoring: the machine drives the crank (+12 N m at the shaft) -> negative net load.
  EXPECT_NEAR(fold_e_machine(bound(2.5, 1.0, true), 0.0, false, 12.0, true).torque_nm, -30.0, 1e-12);
}

TEST(EMachine, SignFlipsTheConvention) {
  // GIVEN an inverter that reports generating torque positive (sign −1) WHEN it reports +20 N m THEN the
  // crank sees +20 · ratio of absorbing load, as the +1 convention with −20.
  const NetLoad a = fold_e_machine(bound(3.0, -1.0, true), 0.0, false, 20.0, true);
  const NetLoad b = fold_e_machine(bound(3.0, 1.0, true), 0.0, false, -20.0, true);
  EXPECT_NEAR(a.torque_nm, 60.0, 1e-12);
  EXPECT_NEAR(a.torque_nm, b.torque_nm, 1e-12);
}

TEST(EMachine, WithALoadSignalTheMachineIsSubtracted) {
  // GIVEN a dynamometer load of 80 N m and a machine boosting 15 N m (ratio 1) THEN the net load is 65 N m.
  const NetLoad n = fold_e_machine(bound(1.0, 1.0, false), 80.0, true, 15.0, true);
  EXPECT_TRUE(n.known);
  EXPECT_NEAR(n.torque_nm, 65.0, 1e-12);
  // Not sole load and no load signal: the net load is not known (the crank-only chain must estimate it).
  EXPECT_FALSE(fold_e_machine(bound(1.0, 1.0, false), 0.0, false, 15.0, true).known);
}

TEST(EMachine, StaleMachineMakesTheNetLoadUnknown) {
  // GIVEN a bound machine whose value is stale (or NaN) THEN the net load is unknown and flagged stale,
  // whatever the load signal says: what rests on it must hold (STALE_CAN), as with a stale load signal.
  for (const bool sole : {true, false}) {
    const NetLoad n = fold_e_machine(bound(1.0, 1.0, sole), 80.0, true, 15.0, false);
    EXPECT_FALSE(n.known);
    EXPECT_TRUE(n.em_stale);
    EXPECT_DOUBLE_EQ(n.em_crank_nm, 0.0);
  }
  const NetLoad nan = fold_e_machine(bound(1.0, 1.0, true), 0.0, false, std::nan(""), true);
  EXPECT_FALSE(nan.known);
  EXPECT_TRUE(nan.em_stale);
}

TEST(EMachine, EngineSignalsOverloadReadsTheSnapshot) {
  EngineSignals sig;
  sig.em_torque_nm = -10.0;
  sig.em_torque_valid = true;
  const NetLoad n = fold_e_machine(bound(2.0, 1.0, true), sig);
  EXPECT_TRUE(n.known);
  EXPECT_NEAR(n.torque_nm, 20.0, 1e-12);
}

TEST(EMachine, TimePipelineSeesTheFoldedLoadAndStaleness) {
  // GIVEN the time pipeline with a sole-load machine (ratio 2) WHEN a step has the machine generating 10 N m
  // THEN the estimators are given 20 N m of load; WHEN the machine value goes stale THEN the load input is
  // stale.
  TimePipeline tp(TimePipelineParams{}, TimeEstimatorParams{}, EngineGeometry{});
  tp.set_e_machine(bound(2.0, 1.0, true));
  EngineSignals sig;
  sig.em_torque_nm = -10.0;
  sig.em_torque_valid = true;
  const TimePipelineOutput& a = tp.step(1'000'000, sig);
  EXPECT_EQ(a.input.load, InputStatus::kOk);
  EXPECT_NEAR(a.input.load_torque_nm, 20.0, 1e-12);
  sig.em_torque_valid = false;
  const TimePipelineOutput& b = tp.step(2'000'000, sig);
  EXPECT_EQ(b.input.load, InputStatus::kStale);
  // Not bound: the load signal alone, as before the hybrid input existed.
  TimePipeline plain(TimePipelineParams{}, TimeEstimatorParams{}, EngineGeometry{});
  sig.load_torque_nm = 33.0;
  sig.load_torque_valid = true;
  sig.em_torque_valid = true;
  EXPECT_NEAR(plain.step(1'000'000, sig).input.load_torque_nm, 33.0, 1e-12);
}

}  // namespace
}  // namespace torqued
