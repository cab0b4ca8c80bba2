// BurnPhaseLearner (estimators/learners/burn_phase_learner.hpp): on the synthetic I4 whose combustion peak is
// later or earlier than its gas model's, the learned offset converges to the truth and removes the
// estimate's firing-order lag; a stale or absent MAP or spark advance does not move it; no allocation.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <vector>

#include "alloc_counter.hpp"
#include "burn_phase_learner.hpp"
#include "chauvin_kalman.hpp"
#include "synthetic_crank.hpp"

namespace torqued {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
constexpr double kModelPeakDeg = 24.0;  ///< the model's combustion peak after firing TDC before learning

/// Which signals the learner is told are fresh.
struct Fresh {
  bool map = true;
  bool spark = true;
};

struct LoopResult {
  double offset_deg = 0.0;
  int cycles_to_tolerance = -1;  ///< first cycle end after which |offset − truth| stayed ≤ tolerance
  double lag_deg = 0.0;          ///< E's firing-order lag behind the truth over the last 20 cycles (+ behind)
  BurnPhaseStats stats;
  std::size_t allocations = 0;
};

/// The default Kalman on the synthetic I4 (true widths, 0.3 µs jitter) whose combustion peak is
/// kModelPeakDeg + truth_deg after TDC, with a gas model that is the same engine's torque with its peak at
/// kModelPeakDeg + offset (zero mean): the model is exact at offset = truth_deg. With `learn` the learner's
/// offset is applied at each cycle end (the chain's feedback (6)); without, the offset stays 0.
LoopResult run_loop(double truth_deg, bool learn, Fresh fresh, double tolerance_deg) {
  test::SyntheticSpec truth;
  truth.cycles = 120;
  truth.burn_peak_rad = (kModelPeakDeg + truth_deg) * kDeg;
  truth.tooth_error_deg = 0.0;
  const test::SyntheticRun run = test::make_synthetic(truth);
  test::SyntheticSpec model = truth;
  const CrankKinematics kin(truth.engine);
  KalmanParams kp{};
  ChauvinKalman kf(truth.engine, truth.wheel, kp);
  kf.set_extended_load(run.load_nm);
  BurnPhaseParams bp{};
  bp.learn = true;
  BurnPhaseLearner learner(truth.engine, truth.wheel, bp);
  const int kk = 2 * truth.wheel.teeth();
  double offset = 0.0, model_mean = 0.0;
  auto set_model = [&](double off) {  // the model's zero-mean ripple at this offset
    model.burn_peak_rad = (kModelPeakDeg + off) * kDeg;
    model_mean = 0.0;
    for (int i = 0; i < 1440; ++i)
      model_mean += test::synthetic_t_ind(kin, model, i * 4.0 * kPi / 1440) / 1440;
  };
  set_model(0.0);
  LoopResult r;
  std::vector<double> est, tru, ang;
  int cycle = 0;
  for (std::size_t n = 0; n < run.samples.size(); ++n) {
    const ToothSample& s = run.samples[n];
    const double theta = s.angle_rad - truth.engine.tdc_offset_rad;  // the step after edge k is centred on it
    kf.set_model_torque(test::synthetic_t_ind(kin, model, theta) - model_mean, true);
    if (!kf.update(s)) continue;
    {
      const test::AllocationScope scope;
      learner.set_signals(fresh.map, fresh.spark, false);
      learner.update(kf.estimate_tooth(), kf.estimate().torque_nm, kf.output_model_nm(),
                     kf.estimate().health == Health::kValid && kf.model_active());
      if (s.tooth == kk - 1) (void)learner.end_cycle();
      r.allocations += scope.count();
    }
    if (s.tooth == kk - 1) {
      ++cycle;
      if (learn && learner.offset_deg() != offset) set_model(offset = learner.offset_deg());
      const bool within = std::abs(offset - truth_deg) <= tolerance_deg;
      if (!within) r.cycles_to_tolerance = -1;
      if (within && r.cycles_to_tolerance < 0) r.cycles_to_tolerance = cycle;
    }
    if (cycle >= truth.cycles - 20) {
      const std::size_t lagged = n - static_cast<std::size_t>(kp.smoother_lag);
      est.push_back(kf.estimate().torque_nm);
      tru.push_back(run.t_ind_nm[lagged]);
      ang.push_back(run.samples[lagged].angle_rad);
    }
  }
  std::complex<double> fe{0.0, 0.0}, ft{0.0, 0.0};  // order 2 per revolution (the I4's firing order)
  for (std::size_t i = 0; i < est.size(); ++i) {
    const std::complex<double> w = std::polar(1.0, -2.0 * ang[i]);
    fe += est[i] * w;
    ft += tru[i] * w;
  }
  r.lag_deg = std::arg(ft / fe) / 2.0 / kDeg;
  r.offset_deg = learn ? offset : learner.offset_deg();
  r.stats = learner.stats();
  return r;
}

constexpr double kOffsetTolDeg = 1.0;  ///< learned offset against the true burn shift
constexpr double kLagTolDeg = 0.3;     ///< the estimate's firing-order lag behind the truth
constexpr int kCycles = 30;            ///< cycles within which the offset reaches kOffsetTolDeg and stays

TEST(BurnPhaseLearner, ABurnLaterOrEarlierThanTheModelsIsLearnedAndItsFiringOrderLagRemoved) {
  for (const double truth : {6.0, -6.0}) {
    // GIVEN the synthetic I4 at 2000 rpm whose combustion peak (30°, then 18° after TDC) is 6° later (then
    // earlier) than the gas model's (24°). (The observable is the firing-order phase, not the peak itself: a
    // model at 20° against a truth at 12° settles at 16°, where this engine's order-2 phase no longer moves
    // with an earlier peak, the burn squeezed against TDC; docs/angle_estimators.md (7).)
    // WHEN the learner's offset feeds the model at each cycle end, or does not
    const LoopResult on = run_loop(truth, true, Fresh{}, kOffsetTolDeg);
    const LoopResult off = run_loop(truth, false, Fresh{}, kOffsetTolDeg);
    std::printf(
        "true shift %+.0f deg: learned %+.2f deg within %.1f deg after %d cycles, lag %+.2f deg "
        "(without the learner %+.2f deg)\n",
        truth, on.offset_deg, kOffsetTolDeg, on.cycles_to_tolerance, on.lag_deg, off.lag_deg);
    // THEN the offset is within 1° of the true shift from cycle 30 on, and converged
    EXPECT_NEAR(on.offset_deg, truth, kOffsetTolDeg);
    EXPECT_GE(on.cycles_to_tolerance, 1);
    EXPECT_LE(on.cycles_to_tolerance, kCycles);
    EXPECT_EQ(on.stats.state, BurnPhaseState::kConverged);
    // and the estimate's firing-order lag is within 0.3°, against beyond it without the learner
    EXPECT_LE(std::abs(on.lag_deg), kLagTolDeg);
    EXPECT_GT(std::abs(off.lag_deg), kLagTolDeg);
    // and the real-time calls did not allocate
    EXPECT_EQ(on.allocations, 0u);
  }
}

TEST(BurnPhaseLearner, AStaleOrAbsentMapOrSparkAdvanceDoesNotMoveIt) {
  // GIVEN the engine whose burn is 8° later than the model's (as above)
  // WHEN the MAP, then the spark advance, is stale for the whole run
  const LoopResult no_map = run_loop(8.0, true, Fresh{.map = false, .spark = true}, kOffsetTolDeg);
  const LoopResult no_spark = run_loop(8.0, true, Fresh{.map = true, .spark = false}, kOffsetTolDeg);
  // THEN the offset stays 0, no cycle was used, every complete cycle is counted against the missing signal
  for (const LoopResult* r : {&no_map, &no_spark}) {
    EXPECT_EQ(r->offset_deg, 0.0);
    EXPECT_EQ(r->stats.cycles_used, 0u);
    EXPECT_EQ(r->stats.state, BurnPhaseState::kNotUsed);
  }
  EXPECT_GT(no_map.stats.cycles_no_map, 100u);
  EXPECT_GT(no_spark.stats.cycles_no_spark, 100u);
}

TEST(BurnPhaseLearner, ImportRespectsTheBounds) {
  // GIVEN a learner with the default bounds (±12°)
  const test::SyntheticSpec sp;
  BurnPhaseLearner l(sp.engine, sp.wheel, BurnPhaseParams{});
  // WHEN a persisted offset inside, then outside, the bounds is imported
  // THEN the first is taken with its cycles, the second refused and the offset unchanged; the state says the
  // offset rests on the import (not "not used") until a cycle of this run is used, and reset forgets it
  EXPECT_EQ(l.stats().state, BurnPhaseState::kNotUsed);
  EXPECT_TRUE(l.import_state(3.5, 200.0));
  EXPECT_EQ(l.offset_deg(), 3.5);
  EXPECT_EQ(l.cycles_behind(), 200u);
  EXPECT_EQ(l.stats().state, BurnPhaseState::kImported);
  EXPECT_FALSE(l.import_state(20.0, 10.0));
  EXPECT_FALSE(l.import_state(std::nan(""), 10.0));
  EXPECT_EQ(l.offset_deg(), 3.5);
  EXPECT_EQ(l.stats().state, BurnPhaseState::kImported);
  l.reset();
  EXPECT_EQ(l.stats().state, BurnPhaseState::kNotUsed);
}

}  // namespace
}  // namespace torqued
