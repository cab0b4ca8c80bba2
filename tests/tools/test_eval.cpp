// tools/eval: metrics on synthetic signals with known answers, and the estimate/truth join of torque-eval.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "evaluator.hpp"

namespace torqued::eval {
namespace {

TEST(EvalMetrics, ConstantOffset) {
  // GIVEN est = truth + 2 over 1 s THEN bias = RMS = MAE = 2, SD = 0, ISE = 4 (N m)^2 s.
  std::vector<double> t, est, truth;
  for (int i = 0; i <= 100; ++i) {
    t.push_back(i * 0.01);
    truth.push_back(50.0 * std::sin(i * 0.3));
    est.push_back(truth.back() + 2.0);
  }
  const ErrorStats s = error_stats(t, est, truth);
  EXPECT_EQ(s.n, 101u);
  EXPECT_NEAR(s.bias, 2.0, 1e-12);
  EXPECT_NEAR(s.rms, 2.0, 1e-12);
  EXPECT_NEAR(s.mae, 2.0, 1e-12);
  EXPECT_NEAR(s.sd, 0.0, 1e-6);
  EXPECT_NEAR(s.ise, 4.0, 1e-9);
}

TEST(EvalMetrics, AlternatingError) {
  // ε = ±3 alternating: bias 0, RMS 3, SD 3, MAE 3; ISE = 9 T.
  std::vector<double> t, est, truth;
  for (int i = 0; i < 200; ++i) {
    t.push_back(i * 0.5);
    truth.push_back(10.0);
    est.push_back(10.0 + (i % 2 ? 3.0 : -3.0));
  }
  const ErrorStats s = error_stats(t, est, truth);
  EXPECT_NEAR(s.bias, 0.0, 1e-12);
  EXPECT_NEAR(s.rms, 3.0, 1e-12);
  EXPECT_NEAR(s.sd, 3.0, 1e-12);
  EXPECT_NEAR(s.mae, 3.0, 1e-12);
  EXPECT_NEAR(s.ise, 9.0 * 199 * 0.5, 1e-9);
}

TEST(EvalMetrics, CycleMeanPercentAndConvergence) {
  EXPECT_NEAR(cycle_mean_pct_error({110, 90, 100}, {100, 100, 100}), 100.0 * 20.0 / 300.0, 1e-12);
  EXPECT_TRUE(std::isnan(cycle_mean_pct_error({}, {})));
  EXPECT_EQ(convergence_index({10, 8, 1, 0.5, 6, 1, 0.2}, 2.0), 5u);
  EXPECT_EQ(convergence_index({1, 1}, 2.0), 0u);
  EXPECT_EQ(convergence_index({1, 5}, 2.0), 2u);  // never converged
}

TEST(EvalMetrics, PhaseLagOfAShiftedWaveform) {
  // GIVEN a 4-cylinder in-cycle waveform (period 180 deg) WHEN the estimate is the truth delayed by 12 deg
  // THEN the cross-correlation finds a 12 deg lag (tolerance 0.3 deg); a lead gives a negative lag.
  std::vector<double> ta, tv, ea, ev, ea2, ev2;
  auto wave = [](double deg) {
    return 80.0 * std::sin(2 * std::numbers::pi * deg / 180.0) +
           20.0 * std::sin(2 * std::numbers::pi * deg / 90.0 + 0.4);
  };
  for (int k = 0; k <= 1200; ++k) {  // 0..7200 deg by 6
    const double a = 6.0 * k;
    ta.push_back(a);
    tv.push_back(wave(a));
  }
  for (int k = 0; 100.0 + 6.0 * k <= 7000.0; ++k) {  // 100..7000 deg by 6
    const double a = 100.0 + 6.0 * k;
    ea.push_back(a);
    ev.push_back(wave(a - 12.0));
    ea2.push_back(a);
    ev2.push_back(wave(a + 7.0));
  }
  const PhaseLag lag = phase_lag(ea, ev, ta, tv);
  ASSERT_TRUE(lag.ok);
  EXPECT_NEAR(lag.lag_deg, 12.0, 0.3);
  EXPECT_GT(lag.correlation, 0.99);
  const PhaseLag lead = phase_lag(ea2, ev2, ta, tv);
  EXPECT_NEAR(lead.lag_deg, -7.0, 0.3);
}

TEST(EvalMetrics, MisfireCounting) {
  MisfireStats s;
  count_misfires({false, true, false, false}, 0b0010, s);  // cyl 2 misfire detected
  count_misfires({true, false, false, false}, 0b0100, s);  // cyl 1 missed, cyl 3 false alarm
  EXPECT_EQ(s.cylinder_cycles, 8u);
  EXPECT_EQ(s.true_misfires, 2u);
  EXPECT_EQ(s.detected, 1u);
  EXPECT_EQ(s.false_alarms, 1u);
  EXPECT_DOUBLE_EQ(s.recall(), 0.5);
}

CsvTable table(const std::string& text, const std::string& name) {
  CsvTable t;
  std::string error;
  std::vector<std::string> warnings;
  EXPECT_TRUE(parse_csv(text, name, t, error, warnings)) << error;
  return t;
}

/// 10 truth cycles of 60 ms with brake mean 100 + c and misfires (cycle 4 cyl 2, cycle 7 cyl 1).
Truth cycle_truth() {
  std::ostringstream os;
  os << "cycle,t_start_s,t_end_s,t_brake_mean_nm,misfire1,misfire2,misfire3,misfire4\n";
  for (int c = 0; c < 10; ++c)
    os << c << "," << c * 0.06 << "," << (c + 1) * 0.06 << "," << 100 + c << "," << (c == 7) << ","
       << (c == 4) << ",0,0\n";
  Truth t;
  t.cycle = table(os.str(), "truth_cycle.csv");
  return t;
}

TEST(EvalJoin, PerCycleJoinConvergenceAndMisfires) {
  // GIVEN one estimate per cycle, stamped at the cycle end with its window start (the daemon's EngineTorque
  // rows): error +50 N m in cycles 0-2, then +3 N m. THEN the midpoint join matches each row to its own
  // cycle.
  std::ostringstream os;
  os << "t_ns,window_start_t_ns,fused_nm,misfire_mask\n";
  for (int c = 0; c < 10; ++c) {
    const auto t_end = static_cast<long long>(std::llround((c + 1) * 0.06e9));
    const auto t_start = static_cast<long long>(std::llround(c * 0.06e9));
    const int mask = c == 4 ? 0b0010 : (c == 5 ? 0b0100 : 0);
    os << t_end << "," << t_start << "," << (100 + c + (c < 3 ? 50 : 3)) << "," << mask << "\n";
  }
  const CsvTable est = table(os.str(), "est.csv");
  EvalOptions opt;
  opt.tolerance = 5.0;
  opt.misfire_col = "misfire_mask";
  EvalReport r;
  std::string error;
  ASSERT_TRUE(evaluate(est, cycle_truth(), {{"fused_nm", "t_brake_mean_nm"}}, opt, r, error)) << error;
  ASSERT_EQ(r.pairs.size(), 1u);
  const PairResult& p = r.pairs[0];
  EXPECT_TRUE(p.per_cycle);
  EXPECT_EQ(p.stats.n, 10u);
  EXPECT_EQ(p.cycles, 10u);
  EXPECT_NEAR(p.stats.bias, (3 * 50.0 + 7 * 3.0) / 10.0, 1e-9);
  EXPECT_NEAR(p.stats.mae, 50.0, 1e-9);
  ASSERT_TRUE(p.converged_cycle.has_value());
  EXPECT_EQ(*p.converged_cycle, 3u);
  EXPECT_NEAR(p.converged_t_s, 0.18, 1e-12);
  double truth_sum = 0;
  for (int c = 0; c < 10; ++c) truth_sum += 100 + c;
  EXPECT_NEAR(p.cycle_pct, 100.0 * (3 * 50.0 + 7 * 3.0) / truth_sum, 1e-9);
  ASSERT_TRUE(r.misfire.has_value());
  EXPECT_EQ(r.misfire->true_misfires, 2u);
  EXPECT_EQ(r.misfire->detected, 1u);
  EXPECT_EQ(r.misfire->false_alarms, 1u);
  EXPECT_EQ(r.misfire->cylinder_cycles, 40u);
  EXPECT_NE(format_report(r, opt.tolerance).find("fused_nm = t_brake_mean_nm"), std::string::npos);
}

TEST(EvalJoin, SampleTimeWithoutWindowUsesTheCycleContainingIt) {
  const CsvTable est = table("t_ns,v\n30000000,1\n90000000,2\n150000000,3\n", "est.csv");
  EvalReport r;
  std::string error;
  EvalOptions opt;
  opt.time_ref = TimeRef::kSample;
  ASSERT_TRUE(evaluate(est, cycle_truth(), {{"v", "t_brake_mean_nm"}}, opt, r, error)) << error;
  // cycles 0,1,2 → truth 100,101,102; errors -99 each.
  EXPECT_NEAR(r.pairs[0].stats.bias, -99.0, 1e-9);
  EXPECT_EQ(r.pairs[0].stats.n, 3u);
}

TEST(EvalJoin, AutoRefusesPerCycleRowsWithoutAWindow) {
  // GIVEN one row per cycle stamped at the cycle end, with neither window_start_t_ns nor a cycle column.
  // THEN --time-ref auto neither joins each row with the next cycle nor guesses: it refuses, naming the
  // options.
  const CsvTable est =
      table("t_ns,v,misfire_mask\n60000000,100,0\n120000000,101,0\n180000000,102,0\n", "est.csv");
  EvalReport r;
  std::string error;
  EXPECT_FALSE(evaluate(est, cycle_truth(), {{"v", "t_brake_mean_nm"}}, EvalOptions{}, r, error));
  EXPECT_NE(error.find("est.csv: the per-cycle join of v needs the window"), std::string::npos) << error;
  EXPECT_NE(error.find("--time-ref end"), std::string::npos) << error;
  EvalOptions opt;
  opt.misfire_col = "misfire_mask";
  EXPECT_FALSE(evaluate(est, cycle_truth(), {}, opt, r, error));
  EXPECT_NE(error.find("--misfire needs the window"), std::string::npos) << error;
}

TEST(EvalJoin, AutoJoinsPerToothRowsWithoutAWindowAtTheirTime) {
  // Instantaneous rows (20 per 60 ms cycle) need no window: each joins the cycle containing its time.
  std::ostringstream os;
  os << "t_ns,v\n";
  for (int k = 0; k < 200; ++k) os << k * 3000000LL + 1000000LL << "," << 100 + k / 20 << "\n";
  EvalReport r;
  std::string error;
  ASSERT_TRUE(evaluate(table(os.str(), "est.csv"), cycle_truth(), {{"v", "t_brake_mean_nm"}}, EvalOptions{},
                       r, error))
      << error;
  EXPECT_EQ(r.pairs[0].stats.n, 200u);
  EXPECT_NEAR(r.pairs[0].stats.rms, 0.0, 1e-12);
}

TEST(EvalJoin, CycleColumnGivesTheWindowOfRowsWithoutWindowStart) {
  // GIVEN cylinder_torque.csv-like rows: cycle n closes 6 ms after the truth's cycle n (the daemon's cycle
  // boundary lags the truth's), a misfire flagged in cycles 4 (cyl 2) and 7 (cyl 1), as the truth says.
  // THEN auto joins each row on the window from the previous cycle's row: 8 of 9 rows joined exactly (the
  // first row has no window), 2 true misfires, 2 detected, 0 false alarms. The sample time would join the
  // next cycle.
  std::ostringstream os;
  os << "t_ns,engine_id,cycle,v,misfire_mask\n";
  for (int c = 0; c < 9; ++c)
    os << (c + 1) * 60000000LL + 6000000LL << ",1," << c << "," << 100 + c << ","
       << (c == 4 ? 0b0010 : (c == 7 ? 0b0001 : 0)) << "\n";
  const CsvTable est = table(os.str(), "cylinder_torque.csv");
  EvalOptions opt;
  opt.misfire_col = "misfire_mask";
  EvalReport r;
  std::string error;
  ASSERT_TRUE(evaluate(est, cycle_truth(), {{"v", "t_brake_mean_nm"}}, opt, r, error)) << error;
  EXPECT_EQ(r.pairs[0].stats.n, 8u);
  EXPECT_NEAR(r.pairs[0].stats.rms, 0.0, 1e-12);
  ASSERT_TRUE(r.misfire.has_value());
  EXPECT_EQ(r.misfire->true_misfires, 2u);
  EXPECT_EQ(r.misfire->detected, 2u);
  EXPECT_EQ(r.misfire->false_alarms, 0u);
  opt.time_ref = TimeRef::kSample;
  ASSERT_TRUE(evaluate(est, cycle_truth(), {{"v", "t_brake_mean_nm"}}, opt, r, error)) << error;
  EXPECT_EQ(r.misfire->detected, 0u);
  EXPECT_EQ(r.misfire->false_alarms, 2u);
}

TEST(EvalJoin, EndTimeRefStepsBackHalfACycle) {
  // Rows stamped 6 ms after the truth cycle end (the daemon's cycle boundary lags the truth's) still match
  // their own cycle with --time-ref end.
  const CsvTable est = table("t_ns,v\n66000000,100\n126000000,101\n", "est.csv");
  EvalOptions opt;
  opt.time_ref = TimeRef::kEnd;
  EvalReport r;
  std::string error;
  ASSERT_TRUE(evaluate(est, cycle_truth(), {{"v", "t_brake_mean_nm"}}, opt, r, error)) << error;
  EXPECT_EQ(r.pairs[0].stats.n, 2u);
  EXPECT_NEAR(r.pairs[0].stats.rms, 0.0, 1e-12);  // cycles 0 and 1
  opt.time_ref = TimeRef::kSample;
  ASSERT_TRUE(evaluate(est, cycle_truth(), {{"v", "t_brake_mean_nm"}}, opt, r, error)) << error;
  EXPECT_NEAR(r.pairs[0].stats.bias, -1.0, 1e-12);  // matched one cycle late
}

TEST(EvalJoin, PerToothInterpolationWhereFilterAndWindow) {
  // Truth ramp 10 N m/s sampled every 10 ms; estimate rows of two methods; method 4 is exact, method 0 is +1.
  std::ostringstream tt;
  tt << "t_s,tooth,angle720_deg,t_brake_nm\n";
  for (int i = 0; i <= 100; ++i)
    tt << i * 0.01 << "," << i % 120 << "," << (i * 6) % 720 << "," << 10.0 * i * 0.01 << "\n";
  Truth truth;
  truth.tooth = table(tt.str(), "truth_tooth.csv");
  std::ostringstream es;
  es << "t_ns,method,value_nm\n";
  for (int i = 1; i < 95; ++i) {
    const double t = i * 0.0103;
    es << static_cast<long long>(std::llround(t * 1e9)) << ",4," << 10.0 * t << "\n";
    es << static_cast<long long>(std::llround(t * 1e9)) << ",0," << 10.0 * t + 1.0 << "\n";
  }
  const CsvTable est = table(es.str(), "est.csv");
  EvalOptions opt;
  opt.where = {{"method", 4}};
  opt.from_s = 0.1;
  opt.to_s = 0.9;
  EvalReport r;
  std::string error;
  ASSERT_TRUE(evaluate(est, truth, {{"value_nm", "t_brake_nm"}}, opt, r, error)) << error;
  const PairResult& p = r.pairs[0];
  EXPECT_FALSE(p.per_cycle);
  EXPECT_GT(p.stats.n, 70u);
  EXPECT_NEAR(p.stats.rms, 0.0, 1e-9);
  for (double t : p.t_s) {
    EXPECT_GE(t, 0.1);
    EXPECT_LE(t, 0.9);
  }
  opt.where = {{"method", 0}};
  ASSERT_TRUE(evaluate(est, truth, {{"value_nm", "t_brake_nm"}}, opt, r, error)) << error;
  EXPECT_NEAR(r.pairs[0].stats.bias, 1.0, 1e-9);
}

TEST(EvalJoin, MissingColumnsAreClearErrors) {
  const CsvTable est = table("t_ns,v\n1,2\n", "est.csv");
  EvalReport r;
  std::string error;
  EXPECT_FALSE(evaluate(est, cycle_truth(), {{"nope", "t_brake_mean_nm"}}, EvalOptions{}, r, error));
  EXPECT_NE(error.find("est.csv: estimate column 'nope' not found"), std::string::npos) << error;
  EXPECT_FALSE(evaluate(est, cycle_truth(), {{"v", "t_nope"}}, EvalOptions{}, r, error));
  EXPECT_NE(error.find("truth column 't_nope'"), std::string::npos) << error;
}

TEST(EvalCsv, BadRowsAreReportedWithLineAndSkipped) {
  CsvTable t;
  std::string error;
  std::vector<std::string> warnings;
  ASSERT_TRUE(parse_csv("t_ns,a\n1,2\n3\n4,x\n5,6\n", "f.csv", t, error, warnings));
  EXPECT_EQ(t.rows(), 3u);  // the short row is skipped, the non-number kept as NaN
  EXPECT_EQ(t.bad_rows, 2u);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_EQ(warnings[0].rfind("f.csv:3: expected 2 cells, found 1", 0), 0u) << warnings[0];
  EXPECT_EQ(warnings[1].rfind("f.csv:4:", 0), 0u) << warnings[1];
  EXPECT_TRUE(std::isnan(t.col(1)[1]));
  EXPECT_FALSE(parse_csv("", "e.csv", t, error, warnings));
  EXPECT_NE(error.find("e.csv: empty file"), std::string::npos);
}

}  // namespace
}  // namespace torqued::eval
