// InertiaLearner (estimators/learners/inertia_learner.hpp): J = k·J_spec from pairs of consecutive cycles,
// k·x = y with x = Δ(J_spec θ̈) and y the torque change that balances it. Truth: pairs generated from a known
// k with noise of the stated σ; tolerances from the learner's own 1σ.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "inertia_learner.hpp"

namespace torqued {
namespace {

// Load steps of ±5..40 N m seen by an engine whose true J is `k_true` × spec; pair noise 1σ = `noise_nm`.
void feed(InertiaLearner& l, double k_true, double noise_nm, int pairs, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> step(5.0, 40.0);
  std::normal_distribution<double> noise(0.0, noise_nm);
  for (int i = 0; i < pairs; ++i) {
    const double y = (i % 2 ? 1.0 : -1.0) * step(rng);  // the torque change (−ΔT_load …)
    const double x = y / k_true;                        // what the spec J sees: Δ(J_spec θ̈) = y / k
    (void)l.observe(x, y + noise(rng));
  }
}

TEST(InertiaLearner, StartsAtTheSpecSheet) {
  InertiaLearner l(InertiaParams{});
  EXPECT_EQ(l.scale(), 1.0);
  EXPECT_TRUE(l.is_prior());
  EXPECT_NEAR(l.scale_sd(), InertiaParams{}.prior_rel_sd, 1e-12);
}

TEST(InertiaLearner, LearnsAFlywheelNineteenPercentHeavierThanTheSpecSheet) {
  for (double k_true : {0.82, 0.93, 1.09, 1.19}) {
    InertiaLearner l(InertiaParams{});
    feed(l, k_true, 1.5, 40, 7);
    EXPECT_FALSE(l.is_prior());
    EXPECT_NEAR(l.scale(), k_true, 3.0 * l.scale_sd()) << "k_true " << k_true;
    EXPECT_LT(l.scale_sd(), 0.02);  // 40 pairs of 5-40 N m at 1.5 N m noise: σ_k ≈ 1.5 / √Σx² ≈ 0.01
    EXPECT_EQ(l.rejected(), 0u);
  }
}

TEST(InertiaLearner, NoExcitationLeavesThePriorAlone) {
  InertiaLearner l(InertiaParams{});
  for (int i = 0; i < 1000; ++i) EXPECT_FALSE(l.observe(0.5 * ((i % 3) - 1), 2.0));  // |x| < min_step_nm
  EXPECT_EQ(l.scale(), 1.0);
  EXPECT_TRUE(l.is_prior());
}

TEST(InertiaLearner, OneBadPairIsRejectedAndCannotMoveTheEstimate) {
  InertiaLearner l(InertiaParams{});
  feed(l, 1.1, 1.5, 30, 3);
  const double k = l.scale();
  // A load step the CAN frame reported one cycle late: y says 60 N m where x says 10.
  EXPECT_FALSE(l.observe(10.0, 60.0));
  EXPECT_EQ(l.rejected(), 1u);
  EXPECT_EQ(l.scale(), k);
  EXPECT_FALSE(l.observe(std::nan(""), 1.0));
}

TEST(InertiaLearner, BoundedAndPersistedExactly) {
  InertiaParams p;
  InertiaLearner l(p);
  feed(l, 1.1, 1.5, 20, 5);
  InertiaLearner m(p);
  ASSERT_TRUE(m.import_state(l.scale(), l.information()));
  EXPECT_EQ(m.scale(), l.scale());
  EXPECT_EQ(m.scale_sd(), l.scale_sd());
  EXPECT_FALSE(m.is_prior());
  // Learning goes on from the imported estimate exactly as from the live one.
  EXPECT_EQ(l.observe(20.0, 22.4), m.observe(20.0, 22.4));
  EXPECT_DOUBLE_EQ(m.scale(), l.scale());
  InertiaLearner r(p);
  EXPECT_FALSE(r.import_state(p.max_scale + 0.1, 1e4));  // outside the bounds
  EXPECT_FALSE(r.import_state(1.0, 1.0));                // less information than the prior itself
  EXPECT_TRUE(r.is_prior());
}

TEST(InertiaLearner, TheSpecSheetHoldsUntilTheEstimateIsTight) {
  InertiaParams p;
  InertiaLearner l(p);
  EXPECT_TRUE(l.observe(20.0, 22.0));  // one pair says +10 %
  EXPECT_GT(l.scale(), 1.05);
  EXPECT_GT(l.scale_sd(), p.apply_max_sd);
  EXPECT_EQ(l.applied_scale(), 1.0);  // not yet used by the balances
  feed(l, 1.1, 1.5, 30, 9);
  EXPECT_LE(l.scale_sd(), p.apply_max_sd);
  EXPECT_EQ(l.applied_scale(), l.scale());
}

TEST(InertiaLearner, LearningOffHoldsTheSpecSheet) {
  InertiaParams p;
  p.learn = false;
  InertiaLearner l(p);
  feed(l, 1.2, 0.5, 20, 1);
  EXPECT_EQ(l.scale(), 1.0);
}

}  // namespace
}  // namespace torqued
