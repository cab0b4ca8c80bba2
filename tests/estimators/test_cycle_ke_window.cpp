// tests/estimators/test_cycle_ke_window.cpp: the wide kinetic-energy window of the 720° balance
// (estimators/energy/cycle_ke_window.cpp) on exact tooth sequences of a 60-2 wheel: KE ∝ ω², no cycle
// difference at constant speed, the exact difference after a speed step, a missing tooth invalidates, W ≤ 0
// disables it.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "cycle_ke_window.hpp"

namespace torqued {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// Teeth of a 60-2 wheel over `cycles` 720° cycles at speed w(cycle, tooth) (rad/s); tooth 0 follows the gap.
std::vector<ToothSample> teeth(int cycles, double (*w)(int, int)) {
  std::vector<ToothSample> v;
  std::int64_t t = 0;
  for (int c = 0; c < cycles; ++c)
    for (int k = 0; k < 116; ++k) {
      ToothSample s;
      s.tooth = k;
      s.angle_rad = ((k / 58) * 360.0 + (k % 58) * 6.0) * kDeg;
      s.width_rad = (k % 58 == 0 ? 18.0 : 6.0) * kDeg;
      s.dt_s = s.width_rad / w(c, k);
      t += static_cast<std::int64_t>(s.dt_s * 1e9);
      s.t_ns = t;
      s.synced = true;
      v.push_back(s);
    }
  return v;
}

struct Fixture {
  EngineGeometry engine;
  WheelGeometry wheel;
  EnergiesParams params;
  CycleEnergy energy{engine, wheel, params};
};

TEST(CycleKeWindow, ConstantSpeedGivesNoCycleDifferenceAndKeScalesWithSpeedSquared) {
  Fixture f;
  double ke[2] = {0, 0};
  for (int i = 0; i < 2; ++i) {
    CycleKeWindow win(f.energy, 120.0, 15.0);
    ASSERT_TRUE(win.enabled());
    const auto seq = teeth(
        4, i == 0 ? +[](int, int) { return 200.0; } : +[](int, int) { return 400.0; });
    int done = 0;
    for (const auto& s : seq)
      if (win.update(s)) {
        ++done;
        if (done >= 2) {  // the first window may start before the first tooth
          EXPECT_TRUE(win.ke_valid());
        }
        if (done >= 3) {
          ASSERT_TRUE(win.cycle_valid());
          EXPECT_NEAR(win.d_ke_cycle_j(), 0.0, 1e-6 * win.ke_j());
        }
      }
    EXPECT_GE(done, 3);  // once per cycle
    ke[i] = win.ke_j();
  }
  EXPECT_GT(ke[0], 0.0);
  EXPECT_NEAR(ke[1] / ke[0], 4.0, 1e-6);  // ½Jω²: twice the speed, four times the energy (dt rounded to 1 ns)
}

TEST(CycleKeWindow, SpeedStepGivesTheExactEnergyDifference) {
  // GIVEN 200 rad/s up to 360° into cycle 2 and 220 rad/s after (the step far from the window around boundary
  // 0) WHEN the windows complete THEN the difference of the window-mean KE one cycle apart is KE(220)·(1 −
  // 1/1.21) once (at the step), and 0 where speed was equal.
  Fixture f;
  CycleKeWindow win(f.energy, 120.0, 15.0);
  std::vector<double> d, k;
  for (const auto& s : teeth(
           5, +[](int c, int k) { return c * 116 + k < 2 * 116 + 58 ? 200.0 : 220.0; }))
    if (win.update(s) && win.cycle_valid()) {
      d.push_back(win.d_ke_cycle_j());
      k.push_back(win.ke_j());
    }
  ASSERT_GE(d.size(), 2u);
  int steps = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (std::fabs(d[i]) < 1e-6 * k[i]) continue;
    ++steps;
    EXPECT_NEAR(d[i], k[i] * (1.0 - 1.0 / 1.21), 1e-6 * k[i]);
  }
  EXPECT_EQ(steps, 1);
}

TEST(CycleKeWindow, MissingToothInvalidatesAndZeroWidthDisables) {
  Fixture f;
  CycleKeWindow off(f.energy, 0.0, 15.0);
  EXPECT_FALSE(off.enabled());
  CycleKeWindow win(f.energy, 120.0, 15.0);
  auto seq = teeth(
      4, +[](int, int) { return 200.0; });
  seq.erase(seq.begin() + 116 * 2 + 3);  // one tooth lost in the third cycle, near the window (boundary 0)
  bool saw_invalid = false;
  for (const auto& s : seq)
    if (win.update(s) && !win.cycle_valid()) saw_invalid = true;
  EXPECT_TRUE(saw_invalid);
}

}  // namespace
}  // namespace torqued
