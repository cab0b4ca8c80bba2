// IndicatedEso (Energies 2019 EN-16..23, angle/energy form): converges to the true mean indicated torque even
// when the efficiency model is wrong, and follows a step.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "alloc_counter.hpp"
#include "indicated_eso.hpp"

using namespace torqued;

namespace {
constexpr double kPi = std::numbers::pi;
// Synthetic engine: segments of π rad; KE follows dKE/dθ = T_ind − T_fric − T_load exactly.
struct Plant {
  double ke = 0.5 * 0.17 * 209.0 * 209.0;
  double speed() const { return std::sqrt(2.0 * ke / 0.17); }
};
}  // namespace

TEST(IndicatedEso, ConvergesWithAWrongEfficiencyModelAndTracksAStep) {
  EngineGeometry g;
  EnergiesParams p;
  p.eso_base_efficiency = 0.5;  // 30 % below the plant's
  IndicatedEso eso(g, p);
  Plant plant;
  const double fuel = 20e-6;  // kg per injection per cylinder
  const double q_mass = 4 * fuel * p.fuel_lhv_j_kg / (4.0 * kPi);
  double t_ind = 0.0;
  std::int64_t t = 0;
  for (int k = 0; k < 400; ++k) {
    const double eff = k < 200 ? 0.28 : 0.31;  // efficiency step at segment 200
    t_ind = eff * q_mass;
    const double fric = 25.0, load = t_ind - fric - (k % 50 < 25 ? 2.0 : -2.0);  // small accelerations
    const double dt = kPi / plant.speed();
    plant.ke += kPi * (t_ind - fric - load);
    t += static_cast<std::int64_t>(dt * 1e9);
    EsoInput in{t, plant.ke, kPi, dt, fuel, 1.0, fric, load, true};
    ASSERT_TRUE(eso.update(in));
    if (k == 199 || k == 399) {
      EXPECT_EQ(eso.estimate().health, Health::kValid);
      EXPECT_NEAR(eso.estimate().torque_nm, t_ind, 0.01 * t_ind) << k;
    }
  }
}

TEST(IndicatedEso, InvalidInputIsRejectedNotPropagated) {
  IndicatedEso eso(EngineGeometry{}, EnergiesParams{});
  EsoInput in{1, std::nan(""), kPi, 0.015, 20e-6, 1.0, 25.0, 50.0, true};
  EXPECT_FALSE(eso.update(in));
  EXPECT_EQ(eso.estimate().health, Health::kInvalidInput);
  EXPECT_TRUE(std::isfinite(eso.estimate().torque_nm));
}

TEST(IndicatedEso, DoesNotAllocate) {
  IndicatedEso eso(EngineGeometry{}, EnergiesParams{});
  torqued::test::AllocationScope scope;
  for (int k = 0; k < 100; ++k) eso.update({k, 3000.0 + k, kPi, 0.015, 20e-6, 1.0, 25.0, 50.0, true});
  EXPECT_EQ(scope.count(), 0u);
}
