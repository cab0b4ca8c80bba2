// AnglePipeline on the simulator's short scenarios: the accuracy targets for the cycle-mean torques,
// per-cylinder imbalance and misfire, crank-only fallback, no allocation per tooth, determinism.
// Tooth widths: the ToothErrorLearner table learned on a warm-up recording of the same wheel
// (eval::warmup_scenario, as the daemon learns and persists it) for friction learning, imbalance, misfire,
// 3-cyl/36-1; the steady-target test uses the simulator's true machining errors (its crank-only RLS bound of
// 5 N m needs the firing orders of the wheel error better than the learner gets them at 3000 rpm: 5.3 N m
// learned). Friction is learned on the fuel_cut coast-down from a zero prior.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <vector>

#include "alloc_counter.hpp"
#include "angle_pipeline.hpp"
#include "engine_sim.hpp"
#include "pipeline_eval.hpp"
#include "tooth_error_learner.hpp"

using namespace torqued;
using eval::EvalOptions;
using eval::ScenarioResult;

class AnglePipelineSim : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    EvalOptions o;  // learned tooth table (default)
    o.friction.reset();
    // Not told the friction law: start at zero, learn on the coast-down, persist (export) the coefficients.
    const ScenarioResult r = eval::evaluate(sim::scenario_by_name("fuel_cut"), o);
    friction_ = r.friction_coefficients;
    observations_ = r.friction_observations;
  }
  static EvalOptions options() {
    EvalOptions o;
    o.friction = friction_;
    o.tooth_table = eval::ToothTable::kLearned;
    return o;
  }
  static EvalOptions options_true_teeth() {
    EvalOptions o = options();
    o.tooth_table = eval::ToothTable::kTrue;
    return o;
  }
  /// The ideal tooth samples of `out` with the simulator's true machining errors in their widths (what the
  /// wheel really shows: the in-cycle observers' input).
  static std::vector<ToothSample> samples_with_true_tooth_errors(const sim::SimOutput& out,
                                                                 const sim::Scenario& sc) {
    auto samples = sim::ideal_tooth_samples(out, sc);
    const int teeth = sc.wheel.teeth();
    for (auto& s : samples) {
      const int p = s.tooth % teeth;
      s.width_rad += out.tooth_error_rad[static_cast<std::size_t>(p)] -
                     out.tooth_error_rad[static_cast<std::size_t>((p + teeth - 1) % teeth)];
    }
    return samples;
  }
  static AnglePipelineConfig pipeline_config(const sim::Scenario& sc) {
    AnglePipelineConfig cfg;
    cfg.engine = sc.engine;
    cfg.wheel = sc.wheel;
    return cfg;
  }
  static std::array<double, 4> friction_;
  static std::uint64_t observations_;
};
std::array<double, 4> AnglePipelineSim::friction_{};
std::uint64_t AnglePipelineSim::observations_ = 0;

TEST_F(AnglePipelineSim, FrictionIsLearnedInFuelCutOff) {
  EXPECT_GT(observations_, 30u);
  // −(C1 + C2 n + C3 n²) at 2000 rpm, 90 °C vs the simulator's law (26.2 N m).
  const double n = 2000.0;
  const double learned =
      -(friction_[0] + friction_[1] * n + friction_[2] * n * n) * std::exp(friction_[3] * 90.0);
  EXPECT_NEAR(learned, 26.2, 0.8);
}

TEST_F(AnglePipelineSim, SteadyCycleMeansWithinThreePercentOrTwoNm) {
  for (const char* name : {"steady_2000_mid", "steady_3000_high"}) {
    const ScenarioResult r = eval::evaluate(sim::scenario_by_name(name), options_true_teeth());
    ASSERT_GT(r.brake.n, 10) << name;
    EXPECT_EQ(r.brake.pass, r.brake.n) << name << " brake max err " << r.brake.max_abs_nm;
    EXPECT_EQ(r.indicated.pass, r.indicated.n) << name << " indicated max err " << r.indicated.max_abs_nm;
    EXPECT_EQ(r.fused.pass, r.fused.n) << name << " fused max err " << r.fused.max_abs_nm;
    EXPECT_EQ(r.indicated_eso.pass, r.indicated_eso.n)
        << name << " ESO max err " << r.indicated_eso.max_abs_nm;
    EXPECT_LT(r.load_rls.max_abs_nm, 5.0) << name;  // crank-only extended load (paper: ±3 N m)
  }
}

TEST_F(AnglePipelineSim, FourThousandRpmLowLoadBrakeWithinTwoNmWithTheWideKineticEnergyWindow) {
  // Edge jitter (0.3 µs) on the 720° balance grows as ω³ in N m: with the ±15° per-cylinder window only, 4000
  // rpm low load had 1.4 N m RMS, 3.2 N m max (84 % within 2 N m). The 120° window (CycleKeWindow) divides it
  // by ≈ 4.
  sim::Scenario sc = sim::scenario_by_name("steady_4000_low");
  sc.duration_s = 1.2;
  const auto out = sim::simulate(sc);
  const ScenarioResult r = eval::evaluate(sc, out, options());
  ASSERT_GT(r.brake.n, 15);
  EXPECT_EQ(r.brake.pass, r.brake.n) << "brake max err " << r.brake.max_abs_nm;
  EXPECT_LT(r.brake.max_abs_nm, 2.0);
  // (indicated = brake + friction: this fixture learned friction on the fuel_cut coast-down from 3000 rpm
  // only)
  EvalOptions narrow = options();
  narrow.base.energies.cycle_ke_window_deg = 0.0;  // the per-cylinder window only (before)
  const ScenarioResult n = eval::evaluate(sc, out, narrow);
  ASSERT_EQ(n.brake.n, r.brake.n);
  std::printf("4000 rpm low load brake RMS: %.2f N m (wide window) vs %.2f N m (per-cylinder window)\n",
              r.brake.rms_nm, n.brake.rms_nm);
  EXPECT_LT(r.brake.rms_nm, 0.5 * n.brake.rms_nm);
}

namespace {
bool same(const TorqueEstimate& a, const TorqueEstimate& b) {
  return a.t_ns == b.t_ns && a.torque_nm == b.torque_nm && a.uncertainty == b.uncertainty &&
         a.health == b.health;
}
}  // namespace

TEST_F(AnglePipelineSim, CylinderWindowLeavesTheCycleBalanceAndItsLearnersUnchanged) {
  // GIVEN one recording at 4000 rpm light load (the jitter's worst case) through two pipelines that differ
  // only in energies.cylinder_window_deg: 0 (the per-cylinder work from the 30° energy window, as before) and
  // 60°
  sim::Scenario sc = sim::scenario_by_name("steady_4000_low");
  sc.duration_s = 1.0;
  const auto out = sim::simulate(sc);
  AnglePipelineConfig narrow = eval::pipeline_config(sc, options());
  narrow.energies.cylinder_window_deg = 0.0;
  AnglePipelineConfig wide = narrow;
  wide.energies.cylinder_window_deg = 60.0;
  AnglePipeline a(narrow), b(wide);
  a.friction().import_coefficients(friction_);
  b.friction().import_coefficients(friction_);
  int segments = 0, cycles = 0, cylinders_differ = 0;
  for (const ToothSample& s : sim::ideal_tooth_samples(out, sc)) {
    const EngineSignals sig = sim::signals_at(out, static_cast<double>(s.t_ns) * 1e-9);
    const std::uint8_t ra = a.on_tooth(s, sig), rb = b.on_tooth(s, sig);
    // WHEN a segment completes THEN it completes on the same tooth in both
    ASSERT_EQ(ra, rb) << s.t_ns;
    if (!(ra & AnglePipeline::kSegmentReady)) continue;
    ++segments;
    // AND every cycle-balance output (720° energy balance, RLS, ESO, friction, fusion) is bit for bit the
    // same
    const CycleOutput& x = a.cycle_output();
    const CycleOutput& y = b.cycle_output();
    EXPECT_EQ(x.t_ns, y.t_ns);
    EXPECT_EQ(x.boundary, y.boundary);
    EXPECT_EQ(x.speed_mean_rad_s, y.speed_mean_rad_s);
    for (auto m : {&CycleOutput::brake, &CycleOutput::indicated, &CycleOutput::friction, &CycleOutput::load,
                   &CycleOutput::brake_energy, &CycleOutput::indicated_crank, &CycleOutput::load_rls,
                   &CycleOutput::indicated_eso})
      EXPECT_TRUE(same(x.*m, y.*m)) << "segment " << segments;
    EXPECT_EQ(x.fused.brake_nm, y.fused.brake_nm);
    EXPECT_EQ(x.fused.sd_nm, y.fused.sd_nm);
    EXPECT_EQ(x.fused.health, y.fused.health);
    EXPECT_EQ(a.crank_error_var(), b.crank_error_var());
    EXPECT_EQ(a.friction().coefficients(), b.friction().coefficients());
    EXPECT_EQ(a.inertia().applied_scale(), b.inertia().applied_scale());
    if (!(ra & AnglePipeline::kCycleReady)) continue;
    ++cycles;
    // AND only the per-cylinder record, which the new window feeds, differs
    if (x.cylinders.torque_nm != y.cylinders.torque_nm) ++cylinders_differ;
    EXPECT_EQ(x.cylinders.cycle, y.cylinders.cycle);
  }
  EXPECT_GT(segments, 100);
  EXPECT_GT(cycles, 25);
  EXPECT_GT(cylinders_differ, cycles / 2);
  EXPECT_EQ(a.stats().cycles, b.stats().cycles);
}

TEST_F(AnglePipelineSim, IdleIndicatedTorqueWithinTwoNmWithTheLocalIdleCorrection) {
  // Motoring (fuel cut-off) never reaches idle: the friction law is extrapolated below ≈ 1100 rpm. Steady
  // idle (zero load) teaches the learner a local correction (FrictionLearner, EN-30: T_fric = T_ind at idle).
  sim::Scenario sc = sim::scenario_by_name("idle");
  sc.duration_s = 5.0;
  const auto out = sim::simulate(sc);
  EvalOptions o = options();
  o.skip_cycles = 10;
  const ScenarioResult r = eval::evaluate(sc, out, o);
  EvalOptions no_idle = o;
  no_idle.base.friction.learn_at_idle = false;
  const ScenarioResult n = eval::evaluate(sc, out, no_idle);
  ASSERT_GE(r.indicated.n, 6);
  std::printf(
      "idle indicated: max %.2f N m (idle correction) vs %.2f N m (extrapolated law); last row %.2f vs "
      "%.2f\n",
      r.indicated.max_abs_nm, n.indicated.max_abs_nm, r.rows.back().indicated - r.rows.back().indicated_true,
      n.rows.back().indicated - n.rows.back().indicated_true);
  EXPECT_EQ(r.indicated.pass, r.indicated.n);
  EXPECT_LT(r.indicated.max_abs_nm, 2.0);
  EXPECT_LT(std::fabs(r.rows.back().indicated - r.rows.back().indicated_true),
            std::fabs(n.rows.back().indicated - n.rows.back().indicated_true));
}

TEST_F(AnglePipelineSim, ImbalanceWithinThreePercentagePoints) {
  const ScenarioResult r = eval::evaluate(sim::scenario_by_name("imbalance"), options());
  // Simulator: fuel +10/0/0/−20 % on cylinders 1..4.
  EXPECT_GT(r.imbalance_true[0], 5.0);
  EXPECT_LT(r.imbalance_true[3], -15.0);
  EXPECT_LE(r.imbalance_max_pp, 3.0);
}

TEST_F(AnglePipelineSim, EveryMisfireFoundNoFalseAlarmUpTo4000Rpm) {
  const ScenarioResult r = eval::evaluate(sim::scenario_by_name("misfire"), options());
  EXPECT_GE(r.misfires_true, 6);
  EXPECT_EQ(r.misfires_found, r.misfires_true);
  EXPECT_EQ(r.misfires_false, 0);
}

TEST_F(AnglePipelineSim, ThreeCylinderAnd36Minus1ByConfigurationOnly) {
  for (const char* name : {"three_cyl", "wheel_36_1"}) {
    const ScenarioResult r = eval::evaluate(sim::scenario_by_name(name), options());
    ASSERT_GT(r.brake.n, 10) << name;
    EXPECT_EQ(r.brake.pass, r.brake.n) << name << " brake max err " << r.brake.max_abs_nm;
    EXPECT_EQ(r.indicated.pass, r.indicated.n) << name << " indicated max err " << r.indicated.max_abs_nm;
  }
}

TEST_F(AnglePipelineSim, CanLostFallsBackToCrankOnlyAndSaysSo) {
  EvalOptions o = options_true_teeth();
  o.can_lost_after_s = 1.0;
  const ScenarioResult r = eval::evaluate(sim::scenario_by_name("steady_2000_mid"), o);
  int crank_only = 0;
  for (const auto& row : r.rows) {
    if (row.t_s > 1.2) {
      EXPECT_EQ(row.quality, FusionQuality::kCrankOnly) << row.t_s;
      EXPECT_NEAR(row.fused, row.brake_true, std::max(3.0, 0.05 * std::fabs(row.brake_true))) << row.t_s;
      ++crank_only;
    }
  }
  EXPECT_GT(crank_only, 5);
}

TEST_F(AnglePipelineSim, OnToothDoesNotAllocateAndIsDeterministic) {
  sim::Scenario sc = sim::scenario_by_name("misfire");
  sc.duration_s = 1.0;
  const auto out = sim::simulate(sc);
  const auto samples = sim::ideal_tooth_samples(out, sc);
  std::vector<EngineSignals> sigs;
  sigs.reserve(samples.size());
  for (const auto& s : samples) sigs.push_back(sim::signals_at(out, static_cast<double>(s.t_ns) * 1e-9));
  AnglePipelineConfig cfg;
  cfg.engine = sc.engine;
  cfg.wheel = sc.wheel;
  AnglePipeline a(cfg), b(cfg);
  std::vector<double> first;
  first.reserve(4096);
  {
    torqued::test::AllocationScope scope;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (a.on_tooth(samples[i], sigs[i]) & AnglePipeline::kSegmentReady)
        first.push_back(a.cycle_output().fused.brake_nm);
    }
    EXPECT_EQ(scope.count(), 0u);
  }
  ASSERT_GT(first.size(), 20u);
  std::size_t k = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (b.on_tooth(samples[i], sigs[i]) & AnglePipeline::kSegmentReady) {
      ASSERT_LT(k, first.size());
      EXPECT_EQ(b.cycle_output().fused.brake_nm, first[k++]);  // bit-identical
    }
  }
  EXPECT_EQ(a.stats().teeth, samples.size());
}

TEST_F(AnglePipelineSim, UnsyncedAndBadSamplesAreCountedNeverNan) {
  AnglePipelineConfig cfg;
  AnglePipeline p(cfg);
  ToothSample s;
  s.synced = false;
  EngineSignals sig;
  EXPECT_EQ(p.on_tooth(s, sig), 0);
  s.synced = true;
  s.dt_s = std::nan("");
  s.width_rad = 0.1;
  EXPECT_EQ(p.on_tooth(s, sig), 0);
  EXPECT_EQ(p.stats().not_synced, 1u);
  EXPECT_EQ(p.stats().invalid, 1u);
  EXPECT_TRUE(std::isfinite(p.cycle_output().fused.brake_nm));
}

TEST_F(AnglePipelineSim, InCycleKalmanAndFourierFollowTheTrueIndicatedTorque) {
  // The per-tooth outputs of the Chauvin observers (helper "angle" owns their accuracy targets; here: wired
  // correctly, given the extended load, aligned to the edge they refer to).
  sim::Scenario sc = sim::scenario_by_name("steady_2000_mid");
  sc.duration_s = 1.5;
  const auto out = sim::simulate(sc);
  const auto samples = samples_with_true_tooth_errors(out, sc);
  AnglePipeline pipe(pipeline_config(sc));
  pipe.friction().import_coefficients(friction_);
  std::map<std::int64_t, double> truth;  // edge time -> true T_ind
  for (const auto& t : out.teeth) truth[t.t_meas_ns] = t.t_ind_nm;
  double sk = 0, sf = 0, skk = 0, sff = 0, stt = 0, st = 0, skt = 0, sft = 0;
  int n = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    pipe.on_tooth(samples[i], sim::signals_at(out, static_cast<double>(samples[i].t_ns) * 1e-9));
    if (samples[i].t_ns < 700'000'000) continue;  // converged
    const ToothOutput& o = pipe.tooth_output();
    ASSERT_TRUE(std::isfinite(o.kalman_ind.torque_nm));
    ASSERT_TRUE(std::isfinite(o.fourier_ind.torque_nm));
    const auto it_k = truth.find(o.kalman_ind.t_ns);
    const auto it_f = truth.find(o.fourier_ind.t_ns);
    if (it_k == truth.end() || it_f == truth.end()) continue;
    const double k = o.kalman_ind.torque_nm, f = o.fourier_ind.torque_nm, t = it_k->second, tf = it_f->second;
    sk += k;
    sf += f;
    st += t;
    skk += k * k;
    sff += f * f;
    stt += t * t;
    skt += k * t;
    sft += f * tf;
    ++n;
  }
  ASSERT_GT(n, 500);
  const auto corr = [n](double sa, double sb, double saa, double sbb, double sab) {
    return (sab - sa * sb / n) / std::sqrt((saa - sa * sa / n) * (sbb - sb * sb / n));
  };
  EXPECT_GT(corr(sk, st, skk, stt, skt), 0.8);
  EXPECT_GT(corr(sf, st, sff, stt, sft), 0.8);
  // Their cycle means carry the extended load: mean within 10 % of the true mean indicated torque.
  EXPECT_NEAR(sk / n, st / n, 0.1 * std::fabs(st / n));
}

TEST_F(AnglePipelineSim, InCycleKalmanCycleMeansFollowAThrottleStepAndASpeedRamp) {
  // GIVEN a dyno-held run at 2000 rpm whose throttle steps 45 → 90 kPa at 0.9 s and whose speed then ramps to
  // 2600 rpm (1.1-1.4 s), the load signal on CAN, the true tooth widths
  sim::Scenario sc = sim::scenario_by_name("steady_2000_mid");
  sc.duration_s = 1.7;
  sc.map_target_kpa = {{0.0, 45.0}, {0.9, 45.0}, {0.95, 90.0}};
  sc.speed_rpm = {{0.0, 2000.0}, {1.1, 2000.0}, {1.4, 2600.0}};
  const auto out = sim::simulate(sc);
  const auto samples = samples_with_true_tooth_errors(out, sc);
  AnglePipeline pipe(pipeline_config(sc));
  pipe.friction().import_coefficients(friction_);
  std::map<std::int64_t, std::pair<double, int>> truth;  // edge time -> true T_ind, cycle
  for (const auto& t : out.teeth) truth[t.t_meas_ns] = {t.t_ind_nm, t.cycle};
  std::map<int, std::pair<double, int>> cycle_err;  // cycle -> summed Kalman error, teeth
  double p2p_lo = 1e300, p2p_hi = -1e300;
  for (const ToothSample& s : samples) {
    pipe.on_tooth(s, sim::signals_at(out, static_cast<double>(s.t_ns) * 1e-9));
    const TorqueEstimate& k = pipe.tooth_output().kalman_ind;
    const auto it = truth.find(k.t_ns);
    if (k.t_ns < 900'000'000 || it == truth.end()) continue;  // WHEN scored from the throttle step on
    auto& [sum, n] = cycle_err[it->second.second];
    sum += k.torque_nm - it->second.first;
    ++n;
    p2p_lo = std::min(p2p_lo, it->second.first);
    p2p_hi = std::max(p2p_hi, it->second.first);
  }
  double se = 0.0;
  int cycles = 0;
  for (const auto& [c, e] : cycle_err) {
    if (e.second < 2 * sc.wheel.teeth()) continue;  // whole cycles only
    se += (e.first / e.second) * (e.first / e.second);
    ++cycles;
  }
  ASSERT_GE(cycles, 10);
  const double rms = std::sqrt(se / cycles);
  std::printf("Kalman per-cycle mean error through the steps: %.2f N m RMS over %d cycles (p2p %.0f N m)\n",
              rms, cycles, p2p_hi - p2p_lo);
  // THEN the in-cycle Kalman's cycle means follow (2.3 N m RMS): its extended load is this tooth's CAN load
  // plus friction (12.8 N m with the last segment's cycle mean, a cycle behind)
  EXPECT_LT(rms, 4.0);
}

TEST_F(AnglePipelineSim, TableStandardErrorWidensTheKalmanSigmaByJOmegaSquaredOnly) {
  // GIVEN a tooth table whose firing order 2 has a known edge-angle standard error (1e-4 rad per cos/sin
  // coefficient), a non-firing order 1 (not counted: not read as torque), and the same table fully
  // identified with zero standard error
  sim::Scenario sc = sim::scenario_by_name("steady_2000_mid");
  sc.duration_s = 1.0;
  const auto out = sim::simulate(sc);
  const auto samples = samples_with_true_tooth_errors(out, sc);
  std::array<ToothOrderId, 2> ids{};
  ids[0].order = 1;
  ids[0].edge_se_rad = 5e-4;
  ids[1].order = 2;
  ids[1].firing = true;
  ids[1].edge_se_rad = 1e-4;
  const double var = wheel_table_accel_var(ids);
  EXPECT_DOUBLE_EQ(var, 16.0 * 1e-8);  // r⁴·se² at r = 2
  std::array<ToothOrderId, 2> exact = ids;
  exact[0].edge_se_rad = exact[1].edge_se_rad = 0.0;
  EXPECT_EQ(wheel_table_accel_var(exact), 0.0);
  AnglePipeline base(pipeline_config(sc)), with(pipeline_config(sc)), zero(pipeline_config(sc));
  with.set_wheel_table_var(var);
  zero.set_wheel_table_var(wheel_table_accel_var(exact));
  const double j = mean_inertia_kgm2(sc.engine);
  int checked = 0;
  // WHEN the three run the same teeth
  for (const auto& s : samples) {
    const EngineSignals sig = sim::signals_at(out, static_cast<double>(s.t_ns) * 1e-9);
    base.on_tooth(s, sig);
    with.on_tooth(s, sig);
    zero.on_tooth(s, sig);
    const TorqueEstimate &a = base.tooth_output().kalman_ind, &b = with.tooth_output().kalman_ind,
                         &z = zero.tooth_output().kalman_ind;
    // THEN the estimate is bit-identical, the zero-error table leaves the 1σ as it was, and the known
    // error adds J̄·ω̄²·r²·se in quadrature (relative 1e-9)
    ASSERT_TRUE(same(a, z));
    ASSERT_EQ(a.torque_nm, b.torque_nm);
    ASSERT_EQ(a.health, b.health);
    ASSERT_EQ(a.t_ns, b.t_ns);
    if (a.uncertainty <= 0.0) {
      EXPECT_EQ(b.uncertainty, a.uncertainty);
      continue;
    }
    const double w = with.tooth_output().speed_lp_rad_s;
    const double extra = j * w * w * 4.0 * 1e-4;
    EXPECT_NEAR(b.uncertainty * b.uncertainty - a.uncertainty * a.uncertainty, extra * extra,
                1e-9 * b.uncertainty * b.uncertainty);
    ++checked;
  }
  EXPECT_GT(checked, 100);
}
