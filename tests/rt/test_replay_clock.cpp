// tests/rt/test_replay_clock.cpp: the one recording-time ↔ monotonic-time formula
// (rt/replay_clock.hpp): speed 1 and 4, as fast as possible, live (speed ignored), a speed <= 0, pause
// and resume.
#include <gtest/gtest.h>

#include <limits>

#include "replay_clock.hpp"

namespace torqued {
namespace {

constexpr std::int64_t kS = 1'000'000'000;

TEST(ReplayClock, SpeedOneMapsRecordingTimeOneToOne) {
  ReplayClock c(1.0);
  EXPECT_FALSE(c.anchored());
  c.anchor(100 * kS, 5 * kS);
  c.anchor(0, 0);  // ignored: the anchor is set once
  ASSERT_TRUE(c.anchored());
  EXPECT_EQ(c.due_mono_ns(100 * kS), 5 * kS);
  EXPECT_EQ(c.due_mono_ns(102 * kS), 7 * kS);
  EXPECT_EQ(c.rec_at(8 * kS), 103 * kS);
}

TEST(ReplayClock, SpeedFourRunsFourTimesFaster) {
  ReplayClock c(4.0);
  c.anchor(0, 10 * kS);
  EXPECT_EQ(c.due_mono_ns(8 * kS), 12 * kS);  // 8 s of recording in 2 s
  EXPECT_EQ(c.rec_at(11 * kS), 4 * kS);
  EXPECT_EQ(c.rec_at(c.due_mono_ns(5 * kS)), 5 * kS);  // the two directions agree
}

TEST(ReplayClock, FastMakesEverythingDueAtTheAnchor) {
  ReplayClock c(std::numeric_limits<double>::infinity());
  EXPECT_TRUE(c.fast());
  c.anchor(0, 3 * kS);
  EXPECT_EQ(c.due_mono_ns(1000 * kS), 3 * kS);
  EXPECT_GT(c.rec_at(3 * kS), 1'000'000 * kS);
}

TEST(ReplayClock, LiveAndNonPositiveSpeedsRunAtOne) {
  // One rule: live input ignores the replay speed; a replay speed <= 0 (or NaN) means 1.
  for (const ReplayClock& c : {ReplayClock(4.0, /*live=*/true), ReplayClock(0.0), ReplayClock(-2.0),
                               ReplayClock(std::numeric_limits<double>::quiet_NaN())})
    EXPECT_EQ(c.speed(), 1.0);
}

TEST(ReplayClock, PauseFreezesRecordingTimeAndResumeShiftsDueTimes) {
  ReplayClock c(2.0);
  c.anchor(0, 0);
  c.pause(1 * kS);  // recording time 2 s
  EXPECT_TRUE(c.paused());
  EXPECT_EQ(c.rec_at(5 * kS), 2 * kS);
  EXPECT_EQ(c.due_mono_ns(3 * kS), std::numeric_limits<std::int64_t>::max());  // nothing is due while paused
  c.resume(4 * kS);                                                            // paused for 3 s
  EXPECT_FALSE(c.paused());
  EXPECT_EQ(c.rec_at(4 * kS), 2 * kS);
  EXPECT_EQ(c.due_mono_ns(4 * kS), 5 * kS);  // 2 s of recording = 1 s of wall time after the resume
  c.resume(9 * kS);                          // not paused: no effect
  EXPECT_EQ(c.due_mono_ns(4 * kS), 5 * kS);
}

}  // namespace
}  // namespace torqued

namespace torqued {
namespace {
// Hostile configuration (replay.speed 1e-300, before the schema bounded it): (t - anchor) / speed was +inf
// and its conversion to int64 undefined (UBSan; on x86 INT64_MIN: every due time in the past, the paced
// replay ran flat out with ring drops). The due time now saturates: never due.
TEST(ReplayClock, TinySpeedSaturatesInsteadOfOverflowing) {
  ReplayClock c(1e-300);
  c.anchor(0, 1000);
  EXPECT_EQ(c.due_mono_ns(0), 1000);
  EXPECT_GT(c.due_mono_ns(1'000'000'000), std::int64_t{9'000'000'000'000'000'000});
  ReplayClock fast_clock(1e300);
  fast_clock.anchor(1'000'000'000, 0);
  EXPECT_GT(fast_clock.rec_at(1'000'000'000), std::int64_t{9'000'000'000'000'000'000});
}
}  // namespace
}  // namespace torqued
