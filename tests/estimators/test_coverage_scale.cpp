// CoverageScale: a claimed 1σ that covers 68 % of the residuals whatever their shape.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "coverage_scale.hpp"

using torqued::CoverageScale;

namespace {
/// Fraction of `errs` with |e| <= sd.
double covered(const std::vector<double>& errs, double sd) {
  int n = 0;
  for (double e : errs) n += std::fabs(e) <= sd ? 1 : 0;
  return static_cast<double>(n) / static_cast<double>(errs.size());
}
/// Residuals of a model that fits most operating points well and some badly: 85 % N(0, 0.3), 15 % N(0, 4).
std::vector<double> heavy_tailed(std::mt19937& rng, int n) {
  std::normal_distribution<double> z(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> v;
  for (int i = 0; i < n; ++i) v.push_back((u(rng) < 0.85 ? 0.3 : 4.0) * z(rng));
  return v;
}
TEST(CoverageScale, ObserveFromStartsAtThePriorOnlyWhenNoScaleIsHeld) {
  // GIVEN no scale yet, then a held one
  CoverageScale c;
  // WHEN a residual above the prior arrives with a prior of 2
  c.observe_from(2.0, 3.0, 0.05, 0.1);
  // THEN the step starts from the prior (up by exp(K·0.68)), not from the residual
  EXPECT_NEAR(c.sd, 2.0 * std::exp(CoverageScale::kGain * CoverageScale::kCoverage), 1e-12);
  EXPECT_EQ(c.n, 1u);
  // AND a later prior does not reset what is held
  const double held = c.sd;
  c.observe_from(50.0, held * 0.5, 0.05, 0.1);
  EXPECT_LT(c.sd, held);
  EXPECT_EQ(c.n, 2u);
}

}  // namespace

TEST(CoverageScale, GaussianResidualsGiveTheirSigma) {
  // GIVEN 2000 residuals N(0, 1.7) after a prior of 5 WHEN observed with a step floor of 0.005
  std::mt19937 rng(11);
  std::normal_distribution<double> z(0.0, 1.7);
  CoverageScale c;
  c.start(5.0);
  for (int i = 0; i < 2000; ++i) c.observe(z(rng), 0.005, 0.01);
  // THEN the scale is the sigma within 8 % and covers 68 % ± 4 % of fresh residuals
  EXPECT_NEAR(c.sd, 1.7, 0.08 * 1.7);
  std::vector<double> fresh;
  for (int i = 0; i < 4000; ++i) fresh.push_back(z(rng));
  EXPECT_NEAR(covered(fresh, c.sd), 0.6827, 0.04);
}

TEST(CoverageScale, HeavyTailedResidualsAreCoveredAsClaimedWhereTheirRmsIsNot) {
  // GIVEN heavy-tailed residuals (the fuel model across operating points)
  std::mt19937 rng(5);
  const std::vector<double> learn = heavy_tailed(rng, 3000);
  const std::vector<double> fresh = heavy_tailed(rng, 6000);
  CoverageScale c;
  double ss = 0.0;
  for (double e : learn) {
    c.observe(e, 0.005, 0.01);
    ss += e * e;
  }
  const double rms = std::sqrt(ss / static_cast<double>(learn.size()));
  // THEN their RMS covers far more than 68 % (what the claimed 1σ was before), the scale 68 % ± 4 %
  EXPECT_GT(covered(fresh, rms), 0.84);
  EXPECT_NEAR(covered(fresh, c.sd), 0.6827, 0.04);
}

TEST(CoverageScale, IgnoresZeroAndNonFiniteResidualsAndKeepsItsFloor) {
  CoverageScale c;
  EXPECT_EQ(c.sd, 0.0);
  c.observe(std::nan(""), 0.05, 0.2);
  c.observe(0.0, 0.05, 0.2);
  EXPECT_EQ(c.n, 0u);
  c.observe(0.05, 0.05, 0.2);  // the first residual sets the scale, not below the floor
  EXPECT_EQ(c.sd, 0.2);
  for (int i = 0; i < 500; ++i) c.observe(1e-3, 0.05, 0.2);
  EXPECT_EQ(c.sd, 0.2);
  EXPECT_EQ(c.n, 501u);
}
