#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "crank_kinematics.hpp"

namespace torqued {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(CrankKinematics, FIsDerivativeOfTravelOverR) {
  // GIVEN the default 4-cylinder geometry
  const CrankKinematics kin(EngineGeometry{});
  const double r = EngineGeometry{}.crank_radius_m();
  // THEN f = (ds/dθ)/R by central differences, to 1e-7 relative over the whole revolution
  for (double th = -kPi; th < kPi; th += 0.037) {
    const double h = 1e-6;
    const double num = (kin.travel(th + h) - kin.travel(th - h)) / (2 * h) / r;
    EXPECT_NEAR(kin.f(th), num, 1e-7) << "theta=" << th;
  }
}

TEST(CrankKinematics, GIsDerivativeOfF) {
  // The (EN-5) typo: g must be f' (docs/equations.md §0), checked numerically.
  const CrankKinematics kin(EngineGeometry{});
  for (double th = -kPi; th < kPi; th += 0.037) {
    const double h = 1e-6;
    EXPECT_NEAR(kin.g(th), (kin.f(th + h) - kin.f(th - h)) / (2 * h), 1e-6) << "theta=" << th;
  }
}

TEST(CrankKinematics, VolumeMatchesCompressionRatioAndDisplacement) {
  const EngineGeometry geo{};
  const CrankKinematics kin(geo);
  EXPECT_NEAR(kin.volume(kPi) / kin.volume(0.0), geo.compression_ratio, 1e-12);
  const double swept = kPi * geo.bore_m * geo.bore_m / 4 * geo.stroke_m;
  EXPECT_NEAR(kin.volume(kPi) - kin.volume(0.0), swept, 1e-15);
}

TEST(CrankKinematics, PhasesFollowFiringOrderNotCylinderNumber) {
  EngineGeometry geo{};  // 1-3-4-2
  const CrankKinematics kin(geo);
  EXPECT_DOUBLE_EQ(kin.phase(1), 0.0);
  EXPECT_DOUBLE_EQ(kin.phase(3), kPi);
  EXPECT_DOUBLE_EQ(kin.phase(4), 2 * kPi);
  EXPECT_DOUBLE_EQ(kin.phase(2), 3 * kPi);
  geo.cylinders = 3;
  geo.firing_order = {1, 2, 3};
  const CrankKinematics k3(geo);
  EXPECT_NEAR(k3.phase(2), 4 * kPi / 3, 1e-15);
}

TEST(CrankKinematics, HalfDInertiaIsHalfDerivativeOfInertia) {
  const CrankKinematics kin(EngineGeometry{});
  for (double th = 0; th < 4 * kPi; th += 0.05) {
    const double h = 1e-6;
    EXPECT_NEAR(kin.half_dinertia(th), 0.5 * (kin.inertia(th + h) - kin.inertia(th - h)) / (2 * h), 1e-9);
  }
}

TEST(CrankKinematics, MassTorqueDoesNoNetWorkOverACycleAtConstantEnergy) {
  // With constant ½Jθ̇² the reciprocating torque averages to zero over 720° (it only exchanges energy).
  const CrankKinematics kin(EngineGeometry{});
  const int n = 7200;
  const double e = 0.5 * kin.inertia(0) * 200.0 * 200.0;
  double work = 0.0;
  for (int i = 0; i < n; ++i) {
    const double th = 4 * kPi * i / n;
    const double w2 = 2 * e / kin.inertia(th);
    const double alpha = -kin.half_dinertia(th) * w2 / kin.inertia(th);
    work += kin.mass_torque(th, std::sqrt(w2), alpha) * (4 * kPi / n);
  }
  EXPECT_NEAR(work, 0.0, 1e-6);
}

TEST(KinematicsTable, MatchesDirectEvaluation) {
  const CrankKinematics kin(EngineGeometry{});
  const KinematicsTable tab(kin, 120);
  for (int n = 0; n < 120; n += 7) {
    EXPECT_DOUBLE_EQ(tab.inertia(n), kin.inertia(n * tab.step_rad()));
    EXPECT_NEAR(tab.torque_per_pa(n, 2), kin.gas_torque(n * tab.step_rad(), 3, 101325.0 + 1.0), 1e-15);
  }
}

}  // namespace
}  // namespace torqued
