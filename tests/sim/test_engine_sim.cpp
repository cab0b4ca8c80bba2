// Physics of the crank-angle simulator (energy balance, IMEP/BMEP/peak pressure, g = f', t(θ)
// monotonic, gap visible, reproducibility, misfire/fuel-cut truth) and the estimator-facing views.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include "can_codec.hpp"
#include "crank_kinematics.hpp"
#include "engine_model.hpp"
#include "engine_sim.hpp"
#include "sim_fixture.hpp"

namespace torqued::sim {
namespace {

using test::run;
constexpr double kPi = std::numbers::pi;
constexpr double kFourPi = 4.0 * kPi;

// Trapezoidal θ-integral of the net torque over trace samples [i0, i1].
double net_work(const std::vector<FineSample>& tr, std::size_t i0, std::size_t i1) {
  double w = 0.0;
  for (std::size_t i = i0; i < i1; ++i) {
    const double a = tr[i].t_ind_nm - tr[i].t_fric_nm - tr[i].t_load_nm;
    const double b = tr[i + 1].t_ind_nm - tr[i + 1].t_fric_nm - tr[i + 1].t_load_nm;
    w += 0.5 * (a + b) * (tr[i + 1].wheel_angle_rad - tr[i].wheel_angle_rad);
  }
  return w;
}

TEST(EngineSim, EnergyBalanceOverCyclesIncludingALoadStep) {
  // GIVEN the load-step scenario traced at every 0.1° step, WHEN we integrate T_ind − T_fric − T_load over
  // each 720° cycle, THEN it equals the change of ½Jθ̇² (CF-2) to 0.1 % of the indicated work of the cycle.
  const auto& r = run(
      "load_step", 1.4, [](Scenario& s) { s.trace_every_steps = 1; }, "load_step_trace");
  const auto& tr = r.out.trace;
  ASSERT_GT(tr.size(), 1000u);
  int checked = 0, changing = 0;
  std::size_t i0 = 0;
  for (std::size_t i = 1; i < tr.size(); ++i) {
    if (std::floor(tr[i].wheel_angle_rad / kFourPi + 1e-9) !=
        std::floor(tr[i0].wheel_angle_rad / kFourPi + 1e-9)) {
      if (std::fmod(tr[i0].wheel_angle_rad, kFourPi) < 1e-9) {
        double abs_work = 0.0;
        for (std::size_t j = i0; j < i; ++j)
          abs_work += std::abs(tr[j].t_ind_nm) * (tr[j + 1].wheel_angle_rad - tr[j].wheel_angle_rad);
        const double dk = tr[i].kinetic_j - tr[i0].kinetic_j;
        EXPECT_NEAR(net_work(tr, i0, i), dk, 1e-3 * abs_work) << "cycle starting at t = " << tr[i0].t_s;
        ++checked;
        if (std::abs(dk) > 20.0) ++changing;
      }
      i0 = i;
    }
  }
  EXPECT_GE(checked, 15);
  EXPECT_GE(changing, 3) << "the load step must change the kinetic energy of some cycles";
}

TEST(EngineSim, SteadyPointsHavePlausibleImepBmepAndPeakPressure) {
  for (const char* name : {"steady_1000_low", "steady_2000_mid", "steady_4000_high"}) {
    const auto& r = run(name, 0.5);
    ASSERT_FALSE(r.out.cycles.empty()) << name;
    const auto& c = r.out.cycles.back();
    const double vd = CrankKinematics(r.scenario.engine).displacement_m3();
    const double bmep = c.t_brake_mean_nm * kFourPi / vd;
    for (int k = 0; k < 4; ++k) {
      EXPECT_GT(c.cyl_imep_pa[k], 2e5) << name;
      EXPECT_LT(c.cyl_imep_pa[k], 14e5) << name;
      EXPECT_GT(c.cyl_peak_pa[k], 10e5) << name;
      EXPECT_LT(c.cyl_peak_pa[k], 90e5) << name;
    }
    EXPECT_GT(bmep, 0.5e5) << name;
    EXPECT_LT(bmep, c.cyl_imep_pa[0]) << name;
    // Dyno holds the set-point: mean speed within 0.5 %.
    const double rpm = c.speed_mean_rad_s * 30.0 / kPi;
    EXPECT_NEAR(rpm, r.scenario.speed_rpm.front().value, 0.005 * r.scenario.speed_rpm.front().value) << name;
  }
  const auto& high = run("steady_4000_high", 0.5).out.cycles.back();
  EXPECT_GT(high.cyl_peak_pa[0], 30e5) << "full-load peak pressure 30-90 bar";
  EXPECT_GT(high.cyl_imep_pa[0], 8e5);
}

TEST(EngineSim, SteadyCycleTruthIsConsistent) {
  const auto& r = run("steady_2000_mid", 0.5);
  for (const auto& c : r.out.cycles) {
    double sum = 0.0;
    for (int k = 0; k < 4; ++k) sum += c.cyl_ind_mean_nm[k];
    // Per-cylinder windows (TDC ± 360°) tile the cycle up to a phase shift: equal in steady state.
    EXPECT_NEAR(sum, c.t_ind_mean_nm, 0.005 * c.t_ind_mean_nm);
    EXPECT_NEAR(c.t_brake_mean_nm, c.t_ind_mean_nm - c.t_fric_mean_nm, 1e-9);
    // The reciprocating torque does no net work over a cycle at steady speed.
    EXPECT_NEAR(c.t_mass_mean_nm, 0.0, 0.05);
    // Steady: load absorbs the brake torque.
    EXPECT_NEAR(c.t_load_mean_nm, c.t_brake_mean_nm, 0.5);
    // Friction law (EN-27, sign-corrected) at 2000 rpm and 90 °C.
    EXPECT_NEAR(c.t_fric_mean_nm, (23.86 - 2.45e-3 * 2000 + 5.2e-6 * 2000 * 2000) * std::exp(-4.67e-3 * 90),
                0.3);
  }
}

TEST(EngineSim, FrictionIsAPositiveLossRisingWithSpeedAndFallingWithOilTemperature) {
  const EngineModel model(scenario_by_name("steady_2000_mid"));
  double prev = 0.0;
  for (double rpm = 800; rpm <= 6000; rpm += 200) {
    const double f = model.friction_nm(rpm * kPi / 30.0, 90.0);
    EXPECT_GT(f, 10.0) << rpm;
    EXPECT_GT(f, prev) << rpm;
    EXPECT_GT(model.friction_nm(rpm * kPi / 30.0, 20.0), f) << "cold oil: more friction";
    prev = f;
  }
}

TEST(EngineSim, KinematicsDerivativeGIsFPrime) {
  const CrankKinematics kin(EngineGeometry{});
  const double h = 1e-5;
  for (double th = -7.0; th < 7.0; th += 0.01)
    EXPECT_NEAR(kin.g(th), (kin.f(th + h) - kin.f(th - h)) / (2 * h), 1e-6) << th;
}

TEST(EngineSim, ToothTimesMonotonicAndGapVisible) {
  for (const char* name : {"steady_3000_mid", "wheel_36_1"}) {
    const auto& r = run(name, 0.3);
    const auto& teeth = r.out.teeth;
    ASSERT_GT(teeth.size(), 100u);
    const int gap_ratio = r.scenario.wheel.missing + 1;
    const int n = r.scenario.wheel.teeth();
    for (std::size_t i = 2; i < teeth.size(); ++i) {
      ASSERT_GT(teeth[i].t_s, teeth[i - 1].t_s);
      ASSERT_GT(teeth[i].t_meas_ns, teeth[i - 1].t_meas_ns);
      const double p = teeth[i].t_s - teeth[i - 1].t_s;
      const double prev = teeth[i - 1].t_s - teeth[i - 2].t_s;
      const double ratio = p / prev;
      if (teeth[i].tooth % n == 0) {
        EXPECT_NEAR(ratio, gap_ratio, 0.3 * gap_ratio) << name << " tooth " << teeth[i].tooth;
      } else if (teeth[i - 1].tooth % n != 0) {
        EXPECT_NEAR(ratio, 1.0, 0.2) << name << " tooth " << teeth[i].tooth;
      }
      EXPECT_EQ(teeth[i].tooth, (teeth[i - 1].tooth + 1) % (2 * n));
    }
  }
}

TEST(EngineSim, FallingEdgeAndExplicitToothListWheels) {
  // GIVEN the 36-1 wheel written as an explicit tooth list with falling marking edges, THEN the marking edges
  // have level 0 and the tooth truth equals that of the N−M description (same seed, same machining errors).
  const auto& nm = run("wheel_36_1", 0.2);
  const auto& ex = run(
      "wheel_36_1", 0.2,
      [](Scenario& s) {
        s.wheel.tooth_count = 35;
        for (int k = 0; k < 35; ++k) s.wheel.tooth_angles_deg[k] = 10.0 * k;
        s.wheel.rising_edge = false;
      },
      "wheel_36_1_explicit_falling");
  ASSERT_EQ(nm.out.teeth.size(), ex.out.teeth.size());
  for (std::size_t i = 0; i < nm.out.teeth.size(); ++i) {
    ASSERT_EQ(nm.out.teeth[i].tooth, ex.out.teeth[i].tooth);
    ASSERT_NEAR(nm.out.teeth[i].t_s, ex.out.teeth[i].t_s, 1e-12);
  }
  std::set<std::int64_t> marking;
  for (const auto& t : ex.out.teeth) marking.insert(t.t_meas_ns);
  int checked = 0;
  for (const auto& e : ex.out.edges) {
    if (e.channel == 0 && marking.count(e.t_ns)) {
      EXPECT_EQ(e.level, 0);
      ++checked;
    }
  }
  EXPECT_EQ(checked, static_cast<int>(ex.out.teeth.size()));
}

TEST(EngineSim, EdgeTimesConvergeWithTheIntegrationStep) {
  // Integration error on edge times must be << the 0.3 µs jitter: halve the step and compare true times.
  const auto tweak = [](double step) {
    return [step](Scenario& s) {
      s.step_deg = step;
      s.sensors.jitter_sd_s = 0.0;
    };
  };
  const auto& a = run("steady_2000_high", 0.3, tweak(0.1), "conv_0.1");
  const auto& b = run("steady_2000_high", 0.3, tweak(0.05), "conv_0.05");
  ASSERT_EQ(a.out.teeth.size(), b.out.teeth.size());
  // Absolute times also carry the (tiny) drift of the explicitly integrated slow loops (dyno, manifold),
  // which see a different grid; tooth periods isolate the crank integration error.
  double worst = 0.0, worst_period = 0.0;
  for (std::size_t i = 0; i < a.out.teeth.size(); ++i) {
    worst = std::max(worst, std::abs(a.out.teeth[i].t_s - b.out.teeth[i].t_s));
    if (i > 0) {
      const double pa = a.out.teeth[i].t_s - a.out.teeth[i - 1].t_s;
      const double pb = b.out.teeth[i].t_s - b.out.teeth[i - 1].t_s;
      worst_period = std::max(worst_period, std::abs(pa - pb));
    }
  }
  EXPECT_LT(worst, 50e-9) << "s";
  EXPECT_LT(worst_period, 1e-9) << "s";
}

TEST(EngineSim, ReproducibleBySeedAndDifferentSeedsDiffer) {
  const auto& a = run("steady_1000_mid", 0.3);
  Scenario sc = a.scenario;
  const SimOutput b = simulate(sc);
  ASSERT_EQ(a.out.edges.size(), b.edges.size());
  for (std::size_t i = 0; i < b.edges.size(); ++i) ASSERT_EQ(a.out.edges[i].t_ns, b.edges[i].t_ns);
  ASSERT_EQ(a.out.can.size(), b.can.size());
  for (std::size_t i = 0; i < b.can.size(); ++i) ASSERT_EQ(a.out.can[i].data, b.can[i].data);
  sc.seed += 1;
  const SimOutput c = simulate(sc);
  ASSERT_EQ(a.out.tooth_error_rad.size(), c.tooth_error_rad.size());
  int differ = 0;
  double ss = 0.0;
  for (std::size_t i = 0; i < c.tooth_error_rad.size(); ++i) {
    differ += a.out.tooth_error_rad[i] != c.tooth_error_rad[i];
    ss += c.tooth_error_rad[i] * c.tooth_error_rad[i];
  }
  EXPECT_EQ(differ, static_cast<int>(c.tooth_error_rad.size()));
  const double sd_deg = std::sqrt(ss / c.tooth_error_rad.size()) * 180.0 / kPi;
  EXPECT_GT(sd_deg, 0.03);
  EXPECT_LT(sd_deg, 0.07);
}

TEST(EngineSim, MisfireFlagsWhereInjectedAndNoWork) {
  const auto& r = run("misfire", 3.5);
  std::set<std::pair<int, int>> injected;
  for (const auto& m : r.scenario.misfires) injected.insert({m.cycle, m.cylinder});
  int seen = 0;
  bool high_speed = false;
  for (const auto& c : r.out.cycles) {
    for (int k = 0; k < 4; ++k) {
      const bool want = injected.count({c.cycle, k + 1}) > 0;
      EXPECT_EQ(c.misfire[k], want) << "cycle " << c.cycle << " cyl " << k + 1;
      if (want) {
        ++seen;
        EXPECT_LT(c.cyl_ind_mean_nm[k], 0.0) << "a misfiring cylinder only pumps";
        if (c.speed_mean_rad_s * 30 / kPi > 3800) high_speed = true;
      } else {
        EXPECT_GT(c.cyl_ind_mean_nm[k], 10.0);
      }
    }
  }
  EXPECT_EQ(seen, static_cast<int>(injected.size()));
  EXPECT_TRUE(high_speed) << "one misfire must be injected at 4000 rpm";
}

TEST(EngineSim, FuelCutCoastDownThenIdle) {
  const auto& r = run("fuel_cut", 3.5);
  int cut_cycles = 0;
  double prev_speed = 1e9;
  for (const auto& c : r.out.cycles) {
    if (!c.fuel_cut) continue;
    bool all_cut = c.t_start_s > 1.05;  // after the clutch opened (5 ms torque lag)
    for (int k = 0; k < 4; ++k) all_cut = all_cut && c.cyl_fuel_kg[k] == 0.0;
    if (!all_cut) continue;
    ++cut_cycles;
    EXPECT_LT(c.t_ind_mean_nm, 0.0) << "motored cycle";
    EXPECT_NEAR(c.t_load_mean_nm, 0.0, 1.0) << "declutched";
    EXPECT_LT(c.speed_mean_rad_s, prev_speed) << "coasting down";
    prev_speed = c.speed_mean_rad_s;
  }
  EXPECT_GE(cut_cycles, 10);
  const auto& last = r.out.cycles.back();
  EXPECT_FALSE(last.fuel_cut);
  EXPECT_NEAR(last.speed_mean_rad_s * 30 / kPi, 850.0, 250.0) << "back at idle";
}

TEST(EngineSim, ImbalanceShowsInPerCylinderTorque) {
  const auto& r = run("imbalance", 0.5);
  const auto& c = r.out.cycles.back();
  EXPECT_GT(c.cyl_ind_mean_nm[0], 1.05 * c.cyl_ind_mean_nm[1]);
  EXPECT_NEAR(c.cyl_ind_mean_nm[1], c.cyl_ind_mean_nm[2], 0.01 * c.cyl_ind_mean_nm[1]);
  EXPECT_LT(c.cyl_ind_mean_nm[3], 0.85 * c.cyl_ind_mean_nm[1]);
  // MAP at each cylinder's IVC differs by the residual manifold ripple only.
  EXPECT_NEAR(c.cyl_fuel_kg[0] / c.cyl_fuel_kg[1], 1.10, 0.005);
  EXPECT_NEAR(c.cyl_fuel_kg[3] / c.cyl_fuel_kg[1], 0.80, 0.005);
}

TEST(EngineSim, ThreeCylinderEngineRuns) {
  const auto& r = run("three_cyl", 0.5);
  ASSERT_FALSE(r.out.cycles.empty());
  const auto& c = r.out.cycles.back();
  for (int k = 0; k < 3; ++k) EXPECT_GT(c.cyl_imep_pa[k], 4e5);
  EXPECT_EQ(c.cyl_imep_pa[3], 0.0);
  EXPECT_EQ(r.out.teeth.back().t_ind_cyl_nm[3], 0.0);
}

TEST(EngineSim, IdealToothSamplesCarryNominalWidthsAndMeasuredTimes) {
  const auto& r = run("steady_2000_mid", 0.5);
  const auto s = ideal_tooth_samples(r.out, r.scenario);
  ASSERT_EQ(s.size(), r.out.teeth.size());
  const double pitch = 2 * kPi / 60;
  double mean_err = 0.0;
  int n = 0;
  for (std::size_t i = 1; i < s.size(); ++i) {
    EXPECT_TRUE(s[i].synced);
    EXPECT_EQ(s[i].t_ns, r.out.teeth[i].t_meas_ns);
    EXPECT_NEAR(s[i].dt_s, (s[i].t_ns - s[i - 1].t_ns) * 1e-9, 1e-12);
    EXPECT_NEAR(s[i].width_rad, (s[i].tooth % 58 == 0) ? 3 * pitch : pitch, 1e-12);
    EXPECT_NEAR(s[i].angle_rad, (s[i].tooth % 58) * pitch + (s[i].tooth >= 58 ? 2 * kPi : 0.0), 1e-12);
    const double speed = s[i].width_rad / s[i].dt_s;
    // Tooth error 0.05° on 6° and 0.3 µs on 500 µs: a few % per tooth.
    EXPECT_NEAR(speed, r.out.teeth[i].speed_rad_s, 0.05 * r.out.teeth[i].speed_rad_s);
    mean_err += speed / r.out.teeth[i].speed_rad_s - 1.0;
    ++n;
  }
  EXPECT_NEAR(mean_err / n, 0.0, 2e-3);
  EXPECT_FALSE(s[0].synced);
}

TEST(EngineSim, SignalsAtMatchTruth) {
  const auto& r = run("steady_2000_mid", 0.5);
  const auto& c = r.out.cycles.back();
  const EngineSignals sig = signals_at(r.out, c.t_end_s);
  ASSERT_TRUE(sig.map_valid && sig.load_torque_valid && sig.oil_temp_valid && sig.fuel_mass_valid);
  EXPECT_NEAR(sig.map_pa, c.map_pa, 2000.0);
  EXPECT_NEAR(sig.load_torque_nm, c.t_load_mean_nm, 2.5);
  EXPECT_NEAR(sig.oil_temp_c, 90.0, 1.0);
  EXPECT_NEAR(sig.fuel_mass_kg, c.cyl_fuel_kg[0], 1e-8);
  EXPECT_NEAR(sig.lambda, 1.0, 0.03);
  EXPECT_FALSE(sig.fuel_cutoff);
  EXPECT_NEAR(sig.intake_temp_k, 303.15, 1.5);
  const EngineSignals stale = signals_at(r.out, c.t_end_s + 1.0);
  EXPECT_FALSE(stale.map_valid);
  EXPECT_FALSE(stale.load_torque_valid);
}

TEST(EngineSim, EMachineFrameCarriesTheLoadThroughItsRatioOnlyWhenPresent) {
  // GIVEN a scenario whose load is an electric machine through a 2:1 gear WHEN simulated THEN EM_1 (0x210)
  // carries the machine's shaft torque, −T_load / 2 (driving positive), within the sensor noise; the demo set
  // has no EM_1.
  Scenario sc = scenario_by_name("steady_2000_mid");
  sc.duration_s = 0.5;
  sc.e_machine.present = true;
  sc.e_machine.ratio = 2.0;
  const SimOutput out = simulate(sc);
  const auto& c = out.cycles.back();
  const EngineSignals sig = signals_at(out, c.t_end_s);
  ASSERT_TRUE(sig.em_torque_valid && sig.load_torque_valid);
  EXPECT_GT(c.t_load_mean_nm, 10.0);  // the machine absorbs (generates)
  EXPECT_NEAR(sig.em_torque_nm, -c.t_load_mean_nm / 2.0, 2.0);
  EXPECT_TRUE(std::any_of(out.can.begin(), out.can.end(), [](const CanFrame& f) { return f.id == kEm1Id; }));
  const auto& plain = run("steady_2000_mid", 0.5);
  EXPECT_FALSE(std::any_of(plain.out.can.begin(), plain.out.can.end(),
                           [](const CanFrame& f) { return f.id == kEm1Id; }));
  EXPECT_FALSE(signals_at(plain.out, c.t_end_s).em_torque_valid);
}

TEST(EngineSim, RejectsInconsistentScenarios) {
  Scenario sc = scenario_by_name("steady_2000_mid");
  sc.engine.firing_order = {1, 1, 3, 4, 0, 0, 0, 0};
  EXPECT_THROW((void)simulate(sc), std::invalid_argument);
  sc = scenario_by_name("steady_2000_mid");
  sc.step_deg = 0.07;
  EXPECT_THROW((void)simulate(sc), std::invalid_argument);
  EXPECT_THROW((void)scenario_by_name("no_such_scenario"), std::invalid_argument);
}

TEST(EngineSim, AllScenariosAreNamedAndDistinct) {
  const auto names = scenario_names();
  const std::set<std::string> unique(names.begin(), names.end());
  EXPECT_EQ(unique.size(), names.size());
  for (const char* want : {"steady_1000_low", "steady_4000_high", "throttle_step", "load_step", "imbalance",
                           "misfire", "fuel_cut", "idle", "three_cyl", "wheel_36_1", "demo"})
    EXPECT_TRUE(unique.count(want)) << want;
  for (const auto& n : names) EXPECT_EQ(scenario_by_name(n).name, n);
}

}  // namespace
}  // namespace torqued::sim
