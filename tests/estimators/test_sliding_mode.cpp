// Sliding-mode estimator (Na-19..21): equivalent control recovers the torque on average, chatters around it,
// cannot exceed λ1, holds on bad input, no allocation.
#include <gtest/gtest.h>

#include <cmath>

#include "alloc_counter.hpp"
#include "sliding_mode.hpp"
#include "time_test_plant.hpp"

namespace torqued {
namespace {
using test::AnalyticPlant;
using test::make_sample;
constexpr double kStep = 0.001;

TEST(SlidingMode, EquivalentControlRecoversConstantTorqueOnAverage) {
  AnalyticPlant plant;  // τ_e = 80, τ_l = 50
  SlidingMode sm(SlidingModeParams{.k_s = 0.01, .lambda1_nm = 150.0}, plant.inertia, kStep);
  double sum = 0.0, max_dev = 0.0;
  int count = 0;
  for (int n = 0; n <= 1000; ++n) {
    const double t = n * kStep;
    sm.update(make_sample(t, kStep, plant.speed(t), plant.load));
    if (t >= 0.5) {
      sum += sm.estimate().torque_nm;
      max_dev = std::max(max_dev, std::abs(sm.estimate().torque_nm - 80.0));
      ++count;
    }
  }
  // THEN the mean is the torque (equivalent control, Na Lemma 2) within 1 %, and it chatters (Remark 3):
  // the observer stays within one switching step λ1·T/J of the measured speed.
  EXPECT_NEAR(sum / count, 80.0, 0.8);
  EXPECT_GT(max_dev, 0.1);
  EXPECT_LT(max_dev, 150.0);
  EXPECT_NEAR(sm.observed_speed_rad_s(), plant.speed(1.0), 2.0 * 150.0 * kStep / plant.inertia);
  EXPECT_EQ(sm.estimate().health, Health::kValid);
}

TEST(SlidingMode, CannotFollowTorqueAboveLambda1) {
  // Na-19 needs λ1 > sup|τ_e|: with λ1 = 60 N m and τ_e − τ_l = 80 N m the sliding mode is lost.
  AnalyticPlant plant{.tau0 = 130.0, .load = 50.0};
  SlidingMode sm(SlidingModeParams{.k_s = 0.01, .lambda1_nm = 60.0}, plant.inertia, kStep);
  for (int n = 0; n <= 500; ++n) sm.update(make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load));
  EXPECT_NEAR(sm.estimate().torque_nm, 60.0, 1e-6);  // saturated at λ1
}

TEST(SlidingMode, BadInputHoldsWithReason) {
  AnalyticPlant plant;
  SlidingMode sm(SlidingModeParams{}, plant.inertia, kStep);
  for (int n = 0; n < 100; ++n) sm.update(make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load));
  const double held = sm.estimate().torque_nm;
  auto s = make_sample(0.1, kStep, plant.speed(0.1), plant.load);
  s.speed = InputStatus::kStale;
  sm.update(s);
  EXPECT_EQ(sm.estimate().health, Health::kStaleInput);
  EXPECT_EQ(sm.estimate().torque_nm, held);
  s = make_sample(0.101, kStep, plant.speed(0.101), std::numeric_limits<double>::infinity());
  sm.update(s);
  EXPECT_EQ(sm.estimate().health, Health::kInvalidInput);
  EXPECT_EQ(sm.estimate().torque_nm, held);
}

TEST(SlidingMode, UpdateDoesNotAllocate) {
  AnalyticPlant plant;
  SlidingMode sm(SlidingModeParams{}, plant.inertia, kStep);
  test::AllocationScope scope;
  for (int n = 0; n < 1000; ++n) sm.update(make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load));
  EXPECT_EQ(scope.count(), 0u);
}

}  // namespace
}  // namespace torqued
