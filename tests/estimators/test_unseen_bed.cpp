// Accuracy targets without a load signal on a short subset of the unseen-engines bed (report engines only,
// short evaluated runs). Full table: build/tools/torque-accuracy --bed unseen
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "pipeline_eval.hpp"
#include "unseen_engines.hpp"

namespace eval = torqued::eval;
namespace sim = torqued::sim;
using torqued::FusionQuality;

namespace {
const sim::BedEngine& engine(const std::string& name) {
  const sim::BedEngine* e = sim::unseen_engine(name);
  if (e == nullptr) throw std::invalid_argument(name);
  return *e;
}
eval::EvalOptions options() {
  eval::EvalOptions o;
  o.skip_cycles = 6;
  return o;
}
double frac(const eval::ErrorStats& s) { return s.n > 0 ? static_cast<double>(s.pass) / s.n : 0.0; }
double cov(const eval::ErrorStats& s) {
  return s.with_sd > 0 ? static_cast<double>(s.covered) / s.with_sd : 0.0;
}
}  // namespace

class UnseenBed : public ::testing::TestWithParam<const char*> {};

TEST(UnseenBedList, HasTuningAndReportEnginesOfEveryKind) {
  int report = 0, tuning = 0, c3 = 0, c4 = 0, c6 = 0, w36 = 0, w60 = 0;
  for (const auto& e : sim::unseen_engines()) {
    (e.report ? report : tuning)++;
    c3 += e.spec.cylinders == 3;
    c4 += e.spec.cylinders == 4;
    c6 += e.spec.cylinders == 6;
    (e.truth.wheel.positions == 36 ? w36 : w60)++;
    // The truth is not the spec sheet: inertia differs (≤ 10 %), friction is not the paper's law.
    EXPECT_LE(std::fabs(e.truth.engine.j_rot_kgm2 / e.spec.j_rot_kgm2 - 1.0), 0.10 + 1e-12) << e.name;
    EXPECT_FALSE(e.truth.friction.paper_law) << e.name;
  }
  EXPECT_GE(report, 4);
  EXPECT_GE(tuning, 2);
  EXPECT_GT(c3 * c4 * c6 * w36 * w60, 0);
}

TEST_P(UnseenBed, MeetsTheTargetsWithAndWithoutTheLoadSignal) {
  const eval::BedResult b = eval::evaluate_bed_engine(engine(GetParam()), options(), /*short_run=*/true);
  const auto& w = b.with_load;
  const auto& n = b.without_load;
  ASSERT_GT(w.cycles, 40);
  // With the load signal: brake ≤ 1 N m RMS; friction (learned from the generic prior) within 10 % or 2 N m.
  EXPECT_LE(w.brake.rms_nm, 1.0);
  EXPECT_LE(w.friction.rms_nm, 2.0);
  // With the load signal, indicated: target 3 % or 2 N m; asserted on RMS (measured 1.1-3.2 N m RMS on
  // the report engines: the 36-1 I4 misses it, see docs/angle_pipeline.md).
  EXPECT_LE(w.indicated.rms_nm, 3.5);
  // Without the load signal: brake within 5 % / 3 N m steady, 8 % / 5 N m transient on ≥ 85 % of the cycles.
  EXPECT_GE(frac(n.brake), 0.85) << "rms " << n.brake.rms_nm << " max " << n.brake.max_abs_nm;
  EXPECT_LE(n.brake.rms_nm, 3.0);
  // Honest 1σ: the claimed brake σ covers the error on ≥ 50 % of the cycles (68 % ideal). Conservative since
  // the four-parameter fuel model (its residual scale is measured at the learn run's references, larger than
  // the short run's steady errors): 98-100 % here, 86-98 % on the full runs (was ≤ 95 % with the Willans
  // line).
  EXPECT_GE(cov(n.brake), 0.50);
}

INSTANTIATE_TEST_SUITE_P(ReportEngines, UnseenBed, ::testing::Values("rep_i4_60", "rep_i3_36"));

TEST(UnseenBedFault, LoadSignalLostMidRunSwitchesWithinOneCycleAndStaysWithinCrankOnlyTargets) {
  const sim::BedEngine& e = engine("rep_i4_60");
  eval::EvalOptions o = options();
  o.spec_engine = e.spec;
  o.friction_prior.reset();
  o.score_all_cycles = true;
  const eval::ScenarioResult learn = eval::evaluate(sim::bed_learning_run(e), o);
  o.friction = learn.friction_coefficients;
  o.idle_correction = std::array<double, 2>{learn.idle_correction_nm, learn.idle_rpm};
  o.fuel_state = learn.fuel_state;
  o.crank_err_var = learn.crank_err_var;
  const double t_lost = 2.0;
  o.load_lost_after_s = t_lost;
  const eval::ScenarioResult r = eval::evaluate(sim::bed_eval_run(e, true), o);
  const double cycle_s = 4.0 * M_PI / (2000.0 * M_PI / 30.0);  // one cycle at 2000 rpm
  int before_full = 0, before = 0, after = 0, after_ok = 0;
  for (const auto& row : r.rows) {
    if (row.t_s < t_lost) {
      ++before;
      before_full += row.quality == FusionQuality::kFull;
    } else if (row.t_s > t_lost + cycle_s) {
      ++after;
      EXPECT_NE(row.quality, FusionQuality::kFull) << row.t_s;  // says so: no longer the full (load) balance
      EXPECT_NE(row.quality, FusionQuality::kInvalid) << row.t_s;
      const double allowed = row.transient ? std::max(5.0, 0.08 * std::fabs(row.brake_true))
                                           : std::max(3.0, 0.05 * std::fabs(row.brake_true));
      after_ok += std::fabs(row.fused - row.brake_true) <= allowed;
    }
  }
  EXPECT_EQ(before_full, before);
  ASSERT_GT(after, 10);
  EXPECT_GE(static_cast<double>(after_ok) / after, 0.85);
}

// The fuel model without a load signal (docs/angle_pipeline.md "Fuel model: physics"), short evaluated runs.
// Full table: build/tools/torque-accuracy --bed unseen --bed-fuel
class UnseenBedFuel : public ::testing::TestWithParam<const char*> {};

TEST_P(UnseenBedFuel, TaughtAtOnePointTheMapIsWithinTargetAndNeverTaughtIsPublishedHonestly) {
  const eval::BedFuelResult b = eval::evaluate_bed_fuel(engine(GetParam()), options(), /*short_run=*/true);
  const auto& one = b.one_point;
  const auto& never = b.never;
  ASSERT_GT(one.cycles, 40);
  // Taught at 2500 rpm / 60 kPa (+ overrun, idle), evaluated at 2000-3000 rpm, 55-80 kPa without the load
  // signal: every cycle published, >= 90 % within 8 % or 5 N m, RMS <= 6 % of the true brake torque, the
  // claimed 1σ covering 40-98 % (measured on the report engines' short runs: table in the docs).
  EXPECT_EQ(one.published, one.cycles);
  EXPECT_GE(one.pass, 90 * one.published / 100) << "rms " << one.rms_nm;
  EXPECT_LE(one.rms_pct, 6.0);
  EXPECT_GE(one.covered, 40 * one.published / 100);
  EXPECT_LE(one.covered, 98 * one.published / 100);
  // The learn run's references rest on a few cells (its one point straddles band edges; the speed ramp to it
  // teaches too): at most 6 of the 16 (measured 4-6), not the whole map.
  EXPECT_GT(one.references, 50u);
  EXPECT_LE(__builtin_popcount(one.cells), 6);
  // Never taught: published on >= 95 % of the cycles with quality prior_only, RMS <= 25 % (the generic
  // friction law's ±27 % dominates). One engine is one draw from the population the priors' 1σ were
  // calibrated on (torque-accuracy --bed-priors): its error may sit outside 1σ on a whole short run
  // (rep_i4_36: 1.4σ), so the per-engine check is 2σ: >= 90 % of its cycles (it holds for 10-11 of the 12
  // calibration engines, whose tails are heavier than a normal's).
  EXPECT_GE(never.published, 95 * never.cycles / 100);
  EXPECT_EQ(never.prior_only, never.published);
  EXPECT_LE(never.rms_pct, 25.0);
  EXPECT_GE(never.covered2, 90 * never.published / 100);
  // With the load signal, from the one-point state: the energy balance leads, fused <= 1.5 N m RMS.
  EXPECT_LE(b.with_load_rms_nm, 1.5);
}

INSTANTIATE_TEST_SUITE_P(ReportEngines, UnseenBedFuel, ::testing::Values("rep_i4_36", "rep_i6_60"));
