// CycleEnergy: Δ(½Jθ̇²) per segment and per 720° against an analytic crank motion (ESTIMATORS.md §0 energy form).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "alloc_counter.hpp"
#include "crank_kinematics.hpp"
#include "cycle_energy.hpp"

using namespace torqued;

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

/// Tooth samples of a rigid crank whose net torque is T0 + A sin(2θ) (a 4-cylinder firing ripple), so that
/// ½J(θ)θ̇² = KE0 + T0 θ + A (1 − cos 2θ)/2 exactly. Edges at the nominal angles of `wheel`.
std::vector<ToothSample> analytic_samples(const EngineGeometry& eng, const WheelGeometry& wheel, double rpm,
                                          double t0_nm, double a_nm, int cycles) {
  const CrankKinematics kin(eng);
  std::vector<double> e1, w1;
  nominal_wheel_edges(wheel, e1, w1);
  const int teeth = wheel.teeth();
  const double w0 = rpm * kPi / 30.0;
  const double ke0 = 0.5 * kin.inertia(-eng.tdc_offset_rad) * w0 * w0;
  const auto speed = [&](double theta_w) {
    const double th = theta_w - eng.tdc_offset_rad;  // relative to cylinder-1 TDC
    const double ke = ke0 + t0_nm * theta_w + a_nm * (1.0 - std::cos(2.0 * th)) / 2.0;
    return std::sqrt(2.0 * ke / kin.inertia(th));
  };
  std::vector<ToothSample> out;
  double t = 0.0, prev_edge = 0.0, prev_t = 0.0;
  bool first = true;
  for (int c = 0; c < cycles; ++c) {
    for (int k = 0; k < 2 * teeth; ++k) {
      const double edge = 4.0 * kPi * c + (k / teeth) * 2.0 * kPi + e1[static_cast<std::size_t>(k % teeth)];
      if (!first) {
        const int steps = 400;  // midpoint rule on dt = dθ / θ̇
        const double h = (edge - prev_edge) / steps;
        for (int i = 0; i < steps; ++i) t += h / speed(prev_edge + (i + 0.5) * h);
      }
      ToothSample s;
      s.t_ns = static_cast<std::int64_t>(std::llround(t * 1e9));
      s.tooth = k;
      s.angle_rad = std::fmod(edge, 4.0 * kPi);
      s.width_rad = w1[static_cast<std::size_t>(k % teeth)];
      s.dt_s = first ? 0.0 : t - prev_t;
      s.synced = !first;
      out.push_back(s);
      prev_edge = edge;
      prev_t = t;
      first = false;
    }
  }
  return out;
}
}  // namespace

TEST(CycleEnergy, SegmentAndCycleBalanceMatchAnalyticMotion) {
  // GIVEN a 4-cylinder engine on a 60-2 wheel, net torque 6 N m mean with ±200 N m firing ripple
  EngineGeometry eng;
  WheelGeometry wheel;
  EnergiesParams p;
  CycleEnergy ce(eng, wheel, p);
  const auto samples = analytic_samples(eng, wheel, 2000.0, 6.0, 200.0, 4);
  int segments = 0, cycles = 0;
  for (const auto& s : samples) {
    if (!ce.update(s, 7.0, true)) continue;
    const auto& seg = ce.segment();
    if (seg.segment_valid) {
      ++segments;
      // THEN each segment's ΔKE / Δθ is the mean net torque (the ripple is periodic in the segment)
      EXPECT_NEAR(seg.d_ke_segment_j / seg.segment_rad, 6.0, 0.3);
      EXPECT_NEAR(seg.segment_rad, kPi, 1e-12);
      EXPECT_TRUE(seg.load_valid);
      EXPECT_NEAR(seg.load_mean_nm, 7.0, 1e-12);
    }
    if (seg.cycle_valid) {
      ++cycles;
      // AND the 720° balance ΔKE/4π equals it within 0.1 N m
      EXPECT_NEAR(seg.d_ke_cycle_j / (4.0 * kPi), 6.0, 0.1);
      EXPECT_NEAR(seg.cycle_load_mean_nm, 7.0, 1e-12);
    }
  }
  EXPECT_GE(segments, 12);
  EXPECT_GE(cycles, 8);
}

TEST(CycleEnergy, ThreeCylinderAnd36Minus1ByConfigurationOnly) {
  EngineGeometry eng;
  eng.cylinders = 3;
  eng.firing_order = {1, 2, 3, 0, 0, 0, 0, 0};
  WheelGeometry wheel;
  wheel.positions = 36;
  wheel.missing = 1;
  CycleEnergy ce(eng, wheel, EnergiesParams{});
  // 3 cylinders fire every 240°: use a ripple periodic in 240° is not sin 2θ; use a pure mean torque instead.
  const auto samples = analytic_samples(eng, wheel, 3000.0, -4.0, 0.0, 4);
  int cycles = 0;
  for (const auto& s : samples) {
    if (ce.update(s, 0.0, true) && ce.segment().cycle_valid) {
      ++cycles;
      EXPECT_NEAR(ce.segment().d_ke_cycle_j / (4.0 * kPi), -4.0, 0.1);
      EXPECT_NEAR(ce.segment().segment_rad, 4.0 * kPi / 3.0, 1e-12);
    }
  }
  EXPECT_GE(cycles, 6);
}

TEST(CycleEnergy, MissingToothBreaksTheChainAndIsCounted) {
  EngineGeometry eng;
  WheelGeometry wheel;
  CycleEnergy ce(eng, wheel, EnergiesParams{});
  auto samples = analytic_samples(eng, wheel, 2000.0, 0.0, 0.0, 4);
  samples.erase(samples.begin() + 250);  // lose one tooth in cycle 2
  int valid_after = 0;
  bool seen_break = false;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (ce.update(samples[i], 0.0, true) && i > 250 && i < 250 + 116) {
      seen_break = true;
      valid_after += ce.segment().cycle_valid ? 1 : 0;
    }
  }
  EXPECT_TRUE(seen_break);
  EXPECT_EQ(ce.breaks(), 1u);
  EXPECT_EQ(valid_after, 0);  // no 720° balance spans the hole
}

TEST(CycleEnergy, UpdateDoesNotAllocate) {
  EngineGeometry eng;
  WheelGeometry wheel;
  CycleEnergy ce(eng, wheel, EnergiesParams{});
  const auto samples = analytic_samples(eng, wheel, 2000.0, 1.0, 100.0, 3);
  torqued::test::AllocationScope scope;
  for (const auto& s : samples) ce.update(s, 1.0, true);
  EXPECT_EQ(scope.count(), 0u);
}
