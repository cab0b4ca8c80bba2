// FuelTorque: fuel-based indicated torque with learned gross efficiency and exhaust pressure (issue 14 item
// 2).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "fuel_torque.hpp"

using torqued::EngineGeometry;
using torqued::FuelTorque;
using torqued::FuelTorqueParams;
using torqued::Health;

namespace {
// Truth of a hypothetical engine that is not the prior: η_g = 0.33, p_exh = 110 kPa.
double truth(const EngineGeometry& g, double fuel_kg, double map_pa) {
  const double vd_4pi =
      std::numbers::pi * 0.25 * g.bore_m * g.bore_m * g.stroke_m * g.cylinders / (4 * std::numbers::pi);
  return 0.33 * g.cylinders * fuel_kg * 43e6 / (4 * std::numbers::pi) + (map_pa - 110000.0) * vd_4pi;
}
// Deterministic standard-normal-ish noise (sum of 12 uniforms − 6).
double noise(unsigned& s) {
  double acc = 0.0;
  for (int i = 0; i < 12; ++i) {
    s = s * 1664525u + 1013904223u;
    acc += static_cast<double>(s >> 8) / 16777216.0;
  }
  return acc - 6.0;
}
}  // namespace

TEST(FuelTorque, LearnsEfficiencyAndExhaustPressureThenCoversItsClaimedSigma) {
  EngineGeometry g;  // 4 cyl, 1.84 L
  FuelTorque ft(g, FuelTorqueParams{});
  EXPECT_EQ(ft.estimate(0, 20e-6, 60000.0).health, Health::kNotConverged);
  unsigned seed = 7;
  const double sd = 1.5;
  for (int k = 0; k < 400; ++k) {  // references across fuel (10-40 mg) and MAP (30-95 kPa)
    const double fuel = 10e-6 + 30e-6 * (0.5 + 0.5 * std::sin(0.37 * k));
    const double map = 30000.0 + 65000.0 * (0.5 + 0.5 * std::cos(0.23 * k));
    (void)ft.learn(fuel, map, truth(g, fuel, map) + sd * noise(seed));
  }
  EXPECT_NEAR(ft.state().theta[0], 0.33, 0.01);
  // Evaluation on fresh points: error within 2 N m, and |error| <= claimed 1σ in 55-85 % of the cases (≈ 68
  // %).
  int covered = 0, n = 0;
  for (int k = 0; k < 300; ++k, ++n) {
    const double fuel = 12e-6 + 25e-6 * (0.5 + 0.5 * std::sin(1.1 * k + 0.3));
    const double map = 35000.0 + 55000.0 * (0.5 + 0.5 * std::cos(0.7 * k));
    const double measured = truth(g, fuel, map) + sd * noise(seed);  // what the claimed σ must cover
    const auto e = ft.estimate(0, fuel, map);
    ASSERT_EQ(e.health, Health::kValid);
    EXPECT_NEAR(e.torque_nm, truth(g, fuel, map), 2.0);
    if (std::fabs(e.torque_nm - measured) <= e.uncertainty) ++covered;
  }
  const double cov = static_cast<double>(covered) / n;
  EXPECT_GT(cov, 0.55);
  EXPECT_LT(cov, 0.85);
}

TEST(FuelTorque, RejectsOutliersAndBadInput) {
  EngineGeometry g;
  FuelTorque ft(g, FuelTorqueParams{});
  for (int k = 0; k < 100; ++k)
    ASSERT_TRUE(ft.learn(20e-6 + 1e-6 * (k % 7), 50000.0 + 1000.0 * (k % 5),
                         truth(g, 20e-6 + 1e-6 * (k % 7), 50000.0 + 1000.0 * (k % 5))));
  const double eta = ft.state().theta[0];
  EXPECT_FALSE(ft.learn(20e-6, 50000.0, 500.0));  // wildly off reference
  EXPECT_FALSE(ft.learn(std::nan(""), 50000.0, 10.0));
  EXPECT_DOUBLE_EQ(ft.state().theta[0], eta);
}
