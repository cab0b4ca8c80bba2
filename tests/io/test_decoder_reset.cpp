// CrankDecoder::reset() resets everything: GIVEN a decoder that has decoded other edges (left mid-state: a
// learned cam window, a held debounce edge, cam edges waiting for a tooth, a pattern search, counters), WHEN
// it is reset() and fed an input, THEN every tooth event and every counter equal those of a new decoder fed
// the same input (exact: the decoder is deterministic). Inputs cover every state machine: a 60-2 wheel with
// a learned cam window, glitch pulses (debounce), runts and a stall (tests/io/synthetic_wheel.hpp), and real
// captures of a cam-pattern wheel (4g63, Miata NB2) and a pulse-width-coded one (GM 24x), tests/data.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "crank_decoder.hpp"
#include "edge_file_source.hpp"
#include "synthetic_wheel.hpp"
#include "wheel_names.hpp"

namespace torqued {
namespace {

struct Output {
  std::vector<ToothEvent> teeth;
  DecoderStats stats;
};

Output feed(CrankDecoder& dec, const std::vector<EdgeEvent>& edges) {
  Output o;
  ToothEvent ev;
  for (const EdgeEvent& e : edges) {
    if (dec.on_edge(e, ev)) o.teeth.push_back(ev);
  }
  o.stats = dec.stats();
  return o;
}

void expect_same(const Output& a, const Output& b) {
  ASSERT_EQ(a.teeth.size(), b.teeth.size());
  for (std::size_t i = 0; i < a.teeth.size(); ++i) {
    const ToothEvent &x = a.teeth[i], &y = b.teeth[i];
    ASSERT_EQ(x.t_ns, y.t_ns) << "event " << i;
    EXPECT_EQ(x.source_t_ns, y.source_t_ns) << "event " << i;
    EXPECT_EQ(x.tooth, y.tooth) << "event " << i;
    EXPECT_EQ(x.angle_rad, y.angle_rad) << "event " << i;
    EXPECT_EQ(x.width_rad, y.width_rad) << "event " << i;
    EXPECT_EQ(x.speed_rad_s, y.speed_rad_s) << "event " << i;
    EXPECT_EQ(x.sync, y.sync) << "event " << i;
    EXPECT_EQ(x.phase_known, y.phase_known) << "event " << i;
    EXPECT_EQ(x.events, y.events) << "event " << i;
  }
  const DecoderStats &s = a.stats, &t = b.stats;
  EXPECT_EQ(s.edges, t.edges);
  EXPECT_EQ(s.crank_edges, t.crank_edges);
  EXPECT_EQ(s.teeth, t.teeth);
  EXPECT_EQ(s.synced_teeth, t.synced_teeth);
  EXPECT_EQ(s.cam_edges, t.cam_edges);
  EXPECT_EQ(s.noise_edges, t.noise_edges);
  EXPECT_EQ(s.debounced_edges, t.debounced_edges);
  EXPECT_EQ(s.lost_teeth, t.lost_teeth);
  EXPECT_EQ(s.gaps, t.gaps);
  EXPECT_EQ(s.syncs, t.syncs);
  EXPECT_EQ(s.sync_losses, t.sync_losses);
  EXPECT_EQ(s.stalls, t.stalls);
  EXPECT_EQ(s.cam_phase_errors, t.cam_phase_errors);
  EXPECT_EQ(s.width_code_errors, t.width_code_errors);
  EXPECT_EQ(s.rejected_edges, t.rejected_edges);
  EXPECT_EQ(s.cam_angle_deg, t.cam_angle_deg);
  EXPECT_EQ(s.last_loss_reason, t.last_loss_reason);
  EXPECT_EQ(s.last_loss_t_ns, t.last_loss_t_ns);
}

// `before`: edges decoded first (then reset()), so that stale state would show.
// Returns the new decoder's counters (what the input exercised).
DecoderStats check_reset(const WheelGeometry& w, const DecoderParams& p, const std::vector<EdgeEvent>& input,
                         const std::vector<EdgeEvent>& before) {
  CrankDecoder fresh(w, p);
  EXPECT_TRUE(fresh.valid()) << fresh.error();
  const Output want = feed(fresh, input);
  EXPECT_GT(want.stats.synced_teeth, 0u);  // the input exercises the synced path
  CrankDecoder used(w, p);
  EXPECT_GT(feed(used, before).stats.teeth, 0u);
  used.reset();
  EXPECT_EQ(used.state(), SyncState::kNoSignal);
  EXPECT_FALSE(used.phase_known());
  EXPECT_EQ(used.stats().edges, 0u);
  expect_same(want, feed(used, input));
  return want.stats;
}

// The first `fraction` of the edges, moved `shift_ns` later (a stale state with times after the input's).
std::vector<EdgeEvent> prefix_shifted(const std::vector<EdgeEvent>& edges, double fraction,
                                      std::int64_t shift_ns) {
  std::vector<EdgeEvent> out(edges.begin(), edges.begin() + static_cast<long>(fraction * edges.size()));
  for (EdgeEvent& e : out) e.t_ns += shift_ns;
  return out;
}

TEST(DecoderReset, GapWheelWithLearnedCamDebounceRuntsAndStallDecodesAsNew) {
  test::SynthOptions o;
  o.cam_rise_deg = 400.0;
  o.duration_s = 0.3;
  o.rpm0 = 1500.0;
  o.rpm1 = 3000.0;
  o.ripple = 0.05;
  std::vector<EdgeEvent> edges = test::synthesize(o).edges;
  // A 200 ns glitch pulse in the middle (its tooth edge is a runt without the debounce), then a 1 s stall.
  const std::size_t a = edges.size() / 3, b = edges.size() / 2;
  const std::int64_t ta = (edges[a].t_ns + edges[a + 1].t_ns) / 2;
  edges.insert(edges.begin() + static_cast<long>(a) + 1, {EdgeEvent{ta, 0, 1}, EdgeEvent{ta + 200, 0, 0}});
  for (std::size_t k = b; k < edges.size(); ++k) edges[k].t_ns += 1'000'000'000;
  DecoderParams p;
  p.cam_window_auto = true;
  p.cam_auto_edges = 2;
  const DecoderStats s = check_reset(o.wheel, p, edges, prefix_shifted(edges, 0.7, 3'000'000'000));
  EXPECT_GE(s.noise_edges, 1u);             // the glitch's tooth edge was a runt
  EXPECT_EQ(s.stalls, 1u);                  // the stall restarted the sync
  EXPECT_NEAR(s.cam_angle_deg, 40.0, 1.0);  // the cam window was learned (400° of the cycle)
  p.min_pulse_us = 1.0;  // the same with the debounce on (a held tooth edge at the end of `before`)
  EXPECT_EQ(check_reset(o.wheel, p, edges, prefix_shifted(edges, 0.7, 3'000'000'000)).debounced_edges, 1u);
}

std::vector<EdgeEvent> read_capture(const char* file, const char* crank, const char* cam) {
  EdgeCsvOptions o;
  o.crank_column = crank;
  o.cam_column = cam;
  o.first_row = EdgeCsvFirstRow::kEdgesFromLow;
  EdgeCsvSource src(std::string(TORQUED_SOURCE_DIR) + "/tests/data/captures/rusefi/" + file, o);
  EXPECT_TRUE(src.ok()) << src.last_error();
  std::vector<EdgeEvent> edges;
  EdgeEvent e;
  while (src.next(e) == SourceStatus::kOk) edges.push_back(e);
  return edges;
}

DecoderStats check_named(const char* file, const char* name, const char* crank, const char* cam) {
  WheelGeometry w;
  DecoderParams p;
  std::string err;
  EXPECT_TRUE(trigger_from_name(name, w, p, &err)) << err;
  p.use_cam = cam[0] != '\0';
  const std::vector<EdgeEvent> edges = read_capture(file, crank, cam);
  EXPECT_FALSE(edges.empty());
  SCOPED_TRACE(name);
  return check_reset(w, p, edges, prefix_shifted(edges, 0.8, 100'000'000'000));
}

TEST(DecoderReset, PatternWheelsDecodeAsNew) {
  EXPECT_GE(check_named("4g63-cranking.csv", "4g63", "crank", "cam").stalls, 2u);
  EXPECT_GE(check_named("nb2-cranking-good.csv", "miata-nb2", "crank", "cam").sync_losses, 1u);
  EXPECT_GT(check_named("gm_24x_cranking.csv", "gm-24x", "crank", "").synced_teeth, 40u);
}

}  // namespace
}  // namespace torqued
