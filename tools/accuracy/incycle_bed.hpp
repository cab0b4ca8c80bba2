#pragma once
// In-cycle indicated torque on the unseen-engines bed from a FRESH start without any fuel cut-off (a vehicle
// at start, a bench that never overruns): the tooth-error learner starts empty and learns on the evaluated
// recording itself, its table applied to the widths at each cycle end as the daemon's chain does
// (AngleChain::on_cycle_end → decoder), the in-cycle observers valid once it is ready. Scored: the Kalman and
// Fourier per-tooth indicated torque against the simulator's truth over the recording's last steady plateaus.
// Not real-time code.
#include <string>

#include "burn_phase_learner.hpp"
#include "cylinder_eval.hpp"
#include "pipeline_eval.hpp"
#include "tooth_error_learner.hpp"
#include "unseen_engines.hpp"

namespace torqued::eval {

/// The burn-phasing learner at the end of a run (kalman.burn_phase_learn; on false: not run).
struct BurnPhaseSummary {
  bool on = false;
  double offset_deg = 0.0;
  BurnPhaseStats stats;
};

/// One scored regime: the in-cycle Kalman and Fourier figures, and the share of the Kalman's samples within
/// its claimed 1σ.
struct InCycleRegime {
  InCycleStats kalman, fourier;
  double kalman_cover_pct = 0.0;    ///< |T̂ − T| ≤ claimed 1σ (% of the scored teeth; 68 when honest)
  double kalman_slow_pct = 0.0;     ///< RMS of the per-cycle mean error (% of p2p): the load-like part
  double kalman_worst_s_pct = 0.0;  ///< worst RMS over 1 s spans of the window (% of p2p)
};

struct InCycleBedResult {
  std::string engine;
  bool report = false;
  double duration_s = 0.0;            ///< length of the recording (s from the fresh start)
  double score_from_s = 0.0;          ///< scored from here to the end (steady plateaus only)
  InCycleStats kalman, fourier;       ///< scored window
  double ready_at_s = -1.0;           ///< when the learner's table was first applied (−1: never)
  double tooth_edge_resid_deg = 0.0;  ///< edge-angle residual of the final table vs the true wheel (deg RMS)
  std::uint64_t cycles_used = 0, cycles_cutoff = 0;
  bool low_orders = false;  ///< every per-revolution order inside the fit identified at the end
  ToothLearnQuality quality = ToothLearnQuality::kNone;  ///< what the final table rests on
  std::string orders;  ///< per order: source letter (h held, o overrun, O overrun-speeds, s speeds, f firing)
  BurnPhaseSummary burn;
  InCycleRegime early;  ///< the first 8 s after ready (the young table's phase; cover, slow, worst1s too)
};

/// In-cycle torque through transients and a fuel cut-off entry/exit (sim::bed_incycle_regimes_run): the
/// same fresh start as evaluate_incycle_fresh(short), then the two regimes, each scored over its window.
struct InCycleRegimesResult {
  std::string engine;
  bool report = false;
  InCycleRegime transient, cutoff;
  double ready_at_s = -1.0;
  ToothLearnQuality quality = ToothLearnQuality::kNone;
  BurnPhaseSummary burn;
};

/// In-cycle torque on a ramp from idle after a fresh start (sim::bed_ramp_start_run: the demo's shape on a
/// bed engine), scored over its first 15 s: the young wheel table through speed ramps to 3500 rpm.
struct InCycleRampResult {
  std::string engine;
  bool report = false;
  InCycleRegime ramp;
  double ready_at_s = -1.0;
  ToothLearnQuality quality = ToothLearnQuality::kNone;
  BurnPhaseSummary burn;
};

/// `table`: kLearned (fresh learner on the recording, the figure), kTrue (the simulator's wheel: the floor),
/// kNone (no correction). `short_run`: a 20 s recording instead of 60 s.
[[nodiscard]] InCycleBedResult evaluate_incycle_fresh(const sim::BedEngine& engine,
                                                      const EvalOptions& options, bool short_run);
/// Transient and cut-off entry/exit regimes after a fresh start (tooth table learned on the recording).
[[nodiscard]] InCycleRegimesResult evaluate_incycle_regimes(const sim::BedEngine& engine,
                                                            const EvalOptions& options);
/// The ramp from idle after a fresh start (tooth table learned on the recording). `dump_path`: the per-tooth
/// CSV of run (EvalOptions::incycle_dump's columns; empty: none).
[[nodiscard]] InCycleRampResult evaluate_incycle_ramp(const sim::BedEngine& engine,
                                                      const EvalOptions& options,
                                                      const std::string& dump_path = {});

}  // namespace torqued::eval
