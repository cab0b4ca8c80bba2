// Crank decoder on the simulator's scenarios (tools/sim/engine_sim.hpp): after sync every tooth index
// matches the truth, the angle error stays below the wheel's machining error (and vanishes with the
// correction table), and no clean scenario loses sync. 3-cylinder and 36-1 by configuration only.
#include <gtest/gtest.h>

#include <cmath>
#include <unordered_map>

#include "crank_decoder.hpp"
#include "engine_sim.hpp"

namespace torqued {
namespace {

struct Result {
  DecoderStats stats;
  int checked = 0, mismatches = 0;
  double max_angle_err_rad = 0.0;
  double max_speed_rel_err = 0.0;
};

Result decode(const sim::SimOutput& out, const WheelGeometry& wheel, bool with_corrections) {
  CrankDecoder dec(wheel, DecoderParams{});
  EXPECT_TRUE(dec.valid()) << dec.error();
  if (with_corrections) {
    EXPECT_TRUE(dec.set_tooth_corrections(out.tooth_error_rad));
  }
  std::unordered_map<std::int64_t, const sim::ToothTruth*> truth;
  for (const auto& t : out.teeth) truth[t.t_meas_ns] = &t;
  Result r;
  ToothEvent ev;
  for (const auto& e : out.edges) {
    if (!dec.on_edge(e, ev) || ev.sync != SyncState::kSynced || !ev.phase_known) continue;
    const auto it = truth.find(ev.t_ns);
    if (it == truth.end()) continue;
    ++r.checked;
    if (ev.tooth != it->second->tooth) ++r.mismatches;
    r.max_angle_err_rad = std::max(r.max_angle_err_rad, std::abs(ev.angle_rad - it->second->angle720_rad));
  }
  r.stats = dec.stats();
  return r;
}

class DecoderOnSim : public ::testing::TestWithParam<const char*> {};

TEST_P(DecoderOnSim, SyncsKeepsSyncAndAngleErrorBelowToothError) {
  // GIVEN a simulator scenario with 0.05° machining error, 0.3 µs jitter and 50 MHz quantisation
  sim::Scenario sc = sim::scenario_by_name(GetParam());
  sc.duration_s = std::min(sc.duration_s, 1.5);
  const sim::SimOutput out = sim::simulate(sc);
  double max_tooth_err = 0.0;
  for (double e : out.tooth_error_rad) max_tooth_err = std::max(max_tooth_err, std::abs(e));
  // WHEN decoded with the scenario's wheel
  const Result plain = decode(out, sc.wheel, false);
  // THEN: no sync loss, every synced tooth has the true index, angle error <= tooth error
  EXPECT_EQ(plain.stats.sync_losses, 0u) << to_string(plain.stats.last_loss_reason);
  EXPECT_EQ(plain.stats.noise_edges, 0u);
  EXPECT_EQ(plain.stats.lost_teeth, 0u);
  EXPECT_EQ(plain.mismatches, 0);
  EXPECT_GT(plain.checked,
            static_cast<int>(out.teeth.size()) - 4 * sc.wheel.teeth());  // synced within 2 cycles
  EXPECT_LE(plain.max_angle_err_rad, max_tooth_err + 1e-12);
  // AND with the true correction table the angle is exact
  const Result corrected = decode(out, sc.wheel, true);
  EXPECT_LT(corrected.max_angle_err_rad, 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Scenarios, DecoderOnSim,
                         ::testing::Values("steady_1000_low", "steady_4000_high", "three_cyl", "wheel_36_1",
                                           "misfire", "fuel_cut", "idle", "load_step", "throttle_step"),
                         [](const auto& info) { return std::string(info.param); });

}  // namespace
}  // namespace torqued
