// tests/estimators/test_mean_speed_tracker.cpp: the mean crank speed of the time chain
// (estimators/time/mean_speed_tracker.cpp): the 720° mean removes the firing ripple exactly, the window fills
// before it is valid, a lost sync clears it, and a 180° window follows a speed change four times sooner.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "mean_speed_tracker.hpp"

namespace torqued {
namespace {

constexpr double kPi = std::numbers::pi;

/// Equal teeth of `width` rad at speed w(θ) = w0 (1 + a sin(2θ)) (I4 firing ripple), exact period per tooth.
struct Wheel {
  double width = 6.0 * kPi / 180.0, w0 = 300.0, a = 0.05, theta = 0.0;
  std::int64_t t = 0;
  ToothSample next(bool synced = true) {
    const double mid = theta + 0.5 * width;
    const double w = w0 * (1.0 + a * std::sin(2.0 * mid));
    theta += width;
    ToothSample s;
    s.width_rad = width;
    s.dt_s = width / w;
    t += static_cast<std::int64_t>(s.dt_s * 1e9);
    s.t_ns = t;
    s.synced = synced;
    return s;
  }
};

TEST(MeanSpeedTracker, CycleMeanIsTheExactFourPiOverTheCycleTime) {
  MeanSpeedTracker m;  // 720°
  Wheel wh;
  double sum_dt = 0.0;
  for (int i = 0; i < 120; ++i) {
    const ToothSample s = wh.next();
    m.update(s);
    if (i < 119) {  // 120 teeth of 6° make the 720° window
      EXPECT_FALSE(m.valid()) << i;
    }
    sum_dt += s.dt_s;
  }
  ASSERT_TRUE(m.valid());
  EXPECT_NEAR(m.speed_rad_s(), 4.0 * kPi / sum_dt, 1e-9 * m.speed_rad_s());
  EXPECT_EQ(m.t_ns(), wh.t);
  // The mean over whole cycles removes the ripple: within 0.2 % of w0 (the harmonic mean of 1 + a sin).
  EXPECT_NEAR(m.speed_rad_s(), wh.w0 * std::sqrt(1.0 - wh.a * wh.a), 1e-3 * wh.w0);
}

TEST(MeanSpeedTracker, LostSyncClearsTheWindow) {
  MeanSpeedTracker m;
  Wheel wh;
  for (int i = 0; i < 200; ++i) m.update(wh.next());
  ASSERT_TRUE(m.valid());
  m.update(wh.next(/*synced=*/false));
  EXPECT_FALSE(m.valid());
  for (int i = 0; i < 119; ++i) m.update(wh.next());
  EXPECT_FALSE(m.valid());
  m.update(wh.next());
  EXPECT_TRUE(m.valid());
}

TEST(MeanSpeedTracker, SegmentWindowFollowsASpeedStepSooner) {
  // GIVEN a step from 300 to 330 rad/s WHEN 180° (I4 segment) and 720° windows run side by side THEN the
  // segment mean reaches the new speed after 30 teeth, the cycle mean only after 120.
  MeanSpeedTracker cyc, seg(kPi);
  Wheel wh;
  wh.a = 0.0;
  for (int i = 0; i < 200; ++i) {
    const ToothSample s = wh.next();
    cyc.update(s);
    seg.update(s);
  }
  wh.w0 = 330.0;
  for (int i = 0; i < 30; ++i) {
    const ToothSample s = wh.next();
    cyc.update(s);
    seg.update(s);
  }
  EXPECT_NEAR(seg.speed_rad_s(), 330.0, 1e-6 * 330.0);
  EXPECT_LT(cyc.speed_rad_s(), 310.0);
}

}  // namespace
}  // namespace torqued
