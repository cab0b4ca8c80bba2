// Regression tests for the decoder failures found on real captures, one per failure, each failing on the
// decoder before their fixes (commit ea708b6; checked by building this file against that commit's torqued_io,
// see docs/io.md). Edge streams are built by hand so each test shows exactly the signal that failed: constant
// speed, and only the disturbance under test. The wheel is given as a tooth list so the old wheel names play
// no part.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "crank_decoder.hpp"
#include "synthetic_wheel.hpp"

namespace torqued {
namespace {

constexpr double kPi = 3.14159265358979323846;

WheelGeometry runs_wheel(int positions, const std::vector<int>& runs, bool rising = true) {
  WheelGeometry w = test::wheel_runs(positions, runs);  // the shared sensor simulator's wheel builder
  w.rising_edge = rising;
  return w;
}

/// One tooth edge per tooth at constant speed `rpm` from angle 0 (tooth 0 of the first revolution), with
/// `shift_pitch(rev, tooth)` moving each edge by that many pitches (negative = early). Each marking edge is
/// followed by the opposite edge a quarter pitch later.
struct Stream {
  std::vector<EdgeEvent> edges;
  std::vector<std::pair<std::int64_t, int>>
      truth;  ///< (time, tooth index within a revolution) per real tooth
};

template <class Shift>
Stream make_stream(const WheelGeometry& w, double rpm, int revs, Shift shift_pitch) {
  Stream s;
  const double rev_ns = 60e9 / rpm, pitch_ns = rev_ns / w.positions;
  const std::uint8_t mark = w.rising_edge ? 1 : 0;
  for (int rev = 0; rev < revs; ++rev) {
    for (int i = 0; i < w.teeth(); ++i) {
      const double t = 1e9 + rev * rev_ns + w.tooth_angles_deg[static_cast<std::size_t>(i)] / 360.0 * rev_ns +
                       shift_pitch(rev, i) * pitch_ns;
      s.edges.push_back(EdgeEvent{static_cast<std::int64_t>(std::llround(t)), 0, mark});
      s.edges.push_back(EdgeEvent{static_cast<std::int64_t>(std::llround(t + 0.25 * pitch_ns)), 0,
                                  static_cast<std::uint8_t>(1 - mark)});
      s.truth.emplace_back(s.edges[s.edges.size() - 2].t_ns, i);
    }
  }
  return s;
}

/// Adds a 40 µs glitch pulse (rising at `t_ns`) to the stream's edges, in time order.
void add_pulse(Stream& s, std::int64_t t_ns) {
  s.edges.push_back(EdgeEvent{t_ns, 0, 1});
  s.edges.push_back(EdgeEvent{t_ns + 40'000, 0, 0});
  std::stable_sort(s.edges.begin(), s.edges.end(),
                   [](const EdgeEvent& a, const EdgeEvent& b) { return a.t_ns < b.t_ns; });
}

struct Result {
  DecoderStats stats;
  int wrong_index = 0;  ///< synced teeth whose index is not the true one
  int synced = 0;
  std::vector<ToothEvent> teeth;
};

/// Decodes; a synced tooth's index is checked against the real tooth at the same time (a synced tooth at the
/// time of no real tooth, a glitch taken for a tooth, is wrong too).
Result run(const WheelGeometry& w, const DecoderParams& p, const Stream& s) {
  Result r;
  CrankDecoder dec(w, p);
  EXPECT_TRUE(dec.valid()) << dec.error();
  ToothEvent t;
  std::size_t k = 0;
  for (const auto& e : s.edges) {
    if (!dec.on_edge(e, t)) continue;
    r.teeth.push_back(t);
    if (t.sync != SyncState::kSynced) continue;
    ++r.synced;
    while (k < s.truth.size() && s.truth[k].first < t.t_ns) ++k;
    if (k == s.truth.size() || s.truth[k].first != t.t_ns || t.tooth % w.teeth() != s.truth[k].second)
      ++r.wrong_index;
  }
  r.stats = dec.stats();
  return r;
}

/// A stream of 10 revolutions at `rpm` (edges moved by `shift_pitch`, as make_stream) with one glitch pulse
/// `frac` of a pitch after tooth `tooth` of the sixth revolution, decoded with the default parameters.
template <class Shift>
std::pair<Stream, Result> glitch_after(const WheelGeometry& w, double rpm, Shift shift_pitch, int tooth,
                                       double frac) {
  Stream s = make_stream(w, rpm, 10, shift_pitch);
  const double pitch_ns = 60e9 / rpm / w.positions;
  add_pulse(s, s.truth[static_cast<std::size_t>(5 * w.teeth() + tooth)].first +
                   static_cast<std::int64_t>(frac * pitch_ns));
  Result r = run(w, DecoderParams{}, s);
  return {std::move(s), std::move(r)};
}

// 4B11 36-2-1 on rising edges: the single gap (2 pitches) measures 1.8 and the tooth after it 1.16 pitch
// (its edge early by 0.2 and 0.04 pitch). Against the trend-scaled prediction that tooth's ratio is 1.43,
// which the old decoder called a lost tooth (any ratio above √2, tested before the normal window), and the
// wrong width then dropped sync every revolution.
TEST(DecoderRegression, ToothInsideTheNormalWindowAfterAGapIsNotLost) {
  const WheelGeometry w = runs_wheel(36, {17, 1, 16, 2});  // 4B11 in rotation order
  const Stream s =
      make_stream(w, 1420.0, 30, [](int, int i) { return i == 17 ? -0.2 : (i == 18 ? -0.04 : 0.0); });
  const Result r = run(w, DecoderParams{}, s);
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.stats.lost_teeth, 0u);
  EXPECT_EQ(r.wrong_index, 0);
  EXPECT_GT(r.synced, 28 * w.teeth());
}

// One glitch edge at 0.55 of a period (not a runt, too short for a tooth) drops sync; the decoder must be
// synced again within one revolution. The old one took the glitch period as its reference: every real tooth
// after it looked like a gap and it never resynced.
TEST(DecoderRegression, ResyncWithinOneRevolutionAfterAGlitch) {
  const WheelGeometry w = runs_wheel(36, {35, 1});  // 36-1
  Stream s = make_stream(w, 3000.0, 12, [](int, int) { return 0.0; });
  const double pitch_ns = 60e9 / 3000.0 / 36;
  // glitch: an extra rising edge 0.55 pitch after tooth 10 of revolution 4, and its falling edge
  std::size_t at = 0;
  for (std::size_t k = 0, m = 0; k < s.edges.size(); ++k) {
    if (s.edges[k].level == 1 && m++ == 4 * 35 + 10) at = k;
  }
  const std::int64_t tg = s.edges[at].t_ns + static_cast<std::int64_t>(0.55 * pitch_ns);
  s.edges.insert(s.edges.begin() + static_cast<long>(at) + 2,
                 {EdgeEvent{tg, 0, 1}, EdgeEvent{tg + 2000, 0, 0}});
  const Result r = run(w, DecoderParams{}, s);
  ASSERT_GE(r.stats.syncs, 1u);
  EXPECT_LE(r.stats.sync_losses, 1u);
  // After the glitch: synced again no more than one revolution (35 teeth) later, and synced to the end.
  int unsynced_after = 0;
  bool seen_glitch = false;
  for (const auto& t : r.teeth) {
    if (t.t_ns >= tg) seen_glitch = true;
    if (seen_glitch && t.sync != SyncState::kSynced) ++unsynced_after;
  }
  EXPECT_LE(unsynced_after, 35);
  EXPECT_EQ(r.teeth.back().sync, SyncState::kSynced);
  EXPECT_EQ(r.wrong_index, 0);
}

// 4B11 on falling edges: a 0.25 µs glitch pulse at 0.47 of a period. It is noise (counted), not a sync loss.
TEST(DecoderRegression, QuarterMicrosecondGlitchAtPoint47OfAPeriodKeepsSync) {
  const WheelGeometry w = runs_wheel(36, {17, 1, 16, 2}, false);
  Stream s = make_stream(w, 1420.0, 10, [](int, int) { return 0.0; });
  const double pitch_ns = 60e9 / 1420.0 / 36;
  std::vector<EdgeEvent> out;
  int marks = 0;
  std::int64_t glitch_t = 0;
  for (const auto& e : s.edges) {
    out.push_back(e);
    if (e.level == 0 && ++marks == 5 * 33 + 5) {  // after tooth 5 of revolution 5: 0.47 pitch later, 250 ns
      glitch_t = e.t_ns + static_cast<std::int64_t>(0.47 * pitch_ns);
    }
    if (glitch_t > 0 && e.level == 1 && e.t_ns < glitch_t) {
      out.push_back(EdgeEvent{glitch_t, 0, 0});
      out.push_back(EdgeEvent{glitch_t + 250, 0, 1});
      glitch_t = -1;
    }
  }
  s.edges = out;
  const Result r = run(w, DecoderParams{}, s);
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.stats.noise_edges, 1u);
  EXPECT_EQ(r.wrong_index, 0);
}

// 36-2 at 1000 rpm: one 40 µs glitch pulse at 0.65 of a period while synced, with no noise edge before it
// (the first edge of a noise burst). The glitch is early enough to be suspect (under burst_tooth_ratio_min of
// both the running period and the trend prediction) but not a runt, so it stands in for the tooth it
// precedes. Before the suspect rule (io/crank_decoder.cpp, suspect_resolves_as_glitch) the true tooth's
// remainder (0.35 of a period, 0.54 of the glitch-shortened one) passed as the next tooth and every index
// after it was one ahead (DecoderBurstResync's "true teeth with a shifted index").
TEST(DecoderRegression, GlitchAtTwoThirdsOfAPeriodDoesNotShiftTheIndex) {
  const WheelGeometry w = runs_wheel(36, {34, 2});
  const auto [s, r] = glitch_after(
      w, 1000.0, [](int, int) { return 0.0; }, 20, 0.65);
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.stats.noise_edges, 1u);  // the true tooth 21, after the glitch that stood in for it
  EXPECT_EQ(r.wrong_index, 1);         // the glitch itself (tooth 21 at the glitch's time); nothing after it
  EXPECT_GT(r.synced, 8 * w.teeth());
}

// No noise at all: at steady 1000 rpm the engine speeds up abruptly, every period 0.62 of a pitch from
// position 20 of the sixth revolution on. Two equal short teeth are not a glitch and its remainder (a glitch
// at 0.56-0.8 of a pitch leaves at most 0.8 of itself): nothing is rejected, no index moves.
TEST(DecoderRegression, AnAbruptSpeedUpWithoutNoiseIsNotTakenForAGlitch) {
  const WheelGeometry w = runs_wheel(36, {34, 2});
  auto fast = [&w](int rev, int i) {
    const double pos = rev * 36.0 + w.tooth_angles_deg[static_cast<std::size_t>(i)] / 10.0;
    return -0.38 * std::max(0.0, pos - (5 * 36.0 + 20.0));
  };
  Stream s = make_stream(w, 1000.0, 10, fast);
  const Result r = run(w, DecoderParams{}, s);
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.stats.noise_edges, 0u);
  EXPECT_EQ(r.wrong_index, 0);
  EXPECT_GT(r.synced, 8 * w.teeth());
}

// The half-rate lock (36-2 at 300 rpm): a glitch (a runt, 0.3 of a pitch after tooth 10 of the sixth
// revolution) starts a noise burst; from tooth 12 on the engine runs 1.3 times faster (each period 0.77 of a
// pitch, for 10 teeth). Tooth 12 comes under burst_tooth_ratio_min (0.8) of the running period (median of the
// last three, all one pitch) and is rejected as noise; the next period, two teeth of 0.77, is 1.54 times the
// running period. Before the held edge (io/crank_decoder.cpp, held_tooth_time) it was taken as one tooth
// (inside sync_ratio_max in a burst), tooth 13 got index 12 and every tooth after it stayed one behind until
// the gap dropped sync. Now the rejected edge, splitting that period evenly, is tooth 12 after all: tooth 13
// advances by two and the split's periods restart the running period.
TEST(DecoderRegression, ToothRejectedInABurstSpeedUpDoesNotLockAtHalfRate) {
  const WheelGeometry w = runs_wheel(36, {34, 2});
  auto speed_up = [](int rev, int i) {  // pitches early: 0.23 more per tooth from tooth 12 to 21, then held
    if (rev < 5) return 0.0;
    return -0.23 * (rev > 5 ? 10 : std::clamp(i - 11, 0, 10));
  };
  const auto [s, r] = glitch_after(w, 300.0, speed_up, 10, 0.3);
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.stats.noise_edges, 2u);  // the glitch and tooth 12
  EXPECT_EQ(r.stats.lost_teeth, 1u);   // tooth 13 advanced by two
  EXPECT_EQ(r.wrong_index, 0);
  EXPECT_GT(r.synced, 8 * w.teeth());
}

// A glitch followed at once by a compression (36-2 at 1000 rpm): a 40 µs glitch pulse at 0.65 of a period
// after tooth 20 of the sixth revolution stands in for tooth 21 (suspect, then resolved as a glitch at tooth
// 21's edge, which is counted as noise: a burst), and from tooth 22 on the engine runs 1.3 times slower (each
// period 1.3 pitches). Timed from the glitch, tooth 22's period is 0.35 + 1.3 = 1.65 pitches, over
// sync_ratio_max (1.6): before io/crank_decoder.cpp timed it from tooth 21's edge (period_from_resolved) that
// dropped sync (unexpected_gap) and the decoder resynced at the gap; now it is 1.3 pitches, a tooth, and its
// speed is the true one.
TEST(DecoderRegression, CompressionRightAfterAGlitchKeepsSyncAndIndex) {
  const WheelGeometry w = runs_wheel(36, {34, 2});
  auto slow_down = [&w](int rev, int i) {  // pitches late: 0.3 more per position from position 22 on
    const double pos = rev * 36.0 + w.tooth_angles_deg[static_cast<std::size_t>(i)] / 10.0;
    return 0.3 * std::max(0.0, pos - (5 * 36.0 + 21.0));
  };
  const auto [s, r] = glitch_after(w, 1000.0, slow_down, 20, 0.65);
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.stats.lost_teeth, 0u);
  EXPECT_EQ(r.stats.noise_edges, 1u);  // the true tooth 21, after the glitch that stood in for it
  EXPECT_EQ(r.wrong_index, 1);         // the glitch itself (tooth 21 at the glitch's time); nothing after it
  EXPECT_GT(r.synced, 8 * w.teeth());
  const std::int64_t t22 = s.truth[5 * 34 + 22].first;
  const auto it =
      std::find_if(r.teeth.begin(), r.teeth.end(), [&](const ToothEvent& t) { return t.t_ns == t22; });
  ASSERT_NE(it, r.teeth.end());
  EXPECT_EQ(it->tooth % w.teeth(), 22);
  // 80.6 rad/s over one pitch in 1.3 pitch times (timed from the glitch: 1.65, 63.5 rad/s)
  EXPECT_NEAR(it->speed_rad_s, 1000.0 * 2.0 * kPi / 60.0 / 1.3, 1.0);
}

// The same glitch, then a second one 0.4 of a pitch after the true tooth 21, in a slow-down of 0.2 pitch per
// position from tooth 22. The first resolves as a glitch (tooth 21's edge is noise, the next period timed
// from it); the second is rejected as burst noise and held. Before held_tooth_time started at the resolved
// edge it split the glitch-timed period (1 - 0.65 + 1.2 pitches) into two near-equal halves: true tooth 22
// was taken for tooth 23 (advance 2), every index after it ran one ahead and the gap dropped sync (12 wrong,
// 1 loss).
TEST(DecoderRegression, SecondGlitchAfterAResolvedOneDoesNotAdvanceTheIndex) {
  const WheelGeometry w = runs_wheel(36, {34, 2});
  auto slow_down = [&w](int rev, int i) {  // pitches late: 0.2 more per position from position 22 on
    const double pos = rev * 36.0 + w.tooth_angles_deg[static_cast<std::size_t>(i)] / 10.0;
    return 0.2 * std::max(0.0, pos - (5 * 36.0 + 21.0));
  };
  auto [s, first] = glitch_after(w, 1000.0, slow_down, 20, 0.65);
  const double pitch_ns = 60e9 / 1000.0 / 36;
  add_pulse(s, s.truth[5 * 34 + 21].first + static_cast<std::int64_t>(0.4 * pitch_ns));  // after tooth 21
  const Result r = run(w, DecoderParams{}, s);
  EXPECT_EQ(first.wrong_index, 1);  // without the second glitch: the first one only
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.stats.lost_teeth, 0u);
  EXPECT_EQ(r.wrong_index, 1);  // the first glitch itself
  EXPECT_GT(r.synced, 8 * w.teeth());
}

// A dense burst at steady idle (60-2 at 800 rpm): glitch pulses every 0.85 of a pitch from tooth 20 of the
// sixth revolution on (4 of them). The first fits the running period (0.85 >= burst_tooth_ratio_min) and
// stands in for tooth 21, whose edge 0.15 pitch later is a runt. Before the last tooth could be retimed
// (io/crank_decoder.cpp, retime_last_tooth) each later glitch was judged from the one before it, 0.85 of a
// pitch, a tooth again: the glitch at 3.4 pitches took index 24 (true 23 at 3.0 was rejected), and the
// indices ran one ahead until the gap dropped sync. Now tooth 21's edge, making the period one pitch, retimes
// tooth 21 and the glitches after it are runts against it.
TEST(DecoderRegression, GlitchesAtFourFifthsOfAPitchAtIdleDoNotRunTheIndexAhead) {
  const WheelGeometry w = runs_wheel(60, {58, 2});
  Stream s = make_stream(w, 800.0, 10, [](int, int) { return 0.0; });
  const double pitch_ns = 60e9 / 800.0 / 60;
  for (int k = 1; k <= 4; ++k)
    add_pulse(s, s.truth[5 * 58 + 20].first + static_cast<std::int64_t>(0.85 * k * pitch_ns));
  const Result r = run(w, DecoderParams{}, s);
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.stats.lost_teeth, 0u);
  EXPECT_EQ(r.wrong_index, 1);  // the first glitch itself (tooth 21 at the glitch's time); nothing after it
  EXPECT_GT(r.synced, 8 * w.teeth());
}

// Cranking at 300 rpm on a 36-2 wheel with ±10 % of a period of jitter on every edge (tooth-to-tooth period
// ratios up to ±20 %, as on noisy-trigger-1): the old decoder's trend-extrapolated prediction turned the
// jitter into unexpected gaps and dropped sync.
TEST(DecoderRegression, CrankingSpeedRippleDoesNotDropSync) {
  const WheelGeometry w = runs_wheel(36, {34, 2});
  std::uint32_t seed = 12345u;
  auto jitter = [&seed](int, int) {
    seed = seed * 1664525u + 1013904223u;
    return 0.2 * (static_cast<double>(seed >> 8) / 16777216.0 - 0.5);  // ±0.1 pitch
  };
  const Stream s = make_stream(w, 300.0, 12, jitter);
  const Result r = run(w, DecoderParams{}, s);
  EXPECT_EQ(r.stats.syncs, 1u);
  EXPECT_EQ(r.stats.sync_losses, 0u) << to_string(r.stats.last_loss_reason);
  EXPECT_EQ(r.wrong_index, 0);
  EXPECT_GT(r.synced, 10 * w.teeth());
}

#ifndef TORQUED_DECODER_BEFORE_ISSUE_13  // min_pulse_us did not exist before the real-capture fixes
// Contact bounce on rising edges: 5 % of a period before every 7th tooth a 0.25 µs pulse. Without the
// debounce its first edge is taken as the tooth (that tooth's speed 5 % off, the next one's the other way);
// with min_pulse_us = 1 both of its edges are dropped and counted, and every tooth's speed is exact.
TEST(DecoderRegression, MinPulseDebounceDropsBouncesAndKeepsToothTimes) {
  const WheelGeometry w = runs_wheel(60, {58, 2});
  const double rpm = 2000.0, pitch_ns = 60e9 / rpm / 60;
  Stream s = make_stream(w, rpm, 8, [](int, int) { return 0.0; });
  std::vector<EdgeEvent> out;
  int bounces = 0, marks = 0;
  for (const auto& e : s.edges) {
    if (e.level == 1 && ++marks % 7 == 0) {
      const auto tb = e.t_ns - static_cast<std::int64_t>(0.05 * pitch_ns);
      out.push_back(EdgeEvent{tb, 0, 1});
      out.push_back(EdgeEvent{tb + 250, 0, 0});
      ++bounces;
    }
    out.push_back(e);
  }
  s.edges = out;
  const double true_rad_s = rpm * 2.0 * kPi / 60.0;
  auto max_err = [&](const Result& r) {
    double m = 0.0;
    for (const auto& t : r.teeth) {
      if (t.sync == SyncState::kSynced && t.events == 0)
        m = std::max(m, std::abs(t.speed_rad_s / true_rad_s - 1.0));
    }
    return m;
  };
  DecoderParams p;
  const Result off = run(w, p, s);
  EXPECT_GT(max_err(off), 0.03);  // without the filter the bounce moves the tooth times
  p.min_pulse_us = 1.0;
  const Result on = run(w, p, s);
  EXPECT_EQ(on.stats.debounced_edges, static_cast<std::uint64_t>(bounces));
  EXPECT_EQ(on.stats.rejected_edges, on.stats.debounced_edges + on.stats.noise_edges);
  EXPECT_EQ(on.stats.sync_losses, 0u);
  EXPECT_EQ(on.wrong_index, 0);
  EXPECT_LT(max_err(on), 1e-4);
}
#endif

}  // namespace
}  // namespace torqued
