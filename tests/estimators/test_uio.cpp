// UIO (Na-9, Na-14): analytic checks against the exact crankshaft plant, exact discretisation, input health,
// no allocation in update().
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "alloc_counter.hpp"
#include "time_test_plant.hpp"
#include "uio.hpp"

namespace torqued {
namespace {
using test::AnalyticPlant;
using test::make_sample;

constexpr double kStep = 0.001;

TEST(Uio, ConstantTorqueIsRecoveredExactlyWhileAccelerating) {
  // GIVEN a constant effective torque larger than the load (the engine accelerates: ω is a ramp)
  AnalyticPlant plant;  // τ_e = 80, τ_l = 50
  Uio uio(UioParams{.k_s = 0.01}, plant.inertia, kStep);
  // WHEN the UIO runs for 0.5 s (50 time constants)
  for (int n = 0; n <= 500; ++n) {
    const double t = n * kStep;
    uio.update(make_sample(t, kStep, plant.speed(t), plant.load));
  }
  // THEN the torque is exact to 1e-6 relative (Na-17 with τ̇_e = 0) and the estimate is valid
  EXPECT_NEAR(uio.estimate().torque_nm, 80.0, 80.0 * 1e-6);
  EXPECT_EQ(uio.estimate().health, Health::kValid);
  EXPECT_EQ(uio.estimate().t_ns, 500'000'000);
}

TEST(Uio, ConstantTorqueExactForAnyStep) {
  for (const double step : {0.0001, 0.001, 0.005, 0.02}) {
    AnalyticPlant plant{.tau0 = 120.0, .load = 150.0};  // decelerating
    Uio uio(UioParams{.k_s = 0.01}, plant.inertia, step);
    const int steps = static_cast<int>(std::lround(1.0 / step));
    for (int n = 0; n <= steps; ++n)
      uio.update(make_sample(n * step, step, plant.speed(n * step), plant.load));
    EXPECT_NEAR(uio.estimate().torque_nm, 120.0, 120.0 * 1e-6) << "step " << step;
  }
}

TEST(Uio, TorqueRampLagsByKTimesRate) {
  // GIVEN τ_e ramping at r = 200 N m/s; Na-17 predicts a steady lag ε = k·r in continuous time.
  const double k = 0.01, r = 200.0;
  AnalyticPlant plant{.tau0 = 60.0, .rate = r, .load = 60.0};
  Uio uio(UioParams{.k_s = k}, plant.inertia, kStep);
  double t = 0.0;
  for (int n = 0; n <= 400; ++n) {
    t = n * kStep;
    uio.update(make_sample(t, kStep, plant.speed(t), plant.load));
  }
  const double lag = plant.torque(t) - uio.estimate().torque_nm;
  // THEN the lag is the exact discrete one, r·(T/α − T/2), which is k·r + O(T²/k) (within 0.1 % here)
  const double alpha = -std::expm1(-kStep / k);
  EXPECT_NEAR(lag, r * (kStep / alpha - kStep / 2.0), 1e-6 * k * r);
  EXPECT_NEAR(lag, k * r, 1e-3 * k * r);
}

TEST(Uio, MatchesContinuousTimeSolutionForSinusoidalTorque) {
  // Na-16: τ̂_e = τ_e/(ks+1). For τ_e = A sin(wt) the steady continuous response is
  // A/√(1+(kw)²)·sin(wt − atan(kw)). The 1 ms discretisation must follow it to O(T).
  const double k = 0.01, w = 2.0 * std::numbers::pi * 5.0, amp = 40.0;
  AnalyticPlant plant{.tau0 = 50.0, .amp = amp, .w = w, .load = 50.0};
  Uio uio(UioParams{.k_s = k}, plant.inertia, kStep);
  double max_err = 0.0;
  for (int n = 0; n <= 2000; ++n) {
    const double t = n * kStep;
    uio.update(make_sample(t, kStep, plant.speed(t), plant.load));
    if (t < 0.5) continue;
    const double expected = 50.0 + amp / std::hypot(1.0, k * w) * std::sin(w * t - std::atan(k * w));
    max_err = std::max(max_err, std::abs(uio.estimate().torque_nm - expected));
  }
  EXPECT_LT(max_err, 0.01 * amp);  // 1 % of the amplitude at T/k = 0.1
}

TEST(Uio, FilterStateMatchesFineStepIntegration) {
  // The ZOH filter x_f[n+1] = x_f[n] + α(x[n] − x_f[n]) is exact for held inputs: compare with RK4 at 1 µs.
  const double k = 0.01;
  FirstOrderFilter<double> f(k, kStep);
  double fine = 0.0;
  for (int n = 0; n < 100; ++n) {
    const double u = 100.0 + 30.0 * std::sin(0.37 * n) + (n % 7);
    f.update(u);
    const int sub = 1000;
    const double h = kStep / sub;
    for (int i = 0; i < sub; ++i) {
      auto d = [&](double x) { return (u - x) / k; };
      const double k1 = d(fine), k2 = d(fine + 0.5 * h * k1), k3 = d(fine + 0.5 * h * k2),
                   k4 = d(fine + h * k3);
      fine += h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4);
    }
    ASSERT_NEAR(f.state(), fine, 1e-9 * std::abs(fine)) << "step " << n;
  }
}

TEST(Uio, StaleAndInvalidInputsHoldTheEstimateWithTheReason) {
  AnalyticPlant plant;
  Uio uio(UioParams{}, plant.inertia, kStep);
  int n = 0;
  for (; n <= 200; ++n) uio.update(make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load));
  const double held = uio.estimate().torque_nm;
  // GIVEN the load torque goes stale (CAN lost)
  auto s = make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load);
  s.load = InputStatus::kStale;
  uio.update(s);
  EXPECT_EQ(uio.estimate().health, Health::kStaleInput);
  EXPECT_EQ(uio.estimate().torque_nm, held);
  // AND a NaN speed is rejected as invalid, never propagated
  ++n;
  s = make_sample(n * kStep, kStep, std::nan(""), plant.load);
  uio.update(s);
  EXPECT_EQ(uio.estimate().health, Health::kInvalidInput);
  EXPECT_EQ(uio.estimate().torque_nm, held);
  // WHEN good inputs return THEN it restarts (not converged), then is valid and exact again
  ++n;
  uio.update(make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load));
  EXPECT_EQ(uio.estimate().health, Health::kNotConverged);
  for (int i = 0; i < 200; ++i) {
    ++n;
    uio.update(make_sample(n * kStep, kStep, plant.speed(n * kStep), plant.load));
  }
  EXPECT_EQ(uio.estimate().health, Health::kValid);
  EXPECT_NEAR(uio.estimate().torque_nm, 80.0, 80.0 * 1e-6);
}

TEST(Uio, UpdateDoesNotAllocate) {
  AnalyticPlant plant;
  Uio uio(UioParams{}, plant.inertia, kStep);
  test::AllocationScope scope;
  for (int n = 0; n < 1000; ++n)
    uio.update(make_sample(n * kStep, n % 3 ? kStep : 1.1 * kStep, plant.speed(n * kStep), plant.load));
  EXPECT_EQ(scope.count(), 0u);
}

}  // namespace
}  // namespace torqued
