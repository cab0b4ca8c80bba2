// Crank decoder on synthetic wheels with known truth (tests/io/synthetic_wheel.hpp): every condition of
// the crank decoder (docs/io.md). GIVEN a wheel and a speed profile, WHEN the edges are decoded, THEN tooth
// index and angle match the truth once synced, and every disturbance is counted.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>

#include "alloc_counter.hpp"
#include "crank_decoder.hpp"
#include "synthetic_wheel.hpp"
#include "wheel_names.hpp"

namespace torqued {
namespace {

using test::SynthOptions;
using test::SynthOutput;

struct Decoded {
  std::vector<ToothEvent> teeth;
  DecoderStats stats;
  int mismatches = 0;        ///< synced+phased teeth whose index differs from the truth
  int checked = 0;           ///< synced+phased teeth compared
  double max_angle_err = 0;  ///< rad, over checked teeth
  double max_speed_err = 0;  ///< relative
  std::int64_t first_synced_ns = -1;
};

Decoded run(const SynthOutput& s, const WheelGeometry& wheel, const DecoderParams& p = {},
            const std::vector<double>& corrections = {}) {
  CrankDecoder dec(wheel, p);
  EXPECT_TRUE(dec.valid()) << dec.error();
  if (!corrections.empty()) {
    EXPECT_TRUE(dec.set_tooth_corrections(corrections));
  }
  Decoded d;
  std::map<std::int64_t, const test::SynthTooth*> truth;
  for (const auto& t : s.teeth) truth[t.t_ns] = &t;
  ToothEvent ev;
  for (const auto& e : s.edges) {
    if (!dec.on_edge(e, ev)) continue;
    d.teeth.push_back(ev);
    if (ev.sync != SyncState::kSynced || !ev.phase_known) continue;
    if (d.first_synced_ns < 0) d.first_synced_ns = ev.t_ns;
    const auto it = truth.find(ev.t_ns);
    if (it == truth.end()) continue;  // an injected edge
    ++d.checked;
    if (ev.tooth != it->second->tooth720) ++d.mismatches;
    double err = std::abs(ev.angle_rad - it->second->angle_rad);
    d.max_angle_err = std::max(d.max_angle_err, err);
  }
  d.stats = dec.stats();
  return d;
}

TEST(CrankDecoder, Clean60m2SyncsFastAndNeverLosesSync) {
  // GIVEN a 60-2 wheel at constant 3000 rpm
  SynthOptions o;
  o.duration_s = 0.2;
  const auto s = test::synthesize(o);
  // WHEN decoded
  const auto d = run(s, o.wheel);
  // THEN synced within ~2 revolutions + cam, every index right, exact angles, no loss
  EXPECT_EQ(d.stats.sync_losses, 0u);
  EXPECT_EQ(d.stats.noise_edges, 0u);
  EXPECT_EQ(d.stats.lost_teeth, 0u);
  EXPECT_EQ(d.mismatches, 0);
  EXPECT_GT(d.checked, 450);  // 10 revolutions of 58 teeth, less the sync time
  EXPECT_LT(d.max_angle_err, 1e-9);
  EXPECT_GT(d.first_synced_ns, 0);
  EXPECT_LT(d.first_synced_ns, 3 * 20'000'000);  // 20 ms per revolution
  // speed from the true width
  const auto& last = d.teeth.back();
  EXPECT_NEAR(last.speed_rad_s, 3000.0 * 2 * std::numbers::pi / 60.0, 0.5);
}

TEST(CrankDecoder, OtherWheelsByConfigurationOnly) {
  struct Case {
    WheelGeometry w;
    const char* name;
  };
  const std::vector<Case> cases = {
      {test::wheel_nm(36, 1), "36-1"},
      {test::wheel_nm(36, 2), "36-2"},
      {test::wheel_nm(24, 1), "24-1"},
      {test::wheel_nm(12, 1), "12-1"},
      {test::wheel_runs(36, {17, 1, 16, 2}), "36-2-1"},
      {test::wheel_runs(24, {11, 1, 10, 2}), "arctic-cat"},
      {test::wheel_runs(36, {13, 2, 16, 2, 1, 2}), "36-2-2-2 (H4)"},
  };
  for (const auto& c : cases) {
    SynthOptions o;
    o.wheel = c.w;
    o.rpm0 = 1500;
    o.rpm1 = 4500;
    o.ripple = 0.02;
    o.duration_s = 0.3;
    const auto d = run(test::synthesize(o), c.w);
    EXPECT_EQ(d.stats.sync_losses, 0u) << c.name << " reason " << to_string(d.stats.last_loss_reason);
    EXPECT_EQ(d.mismatches, 0) << c.name;
    EXPECT_GT(d.checked, 10 * c.w.teeth()) << c.name;
    EXPECT_LT(d.max_angle_err, 1e-9) << c.name;
  }
}

TEST(CrankDecoder, SymmetricWheelIsRejected) {
  const CrankDecoder dec(test::wheel_runs(36, {16, 2, 16, 2}), DecoderParams{});
  EXPECT_FALSE(dec.valid());
  EXPECT_NE(dec.error().find("symmetric"), std::string::npos);
  WheelGeometry nogap;
  nogap.positions = 36;
  nogap.missing = 0;
  EXPECT_FALSE(CrankDecoder(nogap, DecoderParams{}).valid());
}

TEST(CrankDecoder, MachiningErrorBoundsAngleErrorAndCorrectionsRemoveIt) {
  // GIVEN a 60-2 wheel with 0.05° (1σ) machining error per tooth
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0.0, 0.05 * std::numbers::pi / 180.0);
  SynthOptions o;
  for (int i = 0; i < 58; ++i) o.tooth_error_rad.push_back(n(rng));
  o.ripple = 0.03;
  const auto s = test::synthesize(o);
  double max_err = 0;
  for (double e : o.tooth_error_rad) max_err = std::max(max_err, std::abs(e));
  // WHEN decoded without a table: the angle error is the tooth error, never more
  const auto plain = run(s, o.wheel);
  EXPECT_EQ(plain.stats.sync_losses, 0u);
  EXPECT_EQ(plain.mismatches, 0);
  EXPECT_LE(plain.max_angle_err, max_err + 1e-12);
  // WHEN decoded with the correction table: the angle is exact
  const auto corrected = run(s, o.wheel, {}, o.tooth_error_rad);
  EXPECT_LT(corrected.max_angle_err, 1e-9);
  // and the true width enters the speed: width = nominal + corr[i] - corr[i-1]
  const auto& ev = corrected.teeth.back();
  EXPECT_GT(ev.width_rad, 0.0);
}

TEST(CrankDecoder, CrankingAndFirstCombustionSqueeze) {
  // GIVEN cranking at 200 rpm with 40 % compression ripple (2 per rev, 4-cyl), accelerating to 1200 rpm
  for (const auto& w : {test::wheel_nm(60, 2), test::wheel_nm(36, 1)}) {
    SynthOptions o;
    o.wheel = w;
    o.rpm0 = 200;
    o.rpm1 = 1200;
    o.ripple = 0.4;
    o.duration_s = 1.0;
    o.step_s = 5e-6;
    const auto d = run(test::synthesize(o), w);
    // THEN it syncs, and whenever it claims sync the index is right
    EXPECT_GT(d.stats.syncs, 0u);
    EXPECT_EQ(d.mismatches, 0) << w.positions;
    EXPECT_GT(d.checked, 5 * w.teeth());
  }
}

TEST(CrankDecoder, HardAccelerationKeepsSync) {
  SynthOptions o;
  o.rpm0 = 800;
  o.rpm1 = 6500;
  o.duration_s = 0.4;  // ~14000 rpm/s
  o.ripple = 0.05;
  const auto d = run(test::synthesize(o), o.wheel);
  EXPECT_EQ(d.stats.sync_losses, 0u) << to_string(d.stats.last_loss_reason);
  EXPECT_EQ(d.mismatches, 0);
}

TEST(CrankDecoder, RuntPulsesAreRejectedAndCounted) {
  SynthOptions o;
  o.falling_edges = false;
  auto s = test::synthesize(o);
  // Insert runt edges at 10 % of a tooth period after every 50th tooth (and one at 15 % after the gap tooth).
  std::vector<EdgeEvent> noisy;
  int inserted = 0;
  for (std::size_t i = 0; i + 1 < s.edges.size(); ++i) {
    noisy.push_back(s.edges[i]);
    if (s.edges[i].channel == 0 && i % 50 == 25 && s.edges[i + 1].channel == 0) {
      const std::int64_t dt = s.edges[i + 1].t_ns - s.edges[i].t_ns;
      noisy.push_back(EdgeEvent{s.edges[i].t_ns + dt / 10, 0, 1});
      ++inserted;
    }
  }
  s.edges = noisy;
  const auto d = run(s, o.wheel);
  EXPECT_EQ(d.stats.noise_edges, static_cast<std::uint64_t>(inserted));
  EXPECT_EQ(d.stats.sync_losses, 0u);
  EXPECT_EQ(d.mismatches, 0);
  int flagged = 0;
  for (const auto& t : d.teeth) flagged += (t.events & kToothNoiseRejected) ? 1 : 0;
  EXPECT_EQ(flagged, inserted);
}

TEST(CrankDecoder, LostToothIsInterpolatedWithoutLosingSync) {
  SynthOptions o;
  o.falling_edges = false;
  o.duration_s = 0.3;
  auto s = test::synthesize(o);
  // Drop one crank tooth every ~3 revolutions, never a gap-adjacent one.
  std::vector<EdgeEvent> lossy;
  int dropped = 0;
  for (std::size_t i = 0; i < s.edges.size(); ++i) {
    const auto& e = s.edges[i];
    bool drop = false;
    if (e.channel == 0 && i > 200 && i % 170 == 0) {
      for (const auto& t : s.teeth) {
        if (t.t_ns == e.t_ns) drop = (t.tooth720 % 58) > 2 && (t.tooth720 % 58) < 55;
      }
    }
    if (drop) {
      ++dropped;
      continue;
    }
    lossy.push_back(e);
  }
  ASSERT_GT(dropped, 3);
  s.edges = lossy;
  const auto d = run(s, o.wheel);
  EXPECT_EQ(d.stats.lost_teeth, static_cast<std::uint64_t>(dropped));
  EXPECT_EQ(d.stats.sync_losses, 0u) << to_string(d.stats.last_loss_reason);
  EXPECT_EQ(d.mismatches, 0);
}

TEST(CrankDecoder, StallThenRestartResyncs) {
  SynthOptions o;
  o.duration_s = 0.1;
  const auto a = test::synthesize(o);
  auto edges = a.edges;
  const std::int64_t shift = a.edges.back().t_ns + 2'000'000'000;  // 2 s silence
  for (auto e : a.edges) {
    e.t_ns += shift;
    edges.push_back(e);
  }
  CrankDecoder dec(o.wheel, DecoderParams{});
  ToothEvent ev;
  EXPECT_FALSE(dec.poll(0));
  int synced_after = 0;
  for (std::size_t i = 0; i < edges.size(); ++i) {
    if (i == a.edges.size()) {
      EXPECT_EQ(dec.state(), SyncState::kSynced);
      EXPECT_TRUE(dec.poll(a.edges.back().t_ns + 600'000'000));  // live time-out
      EXPECT_EQ(dec.state(), SyncState::kStalled);
    }
    if (dec.on_edge(edges[i], ev) && i >= a.edges.size() && ev.sync == SyncState::kSynced) ++synced_after;
  }
  EXPECT_EQ(dec.stats().stalls, 1u);
  EXPECT_EQ(dec.stats().syncs, 2u);
  EXPECT_GT(synced_after, 100);
}

TEST(CrankDecoder, CamGivesPhaseAndWithoutCamPhaseStaysUnknown) {
  SynthOptions o;
  o.start_deg = 500;  // start in the second revolution
  const auto s = test::synthesize(o);
  const auto d = run(s, o.wheel);
  EXPECT_EQ(d.mismatches, 0);
  EXPECT_GT(d.checked, 400);
  // Without the cam: synced, but the phase is never known
  DecoderParams p;
  p.use_cam = false;
  CrankDecoder dec(o.wheel, p);
  ToothEvent ev;
  int synced = 0;
  for (const auto& e : s.edges) {
    if (dec.on_edge(e, ev) && ev.sync == SyncState::kSynced) {
      ++synced;
      EXPECT_FALSE(ev.phase_known);
    }
  }
  EXPECT_GT(synced, 400);
  // A cam edge in the wrong revolution re-phases and is counted
  DecoderParams shifted;
  shifted.cam_window_start_deg = 360;
  shifted.cam_window_end_deg = 720;
  CrankDecoder dec2(o.wheel, shifted);
  std::map<std::int64_t, int> truth;
  for (const auto& t : s.teeth) truth[t.t_ns] = t.tooth720;
  int off_by_rev = 0, checked = 0;
  for (const auto& e : s.edges) {
    if (dec2.on_edge(e, ev) && ev.sync == SyncState::kSynced && ev.phase_known) {
      ++checked;
      off_by_rev += (ev.tooth == (truth[ev.t_ns] + 58) % 116) ? 1 : 0;
    }
  }
  EXPECT_EQ(off_by_rev, checked);
}

// Cam phase: a cam edge outside a fixed window is a counted cam phase error (never a silent phase);
// cam_window: auto learns the cam edge's angle and reports it; a cam edge that then comes elsewhere is an
// error.
TEST(CrankDecoder, CamOutsideItsWindowIsCountedAndAutoWindowLearnsTheAngle) {
  SynthOptions o;
  o.cam_rise_deg = 400.0;  // in the second revolution of the simulator's cycle
  o.duration_s = 0.4;
  const auto s = test::synthesize(o);
  DecoderParams narrow;  // the configured window misses the cam: every synced cam edge is an error
  narrow.cam_window_start_deg = 100.0;
  narrow.cam_window_end_deg = 200.0;
  const auto bad = run(s, o.wheel, narrow);
  EXPECT_EQ(bad.checked, 0);  // the phase is never claimed
  EXPECT_GE(bad.stats.cam_phase_errors, 8u);

  DecoderParams autop;
  autop.cam_window_auto = true;
  CrankDecoder dec(o.wheel, autop);
  DecoderEventLog log;
  dec.set_event_log(&log);
  std::map<std::int64_t, int> truth;
  for (const auto& t : s.teeth) truth[t.t_ns] = t.tooth720;
  ToothEvent ev;
  int phased = 0, consistent = 0;
  for (const auto& e : s.edges) {
    if (dec.on_edge(e, ev) && ev.sync == SyncState::kSynced && ev.phase_known) {
      ++phased;
      consistent += ev.tooth == (truth[ev.t_ns] + 58) % 116 ? 1 : 0;  // the cam's revolution is revolution 0
    }
  }
  EXPECT_NEAR(dec.stats().cam_angle_deg, 40.0, 0.5);  // 400° of the cycle, in its own revolution
  EXPECT_EQ(dec.stats().cam_phase_errors, 0u);
  EXPECT_GT(phased, 500);
  EXPECT_EQ(consistent, phased);
  // Transitions were logged with their edge times: first edge, then synced.
  DecoderEvent de;
  ASSERT_TRUE(log.pop(de));
  EXPECT_EQ(de.kind, DecoderEventKind::kFirstEdge);
  EXPECT_EQ(de.t_ns, s.edges.front().t_ns);
  ASSERT_TRUE(log.pop(de));
  EXPECT_EQ(de.kind, DecoderEventKind::kSynced);
  EXPECT_EQ(de.to, SyncState::kSynced);
  EXPECT_TRUE(truth.count(de.t_ns) == 1);
  EXPECT_FALSE(log.pop(de));

  // Learned, then a stray cam edge 150° away from the learned angle: counted, logged, phase kept.
  std::vector<EdgeEvent> edges = s.edges;
  const std::size_t mid = edges.size() * 3 / 4;
  for (std::size_t k = mid; k < edges.size(); ++k) {
    if (edges[k].channel == 1 && edges[k].level == 1) {  // a cam rise: add one 150° later (at 3000 rpm)
      const std::int64_t t = edges[k].t_ns + static_cast<std::int64_t>(150.0 / 18000.0 * 1e9);
      auto it = std::lower_bound(edges.begin(), edges.end(), t,
                                 [](const EdgeEvent& a, std::int64_t x) { return a.t_ns < x; });
      edges.insert(it, {EdgeEvent{t, 1, 1}, EdgeEvent{t + 1000, 1, 0}});
      break;
    }
  }
  CrankDecoder dec3(o.wheel, autop);
  dec3.set_event_log(&log);
  for (const auto& e : edges) dec3.on_edge(e, ev);
  EXPECT_EQ(dec3.stats().cam_phase_errors, 1u);
  EXPECT_EQ(dec3.stats().sync_losses, 0u);
  bool logged = false;
  while (log.pop(de)) logged = logged || de.kind == DecoderEventKind::kCamPhase;
  EXPECT_TRUE(logged);
}

TEST(CrankDecoder, FallingEdgeWheel) {
  SynthOptions o;
  auto s = test::synthesize(o);
  // Invert crank levels: the marking edges are now falling edges.
  for (auto& e : s.edges)
    if (e.channel == 0) e.level ^= 1;
  auto w = o.wheel;
  w.rising_edge = false;
  const auto d = run(s, w);
  EXPECT_EQ(d.mismatches, 0);
  EXPECT_GT(d.checked, 400);
}

TEST(CrankDecoder, OnEdgeDoesNotAllocate) {
  SynthOptions o;
  const auto s = test::synthesize(o);
  CrankDecoder dec(o.wheel, DecoderParams{});
  ToothEvent ev;
  std::size_t n = 0;
  const test::AllocationScope scope;
  for (const auto& e : s.edges) n += dec.on_edge(e, ev) ? 1 : 0;
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_GT(n, 0u);
}

TEST(CrankDecoder, CorrectionTableValidation) {
  CrankDecoder dec(WheelGeometry{}, DecoderParams{});
  std::vector<double> wrong(57, 0.0);
  EXPECT_FALSE(dec.set_tooth_corrections(wrong));
  std::vector<double> nan(116, 0.0);
  nan[3] = std::nan("");
  EXPECT_FALSE(dec.set_tooth_corrections(nan));
  std::vector<double> ok(116, 1e-4);
  EXPECT_TRUE(dec.set_tooth_corrections(ok));
}

}  // namespace
}  // namespace torqued

namespace torqued {
namespace {

TEST(CrankDecoder, StoppingEngineIsNeverMisIndexed) {
  // GIVEN an engine coasting down from 600 rpm to 30 rpm with strong compression ripple (long periods at the
  // end, each longer than the one before: looks like missing teeth)
  for (const auto& w : {test::wheel_nm(60, 2), test::wheel_nm(36, 1)}) {
    test::SynthOptions o;
    o.wheel = w;
    o.rpm0 = 600;
    o.rpm1 = 30;
    o.ripple = 0.8;  // the speed drops to a fifth at every compression
    o.duration_s = 1.2;
    o.step_s = 5e-6;
    const auto d = run(test::synthesize(o), w);
    // THEN every tooth claimed synced has the true index (sync may be dropped, never wrong), and no long
    // period was taken for a lost tooth
    EXPECT_EQ(d.mismatches, 0) << w.positions;
    EXPECT_EQ(d.stats.lost_teeth, 0u) << w.positions;
    EXPECT_GT(d.checked, w.teeth()) << w.positions << " syncs " << d.stats.syncs << " losses "
                                    << d.stats.sync_losses << " noise " << d.stats.noise_edges << " "
                                    << to_string(d.stats.last_loss_reason);
  }
}

TEST(CrankDecoder, FirstCombustionSqueezesTheGapWithoutLosingSync) {
  // GIVEN a 60-2 wheel turning at 300 rpm (cranking), and the first combustion accelerating it to 500 rpm
  // during a gap: that gap lasts 2.25 pitches of the previous speed instead of 3
  const WheelGeometry w;
  const double pitch = 2.0 * std::numbers::pi / 60.0;
  std::vector<EdgeEvent> edges;
  std::vector<int> truth;  // tooth720 per crank edge
  double t = 0.001;
  const auto omega = [](double rpm) { return rpm * 2.0 * std::numbers::pi / 60.0; };
  for (int rev = 0; rev < 16; ++rev) {
    for (int i = 0; i < 58; ++i) {
      const bool squeezed = rev >= 8;
      const double width = (i == 0 ? 3.0 : 1.0) * pitch;
      const double speed = (rev == 8 && i == 0) ? omega(400.0) : omega(squeezed ? 500.0 : 300.0);
      t += width / speed;
      edges.push_back(EdgeEvent{static_cast<std::int64_t>(t * 1e9), 0, 1});
      truth.push_back((rev % 2) * 58 + i);
      if (rev % 2 == 0 && i == 7)
        edges.push_back(EdgeEvent{static_cast<std::int64_t>(t * 1e9) + 1000, 1, 1});  // cam ~45°
    }
  }
  CrankDecoder dec(w, DecoderParams{});
  ToothEvent ev;
  std::size_t k = 0;
  int checked = 0, wrong = 0;
  for (const auto& e : edges) {
    const bool crank = e.channel == 0;
    const bool tooth = dec.on_edge(e, ev);
    if (!crank) continue;
    if (tooth && ev.sync == SyncState::kSynced && ev.phase_known) {
      ++checked;
      wrong += ev.tooth == truth[k] ? 0 : 1;
    }
    ++k;
  }
  // THEN synced during cranking, no sync loss at the squeeze, every index right
  EXPECT_EQ(dec.stats().sync_losses, 0u) << to_string(dec.stats().last_loss_reason);
  EXPECT_EQ(dec.stats().syncs, 1u);
  EXPECT_EQ(wrong, 0);
  EXPECT_GT(checked, 12 * 58);
}

}  // namespace
}  // namespace torqued

namespace torqued {
namespace {

// "36-2-1" was once the mirror image of the Mitsubishi 4B11 wheel. In rotation order it is 17 teeth, one
// missing, 16 teeth, two missing: after tooth 0 (first tooth after the two-tooth gap) come 16 one-pitch
// periods, then a two-pitch period (the single gap), 15 more, then the three-pitch gap closing the
// revolution.
TEST(WheelNames, Mitsubishi36m2m1IsInRotationOrder) {
  WheelGeometry w;
  std::string err;
  ASSERT_TRUE(wheel_from_name("36-2-1", w, &err)) << err;
  ASSERT_EQ(w.teeth(), 33);
  EXPECT_DOUBLE_EQ(w.tooth_angles_deg[16], 160.0);  // 17th tooth
  EXPECT_DOUBLE_EQ(w.tooth_angles_deg[17], 180.0);  // after one missing position
  EXPECT_DOUBLE_EQ(w.tooth_angles_deg[32], 330.0);  // last; then 2 missing (340, 350), tooth 0 at 360
}

TEST(WheelNames, CatalogueEntriesAreValidAndUnknownNamesListThem) {
  for (const NamedWheel& n : wheel_catalogue()) {
    WheelGeometry w;
    DecoderParams p;
    std::string err;
    ASSERT_TRUE(trigger_from_name(n.name, w, p, &err)) << n.name << ": " << err;
    const CrankDecoder dec(w, p);
    if (n.n_cam > 0 || n.width_coded) {  // pattern wheels: the crank alone cannot identify the position
      WheelGeometry crank_only;
      ASSERT_TRUE(wheel_from_name(n.name, crank_only, &err));
      EXPECT_FALSE(CrankDecoder(crank_only, DecoderParams{}).valid()) << n.name;
    }
    if (std::string(n.name) == "36-2-2-16-16") {  // symmetric: refused with a reason, never a silent non-sync
      EXPECT_FALSE(dec.valid());
      EXPECT_NE(dec.error().find("symmetric"), std::string::npos) << dec.error();
    } else {
      EXPECT_TRUE(dec.valid()) << n.name << ": " << dec.error();
    }
  }
  WheelGeometry w;
  std::string err;
  EXPECT_FALSE(wheel_from_name("36-3-1", w, &err));
  EXPECT_NE(err.find("known wheels: N-M"), std::string::npos) << err;
  EXPECT_NE(err.find("36-2-2-2"), std::string::npos) << err;
  EXPECT_NE(err.find("arctic-cat"), std::string::npos) << err;
  ASSERT_TRUE(wheel_from_name("60-2", w, &err));
  EXPECT_EQ(w.teeth(), 58);
  // A name several production wheels go by is refused with the candidates
  EXPECT_FALSE(wheel_from_name("36-2-2", w, &err));
  EXPECT_NE(err.find("ambiguous: 36-2-2-16-16"), std::string::npos) << err;
  EXPECT_NE(err.find("36-2-2-17-15"), std::string::npos) << err;
  // Maker aliases are the same wheels as their N-M names
  for (const auto& [alias, nm] : {std::pair{"bosch-60-2", "60-2"}, std::pair{"ford-edis-36-1", "36-1"},
                                  std::pair{"toyota-36-2", "36-2"}}) {
    WheelGeometry a, b;
    ASSERT_TRUE(wheel_from_name(alias, a, &err)) << err;
    ASSERT_TRUE(wheel_from_name(nm, b, &err)) << err;
    ASSERT_EQ(a.teeth(), b.teeth()) << alias;
    for (int i = 0; i < a.teeth(); ++i)
      EXPECT_NEAR(a.tooth_angles_deg[static_cast<std::size_t>(i)], 360.0 * i / b.positions, 1e-9) << alias;
  }
}

TEST(WheelNames, JeepEvdDecodesWithZeroLossesFromTheFirstIdentifyingGap) {
  // GIVEN the Jeep/Chrysler EVD 36-2-2 (gaps after 17 and 15 teeth) cranking then running, by name
  WheelGeometry w;
  DecoderParams p;
  std::string err;
  ASSERT_TRUE(trigger_from_name("jeep-evd", w, p, &err)) << err;
  p.use_cam = false;
  CrankDecoder dec(w, p);
  ASSERT_TRUE(dec.valid()) << dec.error();
  test::SynthOptions o;
  o.wheel = test::wheel_runs(36, {17, 2, 15, 2});
  o.rpm0 = 300.0;
  o.rpm1 = 3000.0;
  o.duration_s = 2.0;
  o.ripple = 0.1;
  o.cam = false;
  const test::SynthOutput s = test::synthesize(o);
  ToothEvent t;
  int synced = 0, wrong = 0;
  std::size_t k = 0;
  for (const auto& e : s.edges) {
    if (!dec.on_edge(e, t) || t.sync != SyncState::kSynced) continue;
    while (k < s.teeth.size() && s.teeth[k].t_ns < t.t_ns) ++k;
    ++synced;
    if (k == s.teeth.size() || s.teeth[k].tooth720 % 32 != t.tooth % 32) ++wrong;
  }
  // THEN one sync, no loss, every synced tooth has its true index
  EXPECT_EQ(dec.stats().syncs, 1u);
  EXPECT_EQ(dec.stats().sync_losses, 0u);
  EXPECT_EQ(wrong, 0);
  EXPECT_GT(synced, 32 * 20);
}

}  // namespace
}  // namespace torqued
