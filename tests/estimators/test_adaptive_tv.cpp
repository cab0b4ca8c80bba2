// Adaptive time-varying parameter estimator (Na-41..54): convergence to known parameters under persistent
// excitation for both laws, excitation monitor, closed-form λ_min, exactness of P/K⁻¹ propagation,
// step-size robustness of the backward-Euler θ̂ update, input health, no allocation.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <numbers>

#include "adaptive_tv.hpp"
#include "alloc_counter.hpp"
#include "time_test_plant.hpp"

namespace torqued {
namespace {
using test::make_sample;
constexpr double kJ = 0.14;

/// Excited operating point: ω and ṁ vary at different frequencies; τ_e = θ_si·[ω, ṁ] with constant θ,
/// and the load is whatever makes J ω̇ = τ_e − τ_l hold exactly.
struct ExcitedPlant {
  double theta_speed = 0.05;  ///< N m s/rad
  double theta_maf = 3000.0;  ///< N m s/kg
  double omega(double t) const { return 220.0 + 25.0 * std::sin(2.0 * std::numbers::pi * 0.7 * t); }
  double domega(double t) const {
    return 25.0 * 2.0 * std::numbers::pi * 0.7 * std::cos(2.0 * std::numbers::pi * 0.7 * t);
  }
  double maf(double t) const { return 0.015 + 0.005 * std::sin(2.0 * std::numbers::pi * 1.9 * t + 0.5); }
  double torque(double t) const { return theta_speed * omega(t) + theta_maf * maf(t); }
  double load(double t) const { return torque(t) - kJ * domega(t); }
  TimeSample sample(double t, double dt) const { return make_sample(t, dt, omega(t), load(t), maf(t)); }
};

AdaptiveParams params_for(bool tv, double kappa) {
  AdaptiveParams p;
  p.time_varying_gain = tv;
  p.kappa = kappa;
  return p;
}

/// Law (50) converges at rate Γ·λ_min(P) (Na Theorem 3); the paper's Γ = diag(0.1, 100) is slow along the
/// weakly excited direction, so convergence tests give law (50) a gain matched to this excitation (λ_min(P) ≈
/// 1e-3..1e-2).
AdaptiveParams converging_params_for(bool tv, double kappa) {
  AdaptiveParams p = params_for(tv, kappa);
  if (!tv) p.gamma = {2000.0, 2000.0};
  return p;
}

class AdaptiveLaws : public ::testing::TestWithParam<std::pair<bool, double>> {};

TEST_P(AdaptiveLaws, ConvergesToConstantParametersUnderPersistentExcitation) {
  const auto [tv, kappa] = GetParam();
  ExcitedPlant plant;
  const double step = 0.001;
  AdaptiveTv est(converging_params_for(tv, kappa), kJ, step);
  double t = 0.0;
  for (int n = 0; n <= 60000; ++n) {
    t = n * step;
    est.update(plant.sample(t, step));
  }
  // THEN θ̂ → θ (Na Remark 8: constant θ, error → 0 up to the O(T) discretisation residual) and τ̂ → τ_e
  const auto th = est.theta_si();
  EXPECT_NEAR(th[0], plant.theta_speed, 0.02 * plant.theta_speed) << "law " << (tv ? 54 : 50);
  EXPECT_NEAR(th[1], plant.theta_maf, 0.02 * plant.theta_maf);
  EXPECT_NEAR(est.estimate().torque_nm, plant.torque(t), 0.002 * plant.torque(t));
  EXPECT_EQ(est.estimate().health, Health::kValid);
  EXPECT_GT(est.lambda_min_p(), AdaptiveParams{}.sigma) << est.lambda_min_p();
  EXPECT_DOUBLE_EQ(est.estimate().uncertainty, est.lambda_min_p());
}

INSTANTIATE_TEST_SUITE_P(Na, AdaptiveLaws,
                         ::testing::Values(std::pair{false, 0.0}, std::pair{false, 0.1}, std::pair{true, 0.0},
                                           std::pair{true, 0.1}));

TEST(AdaptiveTv, ConstantRegressorIsFlaggedNotExcitedAndKStaysBounded) {
  // GIVEN steady operation (φ constant: rank-1 P, Na Lemma 8 fails) for 60 s
  AdaptiveTv est(params_for(true, 0.1), kJ, 0.001);
  for (int n = 0; n < 60000; ++n) est.update(make_sample(n * 0.001, 0.001, 230.0, 45.0, 0.014));
  EXPECT_EQ(est.estimate().health, Health::kNotExcited);
  EXPECT_LT(est.lambda_min_p(), 1e-9);
  // the torque itself is still right (τ = φᵀθ̂ only needs θ̂ along φ)
  EXPECT_NEAR(est.estimate().torque_nm, 45.0, 1e-6 * 45.0);
  // AND the K⁻¹ floor keeps K finite: ≤ 1/(k0_floor·K0)
  const AdaptiveParams p;
  EXPECT_TRUE(est.gain_k().allFinite());
  EXPECT_LE(est.gain_k().norm(), 1.01 / (p.k0_floor * p.k0[0]));
}

TEST(AdaptiveTv, LambdaMinClosedFormMatchesEigenSolver) {
  AdaptiveTv::Mat a;
  for (const auto& v :
       {std::array<double, 3>{2.0, 0.5, 1.0}, {1e-6, 1e-7, 3.0}, {4.0, 0.0, 4.0}, {0.3, -0.2, 0.1}}) {
    a << v[0], v[1], v[1], v[2];
    Eigen::SelfAdjointEigenSolver<AdaptiveTv::Mat> es(a);
    EXPECT_NEAR(AdaptiveTv::lambda_min(a), es.eigenvalues()[0], 1e-12 * (1.0 + a.norm()));
  }
}

TEST(AdaptiveTv, KInverseEqualsDecayedK0PlusP) {
  // Na-53: K⁻¹(t) = e^{−ℓt}K0 + P(t) (plus the floor term (1 − e^{−ℓt})·k0_floor·K0 of this implementation).
  ExcitedPlant plant;
  AdaptiveParams p = params_for(true, 0.1);
  AdaptiveTv est(p, kJ, 0.001);
  const int steps = 2500;
  for (int n = 0; n < steps; ++n) est.update(plant.sample(n * 0.001, 0.001));
  const double decay = std::exp(-p.ell * steps * 0.001);
  const AdaptiveTv::Mat k0 = AdaptiveTv::Vec(p.k0[0], p.k0[1]).asDiagonal();
  const AdaptiveTv::Mat expected = decay * k0 + (1.0 - decay) * p.k0_floor * k0 + est.p();
  EXPECT_LT((est.gain_k_inverse() - expected).norm(), 1e-9 * expected.norm());
  EXPECT_LT((est.gain_k() * est.gain_k_inverse() - AdaptiveTv::Mat::Identity()).norm(), 1e-9);
}

TEST(AdaptiveTv, StepSizeBarelyChangesTheTrajectory) {
  // Backward Euler on θ̂ is first-order: 1 ms vs 0.1 ms on the same continuous signals stay close during the
  // convergence transient (exact parts — filters, P, Q, K⁻¹ — contribute O(T) only through φ_f sampling).
  ExcitedPlant plant;
  for (const bool tv : {false, true}) {
    AdaptiveTv coarse(params_for(tv, 0.1), kJ, 0.001);
    AdaptiveTv fine(params_for(tv, 0.1), kJ, 0.0001);
    double max_diff = 0.0;
    for (int n = 0; n < 30000; ++n) {
      const double t = n * 0.0001;
      fine.update(plant.sample(t, 0.0001));
      if (n % 10 == 0) {
        coarse.update(plant.sample(t, 0.001));
        if (t > 0.5)
          max_diff = std::max(max_diff, std::abs(coarse.estimate().torque_nm - fine.estimate().torque_nm));
      }
    }
    EXPECT_LT(max_diff, 0.01 * plant.torque(0.0)) << "law " << (tv ? 54 : 50);
  }
}

TEST(AdaptiveTv, MissingAirFlowHoldsWithReasonAndNoAllocation) {
  ExcitedPlant plant;
  AdaptiveTv est(params_for(true, 0.1), kJ, 0.001);
  test::AllocationScope scope;
  for (int n = 0; n < 2000; ++n) est.update(plant.sample(n * 0.001, 0.001));
  EXPECT_EQ(scope.count(), 0u);
  const auto theta = est.theta();
  const double held = est.estimate().torque_nm;
  auto s = plant.sample(2.0, 0.001);
  s.maf = InputStatus::kStale;
  est.update(s);
  EXPECT_EQ(est.estimate().health, Health::kStaleInput);
  EXPECT_EQ(est.estimate().torque_nm, held);
  EXPECT_EQ(est.theta(), theta);
  s.maf = InputStatus::kOk;
  s.maf_kg_s = std::nan("");
  est.update(s);
  EXPECT_EQ(est.estimate().health, Health::kInvalidInput);
}

}  // namespace
}  // namespace torqued
