// tests/tools/test_vehicle_bed.cpp: live load references on a vehicle through the daemon's chain
// (tools/accuracy/daemon_bed.cpp evaluate_vehicle_bed_engine, estimators/core/load_reference.hpp). Two report
// engines of the unseen bed (never used for tuning: I4 60-2, I6 36-1), short recordings from a fresh state,
// no load signal. Hybrid: the clutch is open (VEH_1.ClutchOpen mapped as can.signals.em_sole_load) during a
// motored start and standstill charging (4.5 s here), then closes mid-run for driving with boost, generation
// and an overrun in gear. Vehicle: idle in neutral, the clutch closes, driving, overrun in gear, the clutch
// opens again (coast-down), and a second drive from the state the first left. One point: a learning run with
// the load signal at one operating point, then the map without it. Truth: the simulator's per-cycle brake,
// indicated and friction torque. Tolerances are stated per assertion; they are the targets where reached and
// otherwise a little above what the chain gives today (short runs: 4.5 s of charging, not the >= 10 s the
// hybrid target is stated for; the full runs are in the report command `torque-accuracy --vehicle-bed`).
// Label slow (about 10 s per engine; the prior calibration about 30 s).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "daemon_bed.hpp"

namespace torqued::eval {
namespace {
namespace fs = std::filesystem;

const DaemonBedRun& run(const VehicleBedResult& r, const std::string& label) {
  for (const auto& x : r.runs)
    if (x.label == label) return x.r;
  static const DaemonBedRun none{};
  ADD_FAILURE() << "no run " << label;
  return none;
}

class VehicleBed : public ::testing::TestWithParam<const char*> {};

TEST_P(VehicleBed, ClutchFlagMakesTheMachineAReferenceAndTheOverrunInGearTeachesNothing) {
  const sim::BedEngine* e = sim::unseen_engine(GetParam());
  ASSERT_NE(e, nullptr);
  ASSERT_TRUE(e->report) << "only report engines are scored";
  DaemonBedOptions opt;
  opt.out_dir = (fs::temp_directory_path() /
                 ("torqued_vehicle_bed_" + std::string(GetParam()) + "_" + std::to_string(::getpid())))
                    .string();
  opt.short_run = true;
  VehicleBedResult r;
  std::string err;
  const bool ok = evaluate_vehicle_bed_engine(*e, opt, r, err);
  fs::remove_all(opt.out_dir);
  ASSERT_TRUE(ok) << err;

  const DaemonBedRun& open = run(r, "hybrid/open");
  const DaemonBedRun& drive = run(r, "hybrid/drive");
  const DaemonBedRun& st = run(r, "hybrid/drive static-true");
  const DaemonBedRun& sf = run(r, "hybrid/drive static-false");
  ASSERT_GT(open.cycles, 30);
  ASSERT_GT(drive.cycles, 60);
  // While open the machine is the only load: the energy balance (brake within 5 % or 3 N m steady).
  EXPECT_GE(open.brake.pass, 85 * open.brake.n / 100);
  // Friction learned in the motored start is used while closed; the overrun in gear (fuel cut-off, clutch
  // closed, no load signal) must not move it: |error| < 3.5 N m at every cycle (10 % of the 25-40 N m true
  // friction + 1 N m; today 1.7 and 1.9 N m).
  EXPECT_LT(drive.friction.max_abs_nm, 3.5);
  EXPECT_LT(drive.friction.rms_nm, 2.5);
  // Fused brake torque is published on every driving cycle with the flag; without it (static false) too, from
  // the prior fuel model (quality prior_only), within 12 N m RMS on the short run (today 2.8 and 6.5).
  EXPECT_EQ(drive.fused_published, drive.cycles);
  EXPECT_GE(sf.fused_published, 95 * sf.cycles / 100);
  EXPECT_LT(sf.fused.rms_nm, 12.0);
  // Driving after 4.5 s of charging at 3 points (short run): the hybrid target (5 % or 3 N m steady, 8 % or
  // 5 N m transient) on >= 95 % of the cycles (today 98-100 %), brake RMS < 4 N m (today 1.9 and 2.9).
  EXPECT_GE(drive.brake.pass, 95 * drive.brake.n / 100);
  EXPECT_LT(drive.brake.rms_nm, 4.0);
  // The static sole_load (no flag) takes the vehicle's share to be zero: far off (today 65 and 110 N m RMS).
  EXPECT_GT(st.brake.rms_nm, 5.0 * drive.brake.rms_nm);

  // Vehicle without any load reference: nothing learned, fused published from the priors (prior_only) on
  // >= 95 % of the cycles within 12 N m RMS (today 2.0 and 5.5); the friction stays the generic prior, whose
  // claimed 1 sigma (27 %) covers its error on every cycle of these two engines (both within 20 % of the
  // correlation; on others it need not: rep_i4_36 is 45 % covered, rep_i3_60 33 %).
  const DaemonBedRun& nf = run(r, "vehicle/noflag");
  ASSERT_GT(nf.cycles, 60);
  EXPECT_GE(nf.fused_published, 95 * nf.cycles / 100);
  EXPECT_LT(nf.fused.rms_nm, 12.0);
  EXPECT_EQ(nf.friction.covered, nf.friction.n);
  // No flag: the fuel cut-off in gear is not taken for a free coast-down, the coast-down with the clutch open
  // is (the step of J theta'' at cut-off entry and the deceleration, AnglePipeline::detect_free_coast): at
  // least 3 cycles (today 6 and 4), none with the simulator's clutch closed.
  EXPECT_GE(r.free_coast_cycles, 3);
  EXPECT_EQ(r.free_coast_wrong, 0);
  // What the coast-down taught is saved (a law learned over speed from fewer than friction.min_observations
  // cycles was not, while the fuel model learned against it at the idle was: an inconsistent pair).
  EXPECT_TRUE(r.noflag_saved_friction);
  // A second drive from the state the first left (what the coast-down and its idle taught, still no flag):
  // fused within 12 % of the true RMS + 1 N m (today 7.4 % and 5.8 %), its claimed 1 sigma covering at least
  // half of the cycles (today 89 % and 70 %; 53 % pooled before the crank chain was kept to the cells where
  // its 1 sigma was measured).
  const DaemonBedRun& n2 = run(r, "vehicle/noflag 2nd");
  EXPECT_GE(n2.fused_published, 95 * n2.cycles / 100);
  EXPECT_LT(n2.fused.rms_nm, 0.12 * n2.fused.rms_true_nm + 1.0);
  EXPECT_GE(n2.fused.covered, n2.fused.n / 2);
  EXPECT_LE(n2.fused.covered, 97 * n2.fused.n / 100);  // and not so wide that it covers every cycle
  // The same with the neutral flag: its idles in neutral are references too, each resting on the same
  // accessories' prior. Learned as independent they claimed to fix the map (1 sigma covering 54 % of the
  // cycles on rep_i4_60); the fuel model now carries that shared bias (a consider parameter): at least 60 %
  // (today 85 % and 75 %).
  const DaemonBedRun& f2 = run(r, "vehicle/neutral 2nd");
  EXPECT_GE(f2.fused_published, 95 * f2.cycles / 100);
  EXPECT_LT(f2.fused.rms_nm, 0.12 * f2.fused.rms_true_nm + 1.0);
  EXPECT_GE(f2.fused.covered, 60 * f2.fused.n / 100);
  EXPECT_LE(f2.fused.covered, 97 * f2.fused.n / 100);

  // (c) Taught at one operating point (load signal at 2500 rpm, an overrun and idle), the map without it:
  // the target, fused within 8 % or 5 N m, on >= 95 % of the cycles (today 100 % on both engines, RMS 1.7 and
  // 2.7 N m). Before the fuel model waited for a friction law learned over speed, the references taken with
  // the idle-corrected prior friction taught it 17 N m wrong on another report engine.
  const DaemonBedRun& op = run(r, "one-point/map");
  ASSERT_GT(op.cycles, 40);
  EXPECT_EQ(op.fused_published, op.cycles);
  EXPECT_GE(op.fused.loose, 95 * op.fused.n / 100);
  EXPECT_LT(op.fused.rms_nm, 0.05 * op.fused.rms_true_nm + 1.0);
  // Never taught, the same map: published from the priors on every cycle.
  const DaemonBedRun& nv = run(r, "never/map");
  EXPECT_GE(nv.fused_published, 95 * nv.cycles / 100);
}

INSTANTIATE_TEST_SUITE_P(ReportEngines, VehicleBed, ::testing::Values("rep_i4_60", "rep_i6_36"));

// The priors' 1σ defaults (friction.prior_rel_sd, the fuel model's prior 1σ) were set so that on the 12
// calibration engines (tools/sim/unseen_engines.hpp calibration_engines(), never scored elsewhere) the 68th
// percentile of |error| / claimed 1σ is 1 (torque-accuracy --bed-priors; docs/angle_pipeline.md "Calibrating
// the priors"). A change to the fuel model, the friction law or the fusion that de-calibrates them fails
// here: pooled z68 within 0.85-1.2 for each (today 1.01 and 1.00), the fused brake's within 0.85-1.35
// (today 1.09: the tails are heavier than a normal's), on the full maps as the defaults were set (about 30
// s).
TEST(PriorCalibration, ThePriorsOneSigmaCoverTwoThirdsOfTheCalibrationEnginesErrors) {
  DaemonBedOptions opt;
  opt.out_dir =
      (fs::temp_directory_path() / ("torqued_prior_calibration_" + std::to_string(::getpid()))).string();
  opt.short_run = false;
  PriorCalibration pool;
  for (const auto& e : sim::calibration_engines()) {
    PriorCalibration c;
    std::string err;
    ASSERT_TRUE(evaluate_prior_calibration_engine(e, opt, c, err)) << err;
    ASSERT_GT(c.friction_z.size(), 100u) << e.name;
    for (auto [dst, src] : {std::pair{&pool.friction_z, &c.friction_z}, std::pair{&pool.fuel_z, &c.fuel_z},
                            std::pair{&pool.fused_z, &c.fused_z}})
      dst->insert(dst->end(), src->begin(), src->end());
  }
  fs::remove_all(opt.out_dir);
  const auto z68 = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(0.6827 * static_cast<double>(v.size() - 1))];
  };
  const double zf = z68(pool.friction_z), zu = z68(pool.fuel_z), zb = z68(pool.fused_z);
  EXPECT_GE(zf, 0.85);
  EXPECT_LE(zf, 1.2);
  EXPECT_GE(zu, 0.85);
  EXPECT_LE(zu, 1.2);
  EXPECT_GE(zb, 0.85);
  EXPECT_LE(zb, 1.35);
}

}  // namespace
}  // namespace torqued::eval
