// TimePipeline + MeanSpeedTracker: cycle/segment mean speed from teeth, CAN signals to the four estimators,
// stale/invalid handling, selectable estimators, no allocation on the real-time path.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "alloc_counter.hpp"
#include "time_pipeline.hpp"

namespace torqued {
namespace {
constexpr double kTooth = 2.0 * std::numbers::pi / 60.0;  // 6° pitch (gap ignored: widths are what counts)

ToothSample tooth(std::int64_t t_ns, double dt_s, double width = kTooth, bool synced = true) {
  ToothSample s;
  s.t_ns = t_ns;
  s.width_rad = width;
  s.dt_s = dt_s;
  s.synced = synced;
  return s;
}

TEST(MeanSpeedTracker, CycleMeanRemovesFiringRipple) {
  // GIVEN ω(θ) = 200 + 20 sin(2θ) (4-cyl firing ripple, two periods per revolution) over 120 teeth per cycle
  MeanSpeedTracker tr(4.0 * std::numbers::pi);
  double t = 0.0, theta = 0.0;
  for (int i = 0; i < 600; ++i) {
    // exact time to cover one tooth: ∫ dθ/ω(θ), Simpson with 64 panels
    double dt = 0.0;
    const int m = 64;
    for (int k = 0; k <= m; ++k) {
      const double th = theta + kTooth * k / m;
      const double wgt = (k == 0 || k == m) ? 1.0 : (k % 2 ? 4.0 : 2.0);
      dt += wgt / (200.0 + 20.0 * std::sin(2.0 * th));
    }
    dt *= kTooth / (3.0 * m);
    theta += kTooth;
    t += dt;
    tr.update(tooth(static_cast<std::int64_t>(t * 1e9), dt));
    if (i < 119) {
      EXPECT_FALSE(tr.valid());
    }
  }
  ASSERT_TRUE(tr.valid());
  EXPECT_EQ(tr.teeth_in_window(), 120);
  // THEN the mean is the harmonic mean of ω over the cycle: 4π / ∮dθ/ω = √(200² − 20²)
  EXPECT_NEAR(tr.speed_rad_s(), std::sqrt(200.0 * 200.0 - 20.0 * 20.0), 1e-6);
}

TEST(MeanSpeedTracker, SegmentWindowAndLossOfSync) {
  MeanSpeedTracker tr(std::numbers::pi);  // 720°/4 cylinders
  for (int i = 0; i < 40; ++i) tr.update(tooth(i * 1'000'000, 0.001));
  EXPECT_TRUE(tr.valid());
  EXPECT_EQ(tr.teeth_in_window(), 30);
  EXPECT_NEAR(tr.speed_rad_s(), kTooth / 0.001, 1e-9);
  tr.update(tooth(41'000'000, 0.001, kTooth, /*synced=*/false));
  EXPECT_FALSE(tr.valid());
}

TimePipelineParams pipeline_params() {
  TimePipelineParams p;
  p.inertia_kgm2 = 0.14;
  p.speed_timeout_s = 0.05;
  return p;
}

EngineSignals signals(double load, double maf) {
  EngineSignals s;
  s.load_torque_nm = load;
  s.load_torque_valid = true;
  s.maf_kg_s = maf;
  s.maf_valid = true;
  return s;
}

TEST(TimePipeline, SteadyEngineGivesLoadTorqueFromAllEstimators) {
  // GIVEN a steady engine at 250 rad/s (teeth every 6°), load 60 N m, 1 kHz ticks
  TimePipeline pipe(pipeline_params(), TimeEstimatorParams{}, EngineGeometry{});
  const double tooth_dt = kTooth / 250.0;
  std::int64_t next_tooth = 0;
  const auto sig = signals(60.0, 0.02);
  test::AllocationScope scope;
  for (int n = 1; n <= 2000; ++n) {
    const std::int64_t t_ns = n * 1'000'000LL;
    while (next_tooth <= t_ns) {
      pipe.on_tooth(tooth(next_tooth, tooth_dt));
      next_tooth += static_cast<std::int64_t>(std::llround(tooth_dt * 1e9));
    }
    pipe.step(t_ns, sig);
  }
  EXPECT_EQ(scope.count(), 0u);
  const auto& out = pipe.output();
  EXPECT_EQ(out.input.speed, InputStatus::kOk);
  EXPECT_NEAR(out.input.speed_rad_s, 250.0, 0.5);  // tooth times rounded to ns
  EXPECT_NEAR(out.uio.torque_nm, 60.0, 0.5);
  EXPECT_EQ(out.uio.health, Health::kValid);
  EXPECT_NEAR(out.dirty_diff.torque_nm, 60.0, 0.5);
  EXPECT_NEAR(out.adaptive.torque_nm, 60.0, 0.5);
  EXPECT_EQ(out.adaptive.health, Health::kNotExcited);  // steady: no excitation (Na Remark 9)
  EXPECT_EQ(out.uio.t_ns, 2'000'000'000);

  // WHEN the teeth stop (stall / edge source lost) THEN the speed goes stale after the time-out
  for (int n = 2001; n <= 2100; ++n) pipe.step(n * 1'000'000LL, sig);
  EXPECT_EQ(pipe.output().input.speed, InputStatus::kStale);
  EXPECT_EQ(pipe.output().uio.health, Health::kStaleInput);
  // AND when CAN loses the load torque it is stale too
  auto no_load = sig;
  no_load.load_torque_valid = false;
  pipe.step(2'101'000'000LL, no_load);
  EXPECT_EQ(pipe.output().input.load, InputStatus::kStale);
}

TEST(TimePipeline, UnsyncedDecoderIsInvalidAndDisabledEstimatorsSaySo) {
  auto p = pipeline_params();
  p.sliding_mode = false;
  p.adaptive = false;
  TimePipeline pipe(p, TimeEstimatorParams{}, EngineGeometry{});
  pipe.step(1'000'000, signals(50.0, 0.01));
  EXPECT_EQ(pipe.output().uio.health, Health::kInvalidInput);
  EXPECT_EQ(pipe.output().sliding_mode.health, Health::kDisabled);
  EXPECT_EQ(pipe.output().adaptive.health, Health::kDisabled);
}

TEST(TimePipeline, InertiaFromGeometryIsRotatingPlusMeanOscillating) {
  auto p = pipeline_params();
  p.inertia_kgm2 = 0.0;
  const EngineGeometry g{};
  TimePipeline pipe(p, TimeEstimatorParams{}, g);
  // cycle mean of Σ m R² f² ≈ n·m·R²·(1/2)(1 + λ²/4) for the slider-crank
  const double r = g.crank_radius_m(), lam = r / g.rod_m;
  const double approx = g.j_rot_kgm2 + g.cylinders * g.m_osc_kg * r * r * 0.5 * (1.0 + lam * lam / 4.0);
  EXPECT_NEAR(pipe.inertia_kgm2(), approx, 0.01 * (approx - g.j_rot_kgm2));
}

}  // namespace
}  // namespace torqued
