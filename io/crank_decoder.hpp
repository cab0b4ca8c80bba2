#pragma once
// Crank decoder: crank/cam edge timestamps -> crank angle within 720°, per tooth (docs/io.md "Crank
// decoder"). Real-time safe: on_edge()/poll() never allocate, lock, block or throw; every noise edge, lost
// tooth, sync loss and stall is counted in DecoderStats. One instance per engine, driven by one thread.
//
// Wheel model: T real teeth at angles a[0..T-1] in [0, 2π) (tooth 0 = first tooth after the (first) gap),
// from an N-M WheelGeometry or an explicit tooth-angle list. w[i] = a[i] - a[i-1] (mod 2π) is the true
// angular width of the period ending at tooth i; teeth whose w[i] exceeds 1.5 pitch close a gap. Sync: a
// period P is a gap candidate when P / P_pred >= max(gap_ratio_min × g, √g), g = smallest gap ratio, P_pred
// the last normal period extrapolated by the period trend of the last two normal periods (cranking
// accelerates and decelerates by tens of percent per tooth; two gaps separated by one tooth, as on 36-2-2-2,
// are both seen). The count of teeth between consecutive gap candidates must match the wheel's pattern
// (plausibility) — which also identifies which gap it was on multi-gap wheels. Once synced each period is
// checked against the expected one E = w[i]·(P_prev / w[i-1])·trend; q = P / E: q < runt_fraction → noise
// edge rejected; q near 1 → tooth; q near (w[i]+w[i+1])/w[i] → one lost tooth, interpolated; anything else →
// lost sync with a reason. 720° phase: a cam edge whose estimated crank angle falls into
// [cam_window_start_deg, cam_window_end_deg) (angles in 0..720 from tooth 0 of the cycle's first revolution)
// fixes which revolution we are in.
#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "cam_phase.hpp"
#include "decoder_events.hpp"
#include "decoder_wheel.hpp"
#include "edge_debounce.hpp"
#include "engine_geometry.hpp"
#include "gap_sync.hpp"
#include "pattern_sync.hpp"
#include "records.hpp"

namespace torqued {

/// One cam edge of a cam-synced wheel: its crank angle in the 720° cycle (deg, from tooth 0 of the first
/// revolution) and its polarity.
struct CamEdgeSpec {
  double angle_deg = 0.0;
  bool rising = true;
};

/// Cam pattern of a cam-synced wheel: crank wheels without a gap (4G63: 2 teeth, Nissan CAS: 12)
/// or with a symmetric one (Miata NB2: 4 teeth, 70°/110°) take their position from the cam edges. n = 0: no
/// pattern (the crank gap syncs, the cam window below gives the phase).
struct CamPattern {
  static constexpr int kMaxEdges = 8;
  int n = 0;
  std::array<CamEdgeSpec, kMaxEdges> edges{};
  double tolerance_deg = 15.0;  ///< an observed cam edge matches a pattern edge within this (crank deg)
};

/// Decoder tuning; defaults work for the simulator and common Hall sensors. Validated by config/.
struct DecoderParams {
  double gap_ratio_min = 0.6;  /// gap candidate if P/P_pred >= gap_ratio_min × nominal gap ratio
                               /// (cranking/first-combustion squeeze)
  double gap_ratio_max = 2.0;  ///< and <= gap_ratio_max × nominal gap ratio (-), else "too slow" (stall-like)
  double sync_ratio_min = 0.6;  ///< synced: q = P/E accepted down to this (-)
  double sync_ratio_max =
      1.6;  ///< synced: q accepted up to this (-), beyond: lost-tooth hypothesis or sync loss
  double runt_fraction =
      0.5;  ///< synced: an edge earlier than runt_fraction × the expected one-pitch period is noise (-)
  double syncing_runt_fraction =
      0.3;  ///< syncing: earlier than this × the predicted period is noise (-; the
            ///< prediction is rougher before sync, cranking ripple can shorten a period 3x)
  /// Debounce: a tooth edge followed by the opposite crank edge within this time is a glitch pulse, not a
  /// tooth (µs; 0 = off). When on, each tooth is reported at its own time once the opposite edge confirms it.
  double min_pulse_us = 0.0;
  /// Noise bursts. Synced: after a noise edge, this many accepted teeth are judged as inside a burst (-).
  int burst_teeth = 4;
  /// In a burst a period shorter than this fraction of the running tooth period (median of the last three) is
  /// a glitch (synced); resyncing after a sync loss, the clean run before a gap (GapSync::kResyncRunBeforeGap
  /// periods) must lie within [x, 1/x] of its median and the gap must fit that median (-).
  double burst_tooth_ratio_min = 0.8;
  double lost_tooth_min_ratio = 1.5;  ///< lost-tooth hypothesis only where it makes q at least this large (-)
  int max_lost_teeth_per_rev = 2;     ///< more lost teeth than this in one revolution -> lost sync
  double max_trend =
      1.5;  ///< period trend (ratio of the last two normalised periods) clamped to [1/x, x] (-)
  double lost_tooth_min_rpm =
      400.0;  ///< below this speed a long period is a slowdown, never a lost tooth (rpm)
  std::int64_t stall_timeout_ns = 500'000'000;  ///< no crank edge for this long -> stalled (ns)
  bool use_cam = true;                          ///< use the cam channel for the 720° phase
  bool cam_rising = true;                       ///< which cam edge marks the phase
  double cam_window_start_deg = 0.0;  ///< cam edge must fall in [start, end) crank degrees of the 720° cycle
  double cam_window_end_deg = 360.0;
  /// cam_window: auto — learn the cam edge's crank angle from the first cam_auto_edges synced cam edges (all
  /// within cam_auto_spread_deg of each other, else learning restarts), then use the window [a − 90°, a +
  /// 90°) with the first learning edge's revolution as revolution 0. The angle found is in
  /// DecoderStats::cam_angle_deg.
  bool cam_window_auto = false;
  int cam_auto_edges = 4;
  double cam_auto_spread_deg = 10.0;
  std::uint8_t crank_channel = 0;  ///< EdgeEvent::channel of the crank signal
  std::uint8_t cam_channel = 1;    ///< EdgeEvent::channel of the cam signal
  /// Cam-synced wheel (set by a named wheel, io/wheel_names): position and 720° phase from these cam edges.
  CamPattern cam_pattern;
  /// Pulse-width-coded wheel (GM 24x): bit i (period ending at tooth i) is 1 when the opposite crank edge
  /// comes before width_code_threshold of that period (narrow), 0 after it (wide). Teeth <= 32.
  bool width_coded = false;
  std::uint32_t width_code = 0;
  double width_code_threshold = 0.5;
};

/// Why sync was lost (DecoderStats::last_loss_reason).
enum class SyncLossReason : std::uint8_t {
  kNone = 0,
  kUnexpectedGap,     ///< a long period where a tooth was expected, not explainable by a lost tooth
  kGapMissing,        ///< expected gap came as a normal period (extra tooth / noise)
  kTooManyLostTeeth,  ///< more than max_lost_teeth_per_rev in one revolution
  kPeriodTooShort,    ///< a period between runt threshold and sync_ratio_min
  kStall,             ///< no edge within stall_timeout_ns
  kCamPhase,          ///< cam edge outside its window while synced (phase re-established)
  kPattern,           ///< cam pattern or pulse-width code contradicted the decoded position twice in a row
};
[[nodiscard]] const char* to_string(SyncLossReason r) noexcept;
[[nodiscard]] const char* to_string(SyncState s) noexcept;

struct DecoderStats {
  std::uint64_t edges = 0;            ///< all edges seen
  std::uint64_t crank_edges = 0;      ///< crank edges of the selected polarity
  std::uint64_t teeth = 0;            ///< ToothEvents produced
  std::uint64_t synced_teeth = 0;     ///< ... of which while synced
  std::uint64_t cam_edges = 0;        ///< cam edges of the selected polarity
  std::uint64_t noise_edges = 0;      ///< runt edges rejected (earlier than runt_fraction of a pitch)
  std::uint64_t debounced_edges = 0;  ///< tooth edges rejected as glitch pulses (shorter than min_pulse_us)
  std::uint64_t lost_teeth = 0;       ///< teeth interpolated
  std::uint64_t gaps = 0;             ///< gaps seen (syncing and synced)
  std::uint64_t syncs = 0;            ///< times sync was (re)acquired
  std::uint64_t sync_losses = 0;      ///< times sync was lost (stalls excluded)
  std::uint64_t stalls = 0;           ///< stall time-outs
  std::uint64_t cam_phase_errors =
      0;  ///< cam edges outside the window / not in the cam pattern where decoded
  std::uint64_t width_code_errors =
      0;                             ///< pulse-width-coded wheels: tooth whose width bit contradicts the code
  std::uint64_t rejected_edges = 0;  ///< crank edges not used as teeth: noise_edges + debounced_edges
  double cam_angle_deg =
      -1.0;  ///< cam edge angle in the 720° cycle, learned (cam_window_auto) or last measured
  SyncLossReason last_loss_reason = SyncLossReason::kNone;
  std::int64_t last_loss_t_ns = 0;
};

/// Crank decoder: composes the four state machines, each in its own class (io/): EdgeDebounce (glitch
/// pulses), GapSync (sync on missing teeth), PatternSync (sync on a cam pattern or a pulse-width code) and
/// CamPhase (720° phase from the cam); the synced tooth tracking (expected period, lost-tooth recovery) is
/// here. Every sync loss and stall goes through reset_sync().
class CrankDecoder {
 public:
  static constexpr int kMaxGaps = GapSync::kMaxGaps;

  /// Builds the tooth tables. Check valid()/error(): an invalid wheel (no gap, symmetric gaps that cannot
  /// identify the position, angles not increasing) yields a decoder that produces nothing.
  CrankDecoder(const WheelGeometry& wheel, const DecoderParams& params);

  [[nodiscard]] bool valid() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  /// Feed one edge (any channel, any polarity, non-decreasing time). Returns true when `out` holds a tooth
  /// (also while syncing: then out.sync != kSynced and tooth/angle are not meaningful). Real-time safe.
  bool on_edge(const EdgeEvent& edge, ToothEvent& out) noexcept;

  /// Time-out check for live use (no edge for stall_timeout_ns): returns true when the state changed to
  /// kStalled. Real-time safe.
  bool poll(std::int64_t now_ns) noexcept;

  [[nodiscard]] SyncState state() const noexcept { return state_; }
  [[nodiscard]] bool phase_known() const noexcept { return cam_.known(); }
  [[nodiscard]] const DecoderStats& stats() const noexcept { return stats_; }
  [[nodiscard]] int teeth_per_rev() const noexcept { return wheel_.teeth; }
  /// Teeth per 720° cycle (indices of ToothEvent::tooth are 0 .. 2*teeth_per_rev()-1).
  [[nodiscard]] int teeth_per_cycle() const noexcept { return 2 * wheel_.teeth; }
  /// Nominal angle (rad, 0..2π) of tooth i within one revolution.
  [[nodiscard]] double nominal_angle_rad(int i) const noexcept { return wheel_.angle_of(i); }

  /// Per-tooth angle corrections (rad, true edge angle − nominal), either one per tooth of a revolution
  /// (size T) or one per tooth of the 720° cycle (size 2T). Returns false (table unchanged) on a wrong size
  /// or a non-finite value. Not real-time: call between edges from the same thread (no allocation though).
  bool set_tooth_corrections(std::span<const double> rad) noexcept;
  void clear_tooth_corrections() noexcept;

  /// Back to the state of a freshly constructed decoder: kNoSignal, every part reset (debounce, gap and
  /// pattern search, learned cam window), counters zeroed. Keeps what the caller set: the tooth corrections
  /// and the event log. After reset() the same edges give the same tooth events as a new decoder.
  void reset() noexcept;

  /// Sync-state transitions go to `log` (nullptr = none, the default), one DecoderEvent each with its edge
  /// time; another thread drains it (DecoderEventLog::pop) and logs at debug level. The log must outlive the
  /// decoder's use of it. Set before the first edge.
  void set_event_log(DecoderEventLog* log) noexcept { events_ = log; }

 private:
  bool on_crank(std::int64_t t_ns, ToothEvent& out) noexcept;
  bool on_debounced(std::int64_t t_ns, bool active, ToothEvent& out) noexcept;
  bool on_cam_pattern_edge(const EdgeEvent& edge) noexcept;
  void on_cam(std::int64_t t_ns) noexcept;
  bool restart_after_stall(std::int64_t t_ns, ToothEvent& out) noexcept;
  bool gap_syncing_step(std::int64_t t_ns, std::int64_t period_ns, ToothEvent& out) noexcept;
  bool pattern_syncing_step(std::int64_t t_ns, std::int64_t period_ns, ToothEvent& out) noexcept;
  bool synced_step(std::int64_t t_ns, std::int64_t period_ns, ToothEvent& out) noexcept;
  void enter_synced(std::int64_t t_ns, std::int64_t period_ns, int idx, std::uint32_t flags,
                    ToothEvent& out) noexcept;
  void accept_tooth(std::int64_t t_ns, std::int64_t period_ns, int i, double w, int advance, bool gap_tooth,
                    ToothEvent& out) noexcept;
  void reject_noise() noexcept;
  bool suspect_resolves_as_glitch(std::int64_t period_ns) noexcept;
  void hold_rejected(std::int64_t t_ns) noexcept;
  bool retime_last_tooth(std::int64_t t0, std::int64_t t_ns) noexcept;
  [[nodiscard]] bool steady_for_retime(double speed_rpm) const noexcept;
  void arm_retime(std::int64_t t_prev, double u_run) noexcept;
  [[nodiscard]] std::int64_t held_tooth_time(std::int64_t t_ns, double w, double w2,
                                             double u_pred) const noexcept;
  void restart_running_period(std::int64_t t_i, std::int64_t t_ns, double w, double w2) noexcept;
  [[nodiscard]] bool is_synced_noise(std::int64_t period_ns, double u_pred, double q_run) const noexcept;
  [[nodiscard]] bool fits_one_tooth(double q_flat, double trend, double q_run, bool burst) const noexcept;
  [[nodiscard]] std::int64_t period_from_resolved(std::int64_t t_ns, double w, double trend,
                                                  bool burst) const noexcept;
  void lose_sync_on_period(bool gap_tooth, double q, std::int64_t t_ns) noexcept;
  bool emit_lost(std::int64_t t_ns, ToothEvent& out) noexcept;
  /// Synced: the running tooth period (ns/rad), the median of the last three normalised periods (u1_ before
  /// three are known). A glitch accepted as a tooth drags u1_ and the trend; it cannot drag the median.
  [[nodiscard]] double running_u() const noexcept {
    if (u2_ <= 0.0 || u3_ <= 0.0) return u1_;
    return std::max(std::min(u1_, u2_), std::min(std::max(u1_, u2_), u3_));
  }
  void lose_sync(SyncLossReason reason, std::int64_t t_ns) noexcept;
  void reset_sync(SyncState to) noexcept;
  void emit_unsynced(std::int64_t t_ns, SyncState s, ToothEvent& out) noexcept;
  void emit_syncing(std::int64_t t_ns, std::int64_t period_ns, bool tooth_period, ToothEvent& out) noexcept;
  void emit(std::int64_t t_ns, int tooth, double width_rad, std::int64_t period_ns, ToothEvent& out) noexcept;
  void note(DecoderEventKind kind, std::int64_t t_ns, SyncState from, SyncState to, SyncLossReason reason,
            int tooth) noexcept {
    if (events_ != nullptr)
      events_->push(DecoderEvent{t_ns, kind, from, to, static_cast<std::uint8_t>(reason),
                                 static_cast<std::int16_t>(tooth)});
  }

  // Configuration and tables (built once; corrections set by the caller).
  DecoderParams params_;
  bool rising_edge_ = true;  ///< teeth are marked by rising crank edges
  /// Sync on the cam pattern or the width code (PatternSync), else on the gaps (GapSync).
  bool pattern_wheel_ = false;
  std::string error_;
  WheelTables wheel_;
  std::array<double, 2 * kMaxTeeth> corr_{};  ///< angle correction per tooth of 720° (rad)
  // The four state machines.
  EdgeDebounce debounce_;
  GapSync gap_;
  PatternSync pattern_;
  CamPhase cam_;
  // Decoder state and synced tooth tracking.
  SyncState state_ = SyncState::kNoSignal;
  bool have_edge_ = false;
  int rev_ = 0;                  ///< 0 or 1: which revolution of the 720° cycle
  int tooth_ = 0;                ///< index (within revolution) of the last accepted tooth, when synced
  std::int64_t last_t_ns_ = 0;   ///< time of the last accepted crank edge
  std::int64_t period_ns_ = 0;   ///< last accepted period
  double last_width_rad_ = 0.0;  ///< nominal width of the last accepted period (synced)
  double u1_ = 0.0, u2_ = 0.0;   ///< synced: last two periods per radian of true width (ns/rad); 0 = unknown
  double u3_ = 0.0;              ///< synced: the one before u2_ (running_u(); 0 = unknown)
  int burst_teeth_ = 0;    ///< synced: teeth still judged as in a noise burst (a noise edge was rejected)
  int lost_this_rev_ = 0;  ///< synced: teeth interpolated in this revolution
  /// Synced: the last tooth came early against both the running period and the trend (a glitch standing in?):
  /// its period (0 = none), width, and the trend-predicted and running periods per radian before it.
  std::int64_t suspect_period_ns_ = 0;
  double suspect_w_ = 0.0, suspect_u_ = 0.0, suspect_u_run_ = 0.0;
  /// Synced: time of the tooth edge after a suspect resolved as a glitch (rejected as noise, the glitch keeps
  /// its index), until the next tooth is accepted (0 = none): that tooth's period may be timed from it.
  std::int64_t resolved_t_ns_ = 0;
  /// Synced: time of the tooth before the last one (0 = the last tooth cannot be retimed) and the running
  /// period per radian before the last tooth (retime_last_tooth()).
  std::int64_t retime_t0_ns_ = 0;
  double retime_u_ = 0.0;
  /// Synced, in a burst: times of the edges rejected as noise since the last accepted tooth (the latest
  /// kHeld; a true tooth among them is found at the next edge, held_tooth_time()).
  static constexpr int kHeld = 4;
  std::array<std::int64_t, kHeld> held_t_ns_{};
  int held_n_ = 0;
  std::uint32_t pending_flags_ = 0;  ///< ToothEvent::events for the next tooth event
  DecoderStats stats_;
  DecoderEventLog* events_ = nullptr;
};

}  // namespace torqued
