// Per-cylinder truth on the simulator: a tooth table learned on the warm-up recording keeps an
// imbalance with a once-per-revolution component (I4 cylinders 1+4 against 2+3), balanced engines show no
// pattern, a table reloaded with import_table() gives the same per-cylinder output, misfire at idle is found.
// The engines here are not the ones the learner's defaults were chosen on (their geometry, tooth errors and
// imbalance are drawn or set here), and no threshold comes from the simulator's engine.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "cylinder_eval.hpp"
#include "pipeline_eval.hpp"
#include "tooth_error_learner.hpp"

namespace torqued {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// Friction learned on the fuel_cut coast-down from a zero prior, as torque-accuracy does (once per process).
const eval::EvalOptions& options() {
  static const eval::EvalOptions opt = [] {
    eval::EvalOptions o;
    o.friction = eval::learn_friction(o);
    return o;
  }();
  return opt;
}

/// Learns a table on the warm-up recording of `sc`'s wheel, as learned_width_ratios() does.
/// `firing_error_deg` (optional) receives the largest edge-error amplitude left at a firing order (deg).
ToothErrorLearner learn_on_warmup(const sim::Scenario& sc, double* firing_error_deg = nullptr) {
  const sim::Scenario w = eval::warmup_scenario(sc);
  const sim::SimOutput out = sim::simulate(w);
  ToothErrorLearner learner(w.engine, w.wheel, ToothLearnParams{});
  for (const ToothSample& s : sim::ideal_tooth_samples(out, w)) {
    const EngineSignals sig = sim::signals_at(out, static_cast<double>(s.t_ns) * 1e-9);
    learner.set_fuel_cutoff(sig.fuel_cutoff_valid && sig.fuel_cutoff);
    learner.set_map(sig.map_pa, sig.map_valid);
    learner.update(s);
  }
  // Per order: learned vs true edge-error amplitude (diagnostic), true from the simulator's machining errors.
  const int t = learner.teeth();
  std::vector<double> edge(static_cast<std::size_t>(t));
  learner.edge_corrections(edge);
  const auto nominal = sim::nominal_tooth_angles_rad(w.wheel);
  for (const ToothOrderId& id : learner.order_ids()) {
    std::complex<double> l, tr;
    for (int p = 0; p < t; ++p) {
      const auto pi = static_cast<std::size_t>(p);
      const std::complex<double> e = std::polar(1.0, -id.order * nominal[pi]);
      l += edge[pi] * e;
      tr += (out.tooth_error_rad[pi] - out.tooth_error_rad[0]) * e;
    }
    std::printf("order %2d %-7s %-14s %5.0f cycles: learned %.4f deg, true %.4f deg, error %.4f deg\n",
                id.order, id.firing ? "firing" : "", to_string(id.source), id.cycles,
                2.0 * std::abs(l) / t / kDeg, 2.0 * std::abs(tr) / t / kDeg,
                2.0 * std::abs(l - tr) / t / kDeg);
    if (firing_error_deg != nullptr && id.firing)
      *firing_error_deg = std::max(*firing_error_deg, 2.0 * std::abs(l - tr) / t / kDeg);
  }
  return learner;
}

/// An in-cycle row of the --cylinders table and its bounds (RMS, % of the true peak-to-peak).
struct InCycleRow {
  const char* name;
  double max_kalman_pct, max_fourier_pct;
};
/// Runs each row's case through the angle pipeline (its wheel learned on its warm-up recording) and expects
/// the per-tooth Kalman and Fourier indicated torque within the row's RMS bounds, the Kalman lag ≤ 3°, and
/// at least `min_teeth` compared teeth.
void expect_incycle_rows(const std::vector<eval::CylinderCase>& cases, std::span<const InCycleRow> rows,
                         int min_teeth) {
  for (const InCycleRow& row : rows) {
    const auto it = std::find_if(cases.begin(), cases.end(),
                                 [&](const eval::CylinderCase& c) { return c.scenario.name == row.name; });
    ASSERT_NE(it, cases.end()) << row.name;
    const eval::CylinderCaseResult r = eval::evaluate_case(*it, options());
    std::printf("%s: kalman %.1f %% of p2p, lag %.1f deg; fourier %.1f %%, lag %.1f deg\n", row.name,
                r.kalman.rms_pct_p2p, r.kalman.lag_deg, r.fourier.rms_pct_p2p, r.fourier.lag_deg);
    EXPECT_LE(r.kalman.rms_pct_p2p, row.max_kalman_pct) << row.name;
    EXPECT_LE(std::abs(r.kalman.lag_deg), 3.0) << row.name;
    EXPECT_LE(r.fourier.rms_pct_p2p, row.max_fourier_pct) << row.name;
    EXPECT_GT(r.kalman.n, min_teeth) << row.name;
  }
}

TEST(CylinderAccuracy, OncePerRevolutionImbalanceIsKeptByTheLearnedTable) {
  // GIVEN an I4 whose imbalance has a large once-per-revolution part (1+4: +10 %, 2+3: −10 %) and a learned
  // wheel
  const sim::Scenario sc = eval::once_per_rev_imbalance(2000, 900);
  const ToothErrorLearner learner = learn_on_warmup(sc);
  // THEN the once-per-revolution order was identified in overrun (not from the firing cycles, which hold the
  // imbalance) and every order inside the fit was identified
  ASSERT_FALSE(learner.order_ids().empty());
  EXPECT_EQ(learner.order_ids()[0].order, 1);
  EXPECT_FALSE(learner.order_ids()[0].firing);
  EXPECT_EQ(learner.order_ids()[0].source, ToothOrderSource::kOverrun);
  EXPECT_TRUE(learner.low_orders_learned());
  // AND the per-cylinder imbalance is read within ±2 pp at 1000 and 2000 rpm
  const eval::EvalOptions& opt = options();
  for (int rpm : {1000, 2000}) {
    const auto r = eval::evaluate(eval::once_per_rev_imbalance(rpm, 900), opt);
    std::printf(
        "%d rpm: imbalance est %+.1f %+.1f %+.1f %+.1f, true %+.1f %+.1f %+.1f %+.1f, max error %.2f pp\n",
        rpm, r.imbalance_est[0], r.imbalance_est[1], r.imbalance_est[2], r.imbalance_est[3],
        r.imbalance_true[0], r.imbalance_true[1], r.imbalance_true[2], r.imbalance_true[3],
        r.imbalance_max_pp);
    EXPECT_LE(r.imbalance_max_pp, 2.0) << rpm;
    EXPECT_GT(r.imbalance_true[0] + r.imbalance_true[3], 8.0);  // the case really has the per-rev component
  }
}

TEST(CylinderAccuracy, BalancedEnginesShowNoPattern) {
  const eval::EvalOptions& opt = options();
  for (const char* name : {"three_cyl", "wheel_36_1"}) {
    const auto r = eval::evaluate(sim::scenario_by_name(name), opt);
    std::printf("%s: max imbalance error %.2f pp\n", name, r.imbalance_max_pp);
    EXPECT_LE(r.imbalance_max_pp, 1.0) << name;
  }
}

TEST(CylinderAccuracy, BalancedEngineAt3000And4000RpmReadsWithinToleranceWithTheWideCylinderWindow) {
  // GIVEN balanced I4s at 3000 rpm 65 kPa and 4000 rpm 45 kPa with the simulator's edge jitter (0.3 µs) and
  // tooth errors, a wheel learned on each one's warm-up recording, and 4 seeds each (seeds not used to choose
  // the window): each 2 s run is one random draw of the jitter and of the wheel
  const eval::EvalOptions& opt = options();
  eval::EvalOptions before = opt;
  before.base.energies.cylinder_window_deg = 0.0;  // per-cylinder work from the 30° energy window ..
  before.base.cylinder.imbalance_tau_s = 0.0;      // .. and 0.2 per cycle at every speed (before)
  struct Case {
    double rpm, map_kpa, tolerance_pp;
  };
  // 1 pp at 3000 rpm; 2 pp at 4000 rpm light load, where one seed in four still reads 2.8 pp (the learned
  // wheel's residual at the window edges, not averaged away: 1.0 s instead of 0.5 s changes nothing)
  for (const auto& [rpm, map_kpa, tolerance_pp] : {Case{3000.0, 65.0, 1.0}, Case{4000.0, 45.0, 2.0}}) {
    double ss_new = 0.0, ss_old = 0.0;
    constexpr int kSeeds = 4;
    for (int k = 0; k < kSeeds; ++k) {
      sim::Scenario s;
      s.name = "balanced_" + std::to_string(static_cast<int>(rpm));
      s.seed = 920 + static_cast<std::uint64_t>(k);
      s.duration_s = 2.0;
      s.speed_rpm = {{0.0, rpm}};
      s.map_target_kpa = {{0.0, map_kpa}};
      const sim::SimOutput out = sim::simulate(s);
      const double e_new = eval::evaluate(s, out, opt).imbalance_max_pp;
      const double e_old = eval::evaluate(s, out, before).imbalance_max_pp;
      std::printf("  seed %llu: %.2f pp vs %.2f pp\n", static_cast<unsigned long long>(s.seed), e_new, e_old);
      ss_new += e_new * e_new;
      ss_old += e_old * e_old;
    }
    const double rms_new = std::sqrt(ss_new / kSeeds), rms_old = std::sqrt(ss_old / kSeeds);
    std::printf(
        "%4.0f rpm %2.0f kPa: RMS over %d seeds of the max imbalance error %.2f pp (60 deg window, 0.5 s) vs "
        "%.2f pp (30 deg, 0.2 per cycle)\n",
        rpm, map_kpa, kSeeds, rms_new, rms_old);
    // WHEN the per-cylinder work comes from the 60° window and the imbalance is averaged over 0.5 s
    // (defaults) THEN the pattern of a balanced engine reads within the tolerance (RMS over the seeds;
    // before: 0.93 and 4.67 pp) and at most 0.7 of the error before
    EXPECT_LE(rms_new, tolerance_pp) << rpm << " rpm";
    EXPECT_LT(rms_new, 0.7 * rms_old) << rpm << " rpm";
  }
}

TEST(CylinderAccuracy, ReloadedTableGivesTheSamePerCylinderOutput) {
  // GIVEN a table learned live and the same table exported and imported into a fresh learner
  const sim::Scenario sc = eval::once_per_rev_imbalance(2000, 901);
  const ToothErrorLearner live = learn_on_warmup(sc);
  std::vector<double> table(static_cast<std::size_t>(live.teeth()));
  live.edge_corrections(table);
  ToothErrorLearner reloaded(sc.engine, sc.wheel, ToothLearnParams{});
  ASSERT_TRUE(reloaded.import_table(table, 1000));
  std::vector<double> r_live, r_loaded;
  for (int p = 0; p < live.teeth(); ++p) {
    r_live.push_back(live.width_ratio(p));
    r_loaded.push_back(reloaded.width_ratio(p));
  }
  // WHEN the per-cylinder chain runs on the same recording with each
  const sim::SimOutput out = sim::simulate(sc);
  const auto a = eval::per_cylinder_imbalance(sc, out, r_live, options());
  const auto b = eval::per_cylinder_imbalance(sc, out, r_loaded, options());
  // THEN the outputs agree to rounding (1e-6 pp)
  for (int c = 0; c < 4; ++c)
    EXPECT_NEAR(a[static_cast<std::size_t>(c)], b[static_cast<std::size_t>(c)], 1e-6) << c;
  // AND a held order keeps the imported value: a reloaded learner reports every order as held, not learned
  EXPECT_FALSE(reloaded.low_orders_learned());
}

// Every injected misfire of `sc` found (at least `min_true` of them), no false alarm.
void expect_every_misfire_found(const char* what, const sim::Scenario& sc, int min_true) {
  const auto r = eval::evaluate(sc, options());
  std::printf("%s: found %d of %d, false %d\n", what, r.misfires_found, r.misfires_true, r.misfires_false);
  EXPECT_GE(r.misfires_true, min_true);
  EXPECT_EQ(r.misfires_found, r.misfires_true);
  EXPECT_EQ(r.misfires_false, 0);
}

TEST(CylinderAccuracy, MisfireAtIdleIsFoundWithoutFalseAlarms) {
  // GIVEN idle (declutched, idle controller) with three single misfires and cylinder 2 misfiring six cycles
  // running THEN every one is found, no false alarm
  expect_every_misfire_found("idle misfire", eval::idle_misfire(902), 8);
}

TEST(CylinderAccuracy, MisfireRightAfterAFuelCutOffIsFoundWithoutFalseAlarms) {
  // GIVEN the fuel cut-off coast-down back to idle with misfires after the fuel resumes, the first in the
  // very first cycle that burns again (the fired flags still arming) and two in consecutive cycles
  // THEN every one is found, with no false alarm (was 5 of 6: the first read as overrun)
  expect_every_misfire_found("idle after cut-off misfire", eval::idle_after_cut_misfire(904), 6);
}

TEST(CylinderAccuracy, NoFalseAlarmWhereDetectionIsClaimedPossible) {
  // GIVEN balanced I4s held steady (no misfire) from 2000 to 6000 rpm, light load at the top (jitter over a
  // small speed ripple: the shares are noisy), with a learned wheel
  const eval::EvalOptions& opt = options();
  std::uint64_t seed = 903;
  for (const auto& [rpm, map_kpa] :
       {std::pair{2000.0, 65.0}, {4000.0, 45.0}, {6000.0, 45.0}, {6000.0, 95.0}}) {
    sim::Scenario s;
    s.name = "steady_" + std::to_string(static_cast<int>(rpm));
    s.seed = seed++;
    s.duration_s = 2.0;
    s.speed_rpm = {{0.0, rpm}};
    s.map_target_kpa = {{0.0, map_kpa}};
    const auto r = eval::evaluate(s, opt);
    const double active = r.detection_cycles > 0 ? 100.0 * r.detection_active / r.detection_cycles : 0.0;
    std::printf("%4.0f rpm %3.0f kPa: detection active %.0f %% of %d cycles, false alarms %d\n", rpm, map_kpa,
                active, r.detection_cycles, r.misfires_false);
    // THEN no misfire is reported where none happened: detection either works or says it is not possible
    EXPECT_EQ(r.misfires_false, 0) << rpm << " rpm " << map_kpa << " kPa";
    EXPECT_GT(r.detection_cycles, 20) << rpm;
    // AND detection is not simply switched off where the engine fires well above the noise
    // (detection starts noisy on the prior share noise until the measured one is below the limit)
    if (rpm <= 2000.0) {
      EXPECT_GE(active, 75.0) << rpm;
    }
  }
}

TEST(CylinderAccuracy, FiringOrdersOfTheWheelAreLearnedForSpeedsAboveTheWarmUp) {
  // GIVEN I4 and I3 wheels (seeds not used for tuning the learner) learned on the warm-up: firing cycles at
  // 1000-4000 rpm and 65 kPa, then a fuel cut-off at 4000 rpm. The firing orders (I4: 2, 4, 6 per rev; I3: 3,
  // 6) come from the intercept of each coefficient's speed law across the firing cycles, whose engine ripple
  // x·A(ω) (x = 1/ω̄², A drifting a few % with the speed) is ≈ 7x the wheel's share at 4000 rpm. An error left
  // there is an in-cycle torque error ∝ θ̇², twice as large at 6000 rpm as at 4000
  double worst = 0.0;
  for (int cyl : {4, 3}) {
    for (std::uint64_t seed : {1234u, 4321u, 2718u}) {
      sim::Scenario sc = cyl == 3 ? sim::scenario_by_name("three_cyl") : sim::Scenario{};
      sc.seed = seed;
      double err = 0.0;
      learn_on_warmup(sc, &err);
      std::printf("I%d seed %llu: largest firing-order edge error %.2f mdeg\n", cyl,
                  static_cast<unsigned long long>(seed), 1e3 * err);
      worst = std::max(worst, err);
    }
  }
  // THEN every firing order of the wheel's edge angles is learned within 0.003° (the machining error is
  // 0.05° RMS per edge; the x² law of the intercept left 0.0027-0.0047° at order 2 of the I4, x·ln x 0.0022°)
  EXPECT_LT(worst, 0.003);
}

TEST(CylinderAccuracy, InCycleIndicatedTorqueOnRowsNotTunedOn) {
  // GIVEN in-cycle rows of the --cylinders table that no in-cycle default was tuned on (the Kalman's edge
  // noise and the learner's fit harmonics were chosen on the incycle_*_65 rows and fuel_cut), each with its
  // own wheel learned on its warm-up recording
  // Kalman bounds: the figures measured when the differenced edge noise and fit_harmonics = 12 came in
  // (4.7 / 3.8 / 6.2 %) plus ≈ 1 pp, below what the white-R filter and an 8-harmonic table gave (6.1 / 4.7 /
  // 7.9 %). Fourier: the in-cycle targets (8 % to 3000 rpm, 12 % above).
  const InCycleRow rows[] = {
      {"incycle_2000_35", 6.0, 8.0}, {"incycle_3000_95", 4.5, 8.0}, {"incycle_4000_95", 7.5, 12.0}};
  // WHEN the angle pipeline runs on each THEN (expect_incycle_rows) within the stated RMS, lag ≤ 3°
  expect_incycle_rows(eval::cylinder_cases(0, 15), rows, 1000);
}

TEST(CylinderAccuracy, GasTorqueModelAsKnownInputFollowsTheWaveformOnRowsAndEnginesNotTunedOn) {
  // GIVEN the cylinder-pressure model's gas torque ripple fed to the Kalman filter and the Fourier observer
  // as a known input (kalman.gas_model, fourier.gas_model; the burn (energies.burn_duration_deg,
  // burn_wiebe_a), kalman.model_torque_sd_nm and kalman.model_delta tuned on the unseen-engines bed's tuning
  // engines; fourier.model_l_ref on incycle_*_65 + fuel_cut), on simulator rows and on
  // randomised engines (seed 77: geometry, inertia, wheel and injectors drawn at random) not tuned on. Bounds
  // sit between the figures with the model (and its filter gains: kalman.model_torque_sd_nm,
  // fourier.model_l_ref) and without it (the papers' zero-mean priors), so each fails without the model:
  // Kalman / Fourier % of p-p, without → with.
  const InCycleRow rows[] = {{"incycle_1000_35", 1.6, 2.0},  // K 1.8 → 1.1, F 3.5 → 1.0
                             {"incycle_6000_95", 7.0, 8.0},  // K 11.1 → 4.4, F 9.3 → 5.5
                             {"fuel_cut", 7.0, 16.5},  // overrun and idle: K 9.3 → 4.8, F 17.7 → 13.4
                             {"random_0", 2.2, 3.0},   // 3-cylinder, 2234 rpm: K 2.8 → 1.3, F 3.7 → 1.4
                             {"random_3", 4.0, 6.0}};  // 4-cylinder, 3025 rpm: K 5.7 → 1.9, F 6.2 → 3.2
  // WHEN the angle pipeline runs on each with its wheel learned on its warm-up recording THEN within the
  // bounds
  expect_incycle_rows(eval::cylinder_cases(4, 77), rows, 500);
}

}  // namespace
}  // namespace torqued

namespace torqued {
namespace {

TEST(CylinderAccuracy, TaperedCylinderWindowAt6000RpmNoWorseAndFullLoadWithinOnePp) {
  // GIVEN balanced I4s at 6000 rpm, 45 and 95 kPa, with the simulator's edge jitter (0.3 µs) and tooth
  // errors, a learned wheel, and 8 seeds each not used to choose the taper (each 2 s run one random draw)
  const eval::EvalOptions& opt = options();
  eval::EvalOptions rect = opt;
  rect.base.energies.cylinder_window_taper = 0.0;  // the rectangular 60° window (before)
  double ss_new = 0.0, ss_old = 0.0, ss95_new = 0.0, ss95_old = 0.0;
  int runs = 0;
  for (const double map_kpa : {45.0, 95.0}) {
    for (int k = 0; k < 8; ++k) {
      sim::Scenario s;
      s.name = "balanced_6000";
      s.seed = 940 + static_cast<std::uint64_t>(k) + (map_kpa > 50.0 ? 20 : 0);
      s.duration_s = 2.0;
      s.speed_rpm = {{0.0, 6000.0}};
      s.map_target_kpa = {{0.0, map_kpa}};
      const sim::SimOutput out = sim::simulate(s);
      const double e_new = eval::evaluate(s, out, opt).imbalance_max_pp;
      const double e_old = eval::evaluate(s, out, rect).imbalance_max_pp;
      std::printf("  %2.0f kPa seed %llu: %.2f pp vs %.2f pp\n", map_kpa,
                  static_cast<unsigned long long>(s.seed), e_new, e_old);
      ss_new += e_new * e_new;
      ss_old += e_old * e_old;
      if (map_kpa > 50.0) {
        ss95_new += e_new * e_new;
        ss95_old += e_old * e_old;
      }
      ++runs;
    }
  }
  const double rms_new = std::sqrt(ss_new / runs), rms_old = std::sqrt(ss_old / runs);
  const double rms95_new = std::sqrt(2.0 * ss95_new / runs), rms95_old = std::sqrt(2.0 * ss95_old / runs);
  std::printf(
      "6000 rpm: RMS over %d runs of the max imbalance error %.2f pp (parabola) vs %.2f pp (rectangle); "
      "95 kPa %.2f vs %.2f pp\n",
      runs, rms_new, rms_old, rms95_new, rms95_old);
  // WHEN the per-cylinder KE window is the parabola (default) THEN the balanced pattern, edge-jitter noise at
  // this speed, is no worse over all runs (on these seeds 1.57 vs 1.54 pp: 45 kPa 2.1 vs 1.9, one seed at
  // 4 pp; on the 12 tuning seeds 0.70 of it) and at full load within the 1 pp target (rectangle: 1.08 pp)
  EXPECT_LT(rms_new, 1.1 * rms_old);
  EXPECT_LE(rms95_new, 1.0);
}

}  // namespace
}  // namespace torqued
