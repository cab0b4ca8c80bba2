// Per-tooth pre-processing: angle table of the wheel, speed from the true width, low-pass, θ̈ Kalman filter.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "alloc_counter.hpp"
#include "tooth_preprocessor.hpp"

namespace torqued {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(ToothAngleTable, SixtyMinusTwoHas116SamplesAndAnEighteenDegreeGap) {
  const auto t = ToothAngleTable::build(EngineGeometry{}, WheelGeometry{});
  ASSERT_EQ(t.samples, 116);
  EXPECT_NEAR(t.width_rad[0], 18.0 * kPi / 180.0, 1e-12);   // gap period ends at tooth 0
  EXPECT_NEAR(t.width_rad[58], 18.0 * kPi / 180.0, 1e-12);  // and again one revolution later
  EXPECT_NEAR(t.width_rad[1], 6.0 * kPi / 180.0, 1e-12);
  EXPECT_NEAR(t.edge_rad[58], 2.0 * kPi, 1e-12);
  double sum = 0.0;
  for (double s : t.step_rad) sum += s;
  EXPECT_NEAR(sum, 4.0 * kPi, 1e-9);  // the steps between period centres cover the cycle exactly
  const CrankKinematics kin(EngineGeometry{});
  EXPECT_NEAR(t.j_edge[10], kin.inertia(t.edge_rad[10] - EngineGeometry{}.tdc_offset_rad), 1e-15);
}

TEST(ToothAngleTable, ExplicitToothListAndThirtySixMinusOne) {
  WheelGeometry w;
  w.positions = 36;
  w.missing = 1;
  const auto t = ToothAngleTable::build(EngineGeometry{}, w);
  EXPECT_EQ(t.samples, 70);
  EXPECT_NEAR(t.width_rad[0], 20.0 * kPi / 180.0, 1e-12);
  WheelGeometry e;  // the same wheel as an explicit list
  e.tooth_count = 35;
  for (int i = 0; i < 35; ++i) e.tooth_angles_deg[static_cast<std::size_t>(i)] = 100.0 + 10.0 * i;
  const auto t2 = ToothAngleTable::build(EngineGeometry{}, e);
  for (int k = 0; k < 70; ++k)
    EXPECT_NEAR(t2.width_rad[static_cast<std::size_t>(k)], t.width_rad[static_cast<std::size_t>(k)], 1e-12);
}

TEST(ToothPreprocessor, ConstantAccelerationIsRecovered) {
  // GIVEN a crank accelerating at a constant 200 rad/s² from 150 rad/s, ideal edges on a 60-2 wheel
  ToothPreprocessor pp(EngineGeometry{}, WheelGeometry{}, PreprocessParams{});
  const auto& t = pp.table();
  const double alpha = 200.0, w0 = 150.0;
  double angle = 0.0;
  std::int64_t prev_ns = 0;
  test::AllocationScope scope;
  int valid = 0;
  for (int n = 0; n < 3 * t.samples; ++n) {
    const int k = n % t.samples;
    angle += n == 0 ? 0.0 : t.width_rad[static_cast<std::size_t>(k)];
    // θ(t) = w0 t + ½ α t²  →  t(θ) = (−w0 + sqrt(w0² + 2αθ))/α
    const double time = (-w0 + std::sqrt(w0 * w0 + 2.0 * alpha * angle)) / alpha;
    const auto t_ns = static_cast<std::int64_t>(std::llround(time * 1e9));
    ToothSample s;
    s.t_ns = t_ns;
    s.tooth = k;
    s.width_rad = t.width_rad[static_cast<std::size_t>(k)];
    s.dt_s = 1e-9 * static_cast<double>(t_ns - prev_ns);
    s.synced = n > 0;
    prev_ns = t_ns;
    pp.update(s);
    if (pp.state().valid) ++valid;
    if (n > t.samples) {
      // THEN θ̈ within 2 % and the speed within 0.1 % of the true mean over the tooth
      EXPECT_NEAR(pp.state().accel_rad_s2, alpha, 4.0) << n;
      const double t_mid = time - 0.5 * s.dt_s;
      EXPECT_NEAR(pp.state().speed_rad_s, w0 + alpha * t_mid, 0.001 * w0) << n;
    }
  }
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_GT(valid, 2 * t.samples);
  EXPECT_EQ(pp.stats().not_synced, 1u);
}

TEST(ToothPreprocessor, RejectsAndCountsBadSamples) {
  ToothPreprocessor pp(EngineGeometry{}, WheelGeometry{}, PreprocessParams{});
  ToothSample s;
  s.synced = true;
  s.dt_s = 0.0;
  s.width_rad = 0.1;
  EXPECT_FALSE(pp.update(s));
  s.dt_s = 1e-3;
  s.tooth = -1;
  EXPECT_FALSE(pp.update(s));
  EXPECT_EQ(pp.stats().invalid, 2u);
  EXPECT_FALSE(pp.state().valid);
}

TEST(ToothPreprocessor, RelativeNoiseOfSpeedSquared) {
  // 0.05° edges on a 6° tooth: 2·sqrt(2)·0.05/6 ≈ 2.4 % on θ̇² (the expected figure)
  const double rel = ToothPreprocessor::speed_sq_rel_sd(6.0 * kPi / 180.0, 200.0, 0.05 * kPi / 180.0, 0.0);
  EXPECT_NEAR(rel, 0.0236, 0.0005);
}

}  // namespace
}  // namespace torqued
