// Dirty-differentiation estimator (Na-24): exact for constant torque, but passes the raw load noise through
// (Na Lemma 5) where the UIO filters it; holds on bad input; no allocation.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "alloc_counter.hpp"
#include "dirty_diff.hpp"
#include "time_test_plant.hpp"
#include "uio.hpp"

namespace torqued {
namespace {
using test::AnalyticPlant;
using test::make_sample;
constexpr double kStep = 0.001;

TEST(DirtyDiff, ConstantTorqueIsRecoveredExactly) {
  AnalyticPlant plant{.tau0 = 95.0, .load = 40.0};
  DirtyDiff dd(DirtyDiffParams{.k_s = 0.01}, plant.inertia, kStep);
  for (int n = 0; n <= 500; ++n) dd.update(make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load));
  EXPECT_NEAR(dd.estimate().torque_nm, 95.0, 95.0 * 1e-6);
  EXPECT_EQ(dd.estimate().health, Health::kValid);
}

TEST(DirtyDiff, LoadNoisePassesUnfilteredUnlikeTheUio) {
  // GIVEN constant speed and torque, and white noise σ = 5 N m on the measured load only
  const double j = 0.14, sigma = 5.0;
  DirtyDiff dd(DirtyDiffParams{.k_s = 0.01}, j, kStep);
  Uio uio(UioParams{.k_s = 0.01}, j, kStep);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, sigma);
  double dd2 = 0.0, uio2 = 0.0;
  int count = 0;
  for (int n = 0; n < 20000; ++n) {
    const auto s = make_sample(n * kStep, kStep, 250.0, 60.0 + noise(rng));
    dd.update(s);
    uio.update(s);
    if (n < 1000) continue;
    dd2 += std::pow(dd.estimate().torque_nm - 60.0, 2);
    uio2 += std::pow(uio.estimate().torque_nm - 60.0, 2);
    ++count;
  }
  // THEN the dirty-diff error has the full noise σ, the UIO only σ·√(α/(2−α)) (ZOH low-pass of white noise)
  const double alpha = -std::expm1(-kStep / 0.01);
  EXPECT_NEAR(std::sqrt(dd2 / count), sigma, 0.05 * sigma);
  EXPECT_NEAR(std::sqrt(uio2 / count), sigma * std::sqrt(alpha / (2.0 - alpha)), 0.05 * sigma);
}

TEST(DirtyDiff, BadInputHoldsWithReasonAndNoAllocation) {
  AnalyticPlant plant;
  DirtyDiff dd(DirtyDiffParams{}, plant.inertia, kStep);
  test::AllocationScope scope;
  for (int n = 0; n < 1000; ++n) dd.update(make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load));
  EXPECT_EQ(scope.count(), 0u);
  const double held = dd.estimate().torque_nm;
  auto s = make_sample(1.0, 0.0, plant.speed(1.0), plant.load);  // zero step: invalid
  dd.update(s);
  EXPECT_EQ(dd.estimate().health, Health::kInvalidInput);
  EXPECT_EQ(dd.estimate().torque_nm, held);
}

}  // namespace
}  // namespace torqued
