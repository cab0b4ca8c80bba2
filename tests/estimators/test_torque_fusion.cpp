// TorqueFusion: the documented rule (torque_fusion.hpp) — priority, CAN loss, blending gate, invalid hold.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "alloc_counter.hpp"
#include "torque_fusion.hpp"

using namespace torqued;

namespace {
FusionInput inputs(std::int64_t t_ns, std::int64_t can_ns) {
  FusionInput in;
  in.t_ns = t_ns;
  in.can_t_ns = can_ns;
  in.can_seen = true;
  auto& e = in.src[0];
  e = {100.0, 1.0, Health::kValid, true, can_ns};
  in.src[1] = {104.0, 4.0, Health::kValid, false, t_ns};
  in.src[2] = {150.0, 5.0, Health::kValid, true, can_ns};  // far off: outside the gate
  return in;
}
}  // namespace

FusionParams blending() {
  FusionParams p;
  p.blend = true;
  return p;
}

TEST(TorqueFusion, PrefersEnergyWithCanAndBlendsOnlyAgreeingSources) {
  TorqueFusion f(blending());
  const auto& o = f.update(inputs(1'000'000'000, 995'000'000));
  EXPECT_EQ(o.quality, FusionQuality::kFull);
  EXPECT_EQ(o.primary, FusionSourceId::kEnergyCan);
  EXPECT_EQ(o.used_mask, 0b011);  // ESO at 150 N m is 50 N m away: not blended
  const double w0 = 1.0, w1 = 1.0 / 16.0;
  EXPECT_NEAR(o.brake_nm, (100.0 * w0 + 104.0 * w1) / (w0 + w1), 1e-9);
  EXPECT_FALSE(o.can_lost);
  EXPECT_EQ(o.age_ns, 0);  // the crank-only source went in: its newest input is the current tooth
}

TEST(TorqueFusion, FallsBackToCrankOnlyWhenCanIsLostAndSaysSo) {
  TorqueFusion f(FusionParams{});
  const auto& o = f.update(inputs(2'000'000'000, 1'500'000'000));  // CAN 0.5 s old > 0.1 s
  EXPECT_TRUE(o.can_lost);
  EXPECT_EQ(o.quality, FusionQuality::kCrankOnly);
  EXPECT_EQ(o.primary, FusionSourceId::kCrankOnly);
  EXPECT_DOUBLE_EQ(o.brake_nm, 104.0);
  EXPECT_EQ(o.age_ns, 0);
}

TEST(TorqueFusion, PickOnlyWhenBlendingIsOff) {
  TorqueFusion f(FusionParams{});  // default: pick the primary
  const auto& o = f.update(inputs(1'000'000'000, 995'000'000));
  EXPECT_DOUBLE_EQ(o.brake_nm, 100.0);
  EXPECT_EQ(o.age_ns, 5'000'000);  // newest input of the energy+CAN source: the CAN frame
}

TEST(TorqueFusion, NothingUsableHoldsLastValueAndIsInvalid) {
  TorqueFusion f(FusionParams{});
  f.update(inputs(1'000'000'000, 995'000'000));
  FusionInput in = inputs(1'050'000'000, 1'000'000'000);
  for (auto& s : in.src) s.health = Health::kNotConverged;
  const auto& o = f.update(in);
  EXPECT_EQ(o.quality, FusionQuality::kInvalid);
  EXPECT_NE(o.health, Health::kValid);
  EXPECT_TRUE(std::isfinite(o.brake_nm));
  EXPECT_GT(o.age_ns, 50'000'000 - 1);
}

TEST(TorqueFusion, NanSourceIsNeverUsed) {
  TorqueFusion f(FusionParams{});
  FusionInput in = inputs(1'000'000'000, 995'000'000);
  in.src[0].brake_nm = std::nan("");
  const auto& o = f.update(in);
  EXPECT_EQ(o.primary, FusionSourceId::kCrankOnly);
  EXPECT_TRUE(std::isfinite(o.brake_nm));
}

TEST(TorqueFusion, DoesNotAllocate) {
  TorqueFusion f(FusionParams{});
  const FusionInput in = inputs(1'000'000'000, 995'000'000);
  torqued::test::AllocationScope scope;
  for (int i = 0; i < 100; ++i) f.update(in);
  EXPECT_EQ(scope.count(), 0u);
}

TEST(TorqueFusion, BlendOfDisagreeingSourcesClaimsTheirSpreadNotTheirCombinedSigma) {
  // GIVEN two blended sources 3 N m apart, each claiming 1σ = 1 N m (within the 3σ gate, but 2.1σ apart)
  TorqueFusion f(blending());
  FusionInput in = inputs(1'000'000'000, 995'000'000);
  in.src[1] = {103.0, 1.0, Health::kValid, false, in.t_ns};
  in.src[2].health = Health::kDisabled;
  const auto& o = f.update(in);
  ASSERT_EQ(o.used_mask, 0b011);
  // THEN the mean is the inverse-variance one, and its 1σ is scaled by the PDG factor √(χ²/(n−1)) = √4.5:
  // 1.5 N m, not the 0.71 N m two consistent sources would give
  EXPECT_NEAR(o.brake_nm, 101.5, 1e-9);
  EXPECT_NEAR(o.sd_nm, std::sqrt(0.5) * std::sqrt(4.5), 1e-9);
  // AND sources that agree within their 1σ keep the combined 1σ (no scaling below 1)
  in.src[1].brake_nm = 100.5;
  EXPECT_NEAR(f.update(in).sd_nm, std::sqrt(0.5), 1e-9);
}

TEST(TorqueFusion, WithoutTheEnergyBalanceALeaderThatItsWitnessContradictsWidensItsSigma) {
  // GIVEN no measured load (energy balance not usable), blending off: the crank chain claims 1 N m at 100,
  // the fuel model 2 N m at 106 (within the 3σ gate of √5 · 3 = 6.7 N m, but 2.7σ apart)
  TorqueFusion f(FusionParams{});
  FusionInput in = inputs(1'000'000'000, 995'000'000);
  in.src[0].health = Health::kNotConverged;
  in.src[1] = {100.0, 1.0, Health::kValid, false, in.t_ns};
  in.src[2] = {106.0, 2.0, Health::kValid, true, in.can_t_ns};
  const auto& o = f.update(in);
  // THEN the crank chain leads (smallest claim) with its value, and its 1σ takes the PDG factor √(36/5)
  EXPECT_EQ(o.primary, FusionSourceId::kCrankOnly);
  EXPECT_NEAR(o.brake_nm, 100.0, 1e-9);
  EXPECT_NEAR(o.sd_nm, std::sqrt(36.0 / 5.0), 1e-9);
  // AND a witness within the claims, or outside the gate, leaves it alone
  in.src[2].brake_nm = 101.5;
  EXPECT_NEAR(f.update(in).sd_nm, 1.0, 1e-9);
  in.src[2].brake_nm = 120.0;
  EXPECT_NEAR(f.update(in).sd_nm, 1.0, 1e-9);
  // AND with the energy balance leading nothing changes (the dynamometer case)
  FusionInput dyno = inputs(1'000'000'000, 995'000'000);
  dyno.src[1] = {103.0, 1.0, Health::kValid, false, dyno.t_ns};
  EXPECT_NEAR(f.update(dyno).sd_nm, 1.0, 1e-9);
}
