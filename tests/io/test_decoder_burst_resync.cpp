// Resync inside noise bursts: noise bursts between clean revolutions (60-2 and 36-2 wheels, cranking with a
// compression ripple and idle; the tests' sensor simulator, tests/support/synthetic_wheel.hpp; many burst
// placements from fixed seeds). While the decoder is SYNCING inside a burst, its gap search must not take a
// gap that the glitches made (a short glitch period as the reference, then a normal tooth period looks like
// the gap): every synced tooth, the tooth of each (re)sync included, carries the index of the true tooth
// nearest in time (a glitch may stand in for the tooth it precedes), and after each burst the decoder is
// synced again within one revolution of the burst's end.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "crank_decoder.hpp"
#include "synthetic_wheel.hpp"

namespace torqued {
namespace {

struct Burst {
  std::int64_t start_ns, end_ns;
};

struct Case {
  int positions, missing;
  double rpm0, rpm1, ripple;
  unsigned seed;
};

struct Noisy {
  test::SynthOutput clean;
  std::vector<EdgeEvent> edges;
  std::vector<Burst> bursts;
  double rev_s = 0;  ///< longest revolution time of the run (at the lower speed, ripple included)
};

/// 5 s of the wheel; a burst every 3 revolutions (from the second one on, placed at random within a
/// revolution): 12 pulses 40 µs wide at random times within 30 ms (as in test_decoder_noise_resync.cpp).
Noisy make(const Case& c) {
  test::SynthOptions o;
  o.wheel = test::wheel_nm(c.positions, c.missing);
  o.rpm0 = c.rpm0;
  o.rpm1 = c.rpm1;
  o.duration_s = 5.0;
  o.ripple = c.ripple;
  o.ripple_order = 2.0;
  o.cam = false;
  Noisy n{test::synthesize(o), {}, {}, 60.0 / std::min(c.rpm0, c.rpm1) / (1.0 - c.ripple)};
  n.edges = n.clean.edges;
  std::mt19937 rng(c.seed);
  std::uniform_real_distribution<double> jitter(0.0, n.rev_s);
  for (int b = 0; (1.0 + 3.0 * b) * n.rev_s < o.duration_s - 2.0 * n.rev_s; ++b) {
    const double at = (1.0 + 3.0 * b) * n.rev_s;
    const auto start = static_cast<std::int64_t>((at + jitter(rng)) * 1e9);
    n.bursts.push_back({start, test::add_noise_burst(n.edges, start, rng)});
  }
  std::stable_sort(n.edges.begin(), n.edges.end(),
                   [](const EdgeEvent& a, const EdgeEvent& b) { return a.t_ns < b.t_ns; });
  return n;
}

std::int64_t time_of(const test::SynthTooth& x) { return x.t_ns; }
std::int64_t time_of(std::int64_t t) { return t; }

/// Index (within the revolution) of the true tooth nearest in time to t.
int nearest_true_tooth(const test::SynthOutput& clean, std::int64_t t, int teeth) {
  const auto it = std::lower_bound(clean.teeth.begin(), clean.teeth.end(), t,
                                   [](const test::SynthTooth& x, std::int64_t v) { return x.t_ns < v; });
  if (it == clean.teeth.end()) return clean.teeth.back().tooth720 % teeth;
  if (it == clean.teeth.begin() || it->t_ns - t <= t - std::prev(it)->t_ns) return it->tooth720 % teeth;
  return std::prev(it)->tooth720 % teeth;
}

struct Result {
  int wrong = 0;                 ///< synced teeth with a wrong index
  int wrong_at_glitch = 0;       ///< ... reported at a glitch edge (the rest are true teeth, index shifted)
  int wrong_lost = 0;            ///< ... flagged as a recovered lost tooth (advanced by two)
  int glitch_teeth = 0;          ///< synced teeth reported at a glitch edge (a glitch standing in)
  int true_rejected = 0;         ///< true teeth rejected as noise while synced
  int bursts_wrong = 0;          ///< bursts followed by a synced tooth with a wrong index before the next one
  int wrong_after_bad_sync = 0;  ///< ... that follow a (re)sync at a wrong index (same sync)
  int wrong_resync = 0;          ///< ... of which the tooth of a (re)sync
  int late = 0;                  ///< bursts after which sync came back later than one revolution
  int bursts = 0;
  int losses = 0;  ///< sync losses
  std::string first_wrong;
};

Result run(const Case& c, const DecoderParams& p) {
  const Noisy n = make(c);
  const int teeth = c.positions - c.missing;
  CrankDecoder dec(test::wheel_nm(c.positions, c.missing), p);
  EXPECT_TRUE(dec.valid()) << dec.error();
  Result r;
  std::vector<ToothEvent> out;
  ToothEvent t;
  bool bad_sync = false;
  std::vector<bool> burst_wrong(n.bursts.size(), false);
  for (const auto& e : n.edges) {
    const bool true_tooth =
        e.channel == 0 && e.level == 1 &&
        std::binary_search(n.clean.teeth.begin(), n.clean.teeth.end(), e.t_ns,
                           [](const auto& a, const auto& b) { return time_of(a) < time_of(b); });
    const bool was_synced = dec.state() == SyncState::kSynced;
    const std::uint64_t noise_before = dec.stats().noise_edges;
    const bool got = dec.on_edge(e, t);
    r.true_rejected += true_tooth && was_synced && dec.stats().noise_edges > noise_before;
    if (!got) continue;
    out.push_back(t);
    if (t.sync != SyncState::kSynced) {
      bad_sync = false;
      continue;
    }
    const bool ok = t.tooth % teeth == nearest_true_tooth(n.clean, t.t_ns, teeth);
    r.glitch_teeth += !true_tooth;
    if (t.events & kToothResynced) bad_sync = !ok;
    if (ok) continue;
    ++r.wrong;
    r.wrong_at_glitch += !true_tooth;
    r.wrong_lost += (t.events & kToothLostRecovered) != 0;
    for (std::size_t b = n.bursts.size(); b-- > 0;) {
      if (n.bursts[b].start_ns <= t.t_ns) {
        burst_wrong[b] = true;
        break;
      }
    }
    if (bad_sync && !(t.events & kToothResynced)) ++r.wrong_after_bad_sync;
    if (t.events & kToothResynced) ++r.wrong_resync;
    if (r.first_wrong.empty())
      r.first_wrong = "tooth " + std::to_string(t.tooth % teeth) + " at " + std::to_string(t.t_ns * 1e-9) +
                      " s (true " + std::to_string(nearest_true_tooth(n.clean, t.t_ns, teeth)) + ")";
  }
  r.losses = static_cast<int>(dec.stats().sync_losses);
  r.bursts_wrong = static_cast<int>(std::count(burst_wrong.begin(), burst_wrong.end(), true));
  for (const Burst& b : n.bursts) {
    ++r.bursts;
    const auto back = std::find_if(out.begin(), out.end(), [&](const ToothEvent& x) {
      return x.t_ns > b.end_ns && x.sync == SyncState::kSynced;
    });
    if (back == out.end() || back->t_ns - b.end_ns > static_cast<std::int64_t>(n.rev_s * 1e9)) ++r.late;
  }
  return r;
}

std::vector<Case> cases() {
  std::vector<Case> v;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    v.push_back({60, 2, 250.0, 320.0, 0.25, seed});  // cranking
    v.push_back({36, 2, 250.0, 320.0, 0.25, seed});
    v.push_back({60, 2, 800.0, 800.0, 0.05, seed});  // idle
    v.push_back({36, 2, 800.0, 800.0, 0.05, seed});
  }
  return v;
}

TEST(DecoderBurstResync, NoResyncOnAGlitchMadeGapAndResyncWithinOneRevolution) {
  DecoderParams p;
  p.use_cam = false;
  int wrong = 0, wrong_resync = 0, after = 0, late = 0, bursts = 0, losses = 0;
  Result all;
  for (const Case& c : cases()) {
    const Result r = run(c, p);
    all.wrong_at_glitch += r.wrong_at_glitch;
    all.wrong_lost += r.wrong_lost;
    all.glitch_teeth += r.glitch_teeth;
    all.true_rejected += r.true_rejected;
    all.bursts_wrong += r.bursts_wrong;
    std::printf(
        "info: %d-%d at %.0f rpm, seed %u: synced teeth with a wrong index %d (at a glitch edge %d, "
        "lost-tooth recoveries %d); glitch edges taken as teeth %d; true teeth rejected as noise %d; "
        "bursts followed by a wrong index %d of %d; sync losses %d; late %d\n",
        c.positions, c.missing, c.rpm0, c.seed, r.wrong, r.wrong_at_glitch, r.wrong_lost, r.glitch_teeth,
        r.true_rejected, r.bursts_wrong, r.bursts, r.losses, r.late);
    wrong += r.wrong;
    wrong_resync += r.wrong_resync;
    after += r.wrong_after_bad_sync;
    late += r.late;
    losses += r.losses;
    bursts += r.bursts;
    EXPECT_EQ(r.wrong_resync + r.wrong_after_bad_sync, 0)
        << c.positions << "-" << c.missing << " at " << c.rpm0 << " rpm, seed " << c.seed << ": "
        << r.first_wrong;
  }
  std::printf(
      "info: %d bursts; resync teeth with a wrong index %d, teeth after such a resync %d; synced teeth "
      "with a wrong index in all %d; sync losses %d; bursts resynced later than one revolution %d\n",
      bursts, wrong_resync, after, wrong, losses, late);
  std::printf(
      "info: of the %d: %d reported at a glitch edge, %d lost-tooth recoveries, the rest true teeth with a "
      "shifted index; glitch edges taken as teeth %d; true teeth rejected as noise while synced %d; bursts "
      "followed by a wrong index %d\n",
      wrong, all.wrong_at_glitch, all.wrong_lost, all.glitch_teeth, all.true_rejected, all.bursts_wrong);
  // Before the gap search checked the clean run before the gap (io/gap_sync.cpp, run_fits_gap), these cases
  // had 56 resyncs at a glitch-made gap (wrong index) and 795 teeth decoded on from them.
  EXPECT_EQ(wrong_resync, 0);
  EXPECT_EQ(after, 0);
  // Resync within one revolution of a burst's end, after every burst: the first gap after it with a steady
  // run before it, or (io/gap_sync.cpp, on_post_gap_period) with a steady run after it, synced
  // kResyncRunBeforeGap teeth after that gap. Before the run after the gap counted, 11 of 312 bursts waited
  // for the next gap (the burst ended under 4 clean teeth before the gap, or a glitch had shortened the
  // search's reference, or had split the gap so that the next run was one period longer than a revolution
  // allowed). Then 1 was left (36-2 cranking, seed 2, the 4th burst, 3.292-3.322 s): a glitch period (3.53
  // ms) and the true tooth 32 after the last glitch (3.96 ms) then tooth 33 (7.34 ms, the compression's slow
  // point) made the search's trend 1.85 (clamped to max_trend 1.5), so the true gap (19.24 ms, 1.75 x the
  // prediction) was counted as a tooth period; the run before the next gap was then 35 periods, over the
  // revolution's bound, and the decoder synced only at the gap after it (1.37 revolutions). After a sync loss
  // the run has no upper bound now (io/gap_sync.cpp, on_gap_candidate): that gap, 0.72 revolutions after the
  // burst, syncs.
  EXPECT_EQ(late, 0) << "of " << bursts;
  // Synced teeth with a wrong index in all (not only after a resync): 817 before the suspect-tooth rule
  // (io/crank_decoder.cpp, suspect_resolves_as_glitch: the first glitch of a burst, early against both the
  // running period and the trend, stood in for a tooth and the true tooth's remainder passed as the next
  // one), 421 with it, 160 with the held edge (io/crank_decoder.cpp, held_tooth_time: a true tooth rejected
  // against a running period that lagged a speed-up was counted as one with the next, the half-rate lock;
  // 36-2 cranking seeds 2 and 6, 119 and 80 -> 4 and 0). Left: glitches standing in for teeth, one too many
  // in a dense burst (60-2 and 36-2 idle, seeds 2, 4, 5; 36-2 cranking seed 5). 86 with the retimed tooth
  // (io/crank_decoder.cpp, retime_last_tooth: at steady speed over 400 rpm a glitch at 0.8 of a pitch stood
  // in for a tooth and the glitches after it were judged from it; the tooth's own edge right after it now
  // retimes it): 60-2 idle seed 2 40 -> 0, 36-2 idle seed 4 35 -> 2, sync losses 77 -> 68. Left: a glitch
  // standing in at the gap and in cranking bursts (36-2 idle seed 5, 36-2 cranking seed 5), docs/io.md. The
  // bound is the count measured (fixed seeds, deterministic) with a margin of 4.
  EXPECT_LE(wrong, 90);
  EXPECT_LE(losses, 70);
}

}  // namespace
}  // namespace torqued
