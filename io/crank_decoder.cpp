// Crank decoder implementation. See crank_decoder.hpp for the model; comments here explain the why.
#include "crank_decoder.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace torqued {
namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kDegToRad = std::numbers::pi / 180.0;
}  // namespace

const char* to_string(SyncLossReason r) noexcept {
  switch (r) {
    case SyncLossReason::kNone:
      return "none";
    case SyncLossReason::kUnexpectedGap:
      return "unexpected_gap";
    case SyncLossReason::kGapMissing:
      return "gap_missing";
    case SyncLossReason::kTooManyLostTeeth:
      return "too_many_lost_teeth";
    case SyncLossReason::kPeriodTooShort:
      return "period_too_short";
    case SyncLossReason::kStall:
      return "stall";
    case SyncLossReason::kCamPhase:
      return "cam_phase";
    case SyncLossReason::kPattern:
      return "pattern_mismatch";
  }
  return "unknown";
}

const char* to_string(DecoderEventKind k) noexcept {
  switch (k) {
    case DecoderEventKind::kFirstEdge:
      return "first_edge";
    case DecoderEventKind::kSynced:
      return "synced";
    case DecoderEventKind::kLost:
      return "lost_sync";
    case DecoderEventKind::kStalled:
      return "stalled";
    case DecoderEventKind::kCamPhase:
      return "cam_phase_error";
  }
  return "unknown";
}

const char* to_string(SyncState s) noexcept {
  switch (s) {
    case SyncState::kNoSignal:
      return "no_signal";
    case SyncState::kSyncing:
      return "syncing";
    case SyncState::kSynced:
      return "synced";
    case SyncState::kLostSync:
      return "lost_sync";
    case SyncState::kStalled:
      return "stalled";
  }
  return "unknown";
}

CrankDecoder::CrankDecoder(const WheelGeometry& wheel, const DecoderParams& params)
    : params_(params),
      rising_edge_(wheel.rising_edge),
      pattern_wheel_(PatternSync::used(params)),
      debounce_(static_cast<std::int64_t>(std::llround(params.min_pulse_us * 1e3))),
      cam_(params) {
  error_ = build_wheel_tables(wheel, wheel_);
  if (error_.empty()) error_ = gap_.find_gaps(wheel_);
  if (!error_.empty()) return;
  // A cam pattern or a width code gives the position, not the gaps.
  error_ = pattern_wheel_ ? pattern_.init(wheel_, params_) : gap_.init_identification(wheel_, params_);
}

bool CrankDecoder::set_tooth_corrections(std::span<const double> rad) noexcept {
  const auto t = static_cast<std::size_t>(wheel_.teeth);
  if (t == 0 || (rad.size() != t && rad.size() != 2 * t)) return false;
  for (const double v : rad) {
    if (!std::isfinite(v) || std::abs(v) > 0.5 * wheel_.pitch_rad) return false;
  }
  for (std::size_t i = 0; i < 2 * t; ++i) corr_[i] = rad[i % rad.size()];
  return true;
}

void CrankDecoder::clear_tooth_corrections() noexcept { corr_.fill(0.0); }

// Sync lost (lose_sync), stalled (poll, a long period) or reset: the position is unknown, so is the 720°
// phase, and both searches start over (the gap search at the next period, the pattern search at the next
// tooth); the synced speed estimate is dropped (the period that lost sync is no reference).
// Survives a sync loss (reset() alone clears it): the cam window and its learning (cam_window: auto), a
// property of the engine's cam timing rather than of this sync, so the phase comes back at the first cam
// edge after resync; rev_ (meaningless without the phase, which the cam fixes; a gap wheel's resync keeps
// counting revolutions from it); the debounce state (it filters the signal whatever the decoded position);
// the cam edges waiting for the next tooth (they still fall into the next tooth interval); the event flags
// pending for the next tooth event; the counters.
void CrankDecoder::reset_sync(SyncState to) noexcept {
  state_ = to;
  cam_.set_known(false);
  gap_.reset(to == SyncState::kLostSync);
  pattern_.restart();
  u1_ = u2_ = u3_ = 0.0;
  burst_teeth_ = 0;
  suspect_period_ns_ = 0;
  resolved_t_ns_ = 0;
  retime_t0_ns_ = 0;
  held_n_ = 0;
  period_ns_ = 0;
}

void CrankDecoder::reset() noexcept {
  reset_sync(SyncState::kNoSignal);
  debounce_.reset();
  pattern_.reset();
  cam_.reset(params_);
  have_edge_ = false;
  rev_ = 0;
  tooth_ = 0;
  last_t_ns_ = 0;
  last_width_rad_ = 0.0;
  lost_this_rev_ = 0;
  pending_flags_ = 0;
  stats_ = DecoderStats{};
}

bool CrankDecoder::on_edge(const EdgeEvent& edge, ToothEvent& out) noexcept {
  ++stats_.edges;
  if (wheel_.teeth == 0) return false;
  if (edge.channel == params_.crank_channel) {
    const bool active = (edge.level != 0) == rising_edge_;
    if (!active) pattern_.on_opposite_edge(edge.t_ns);
    if (debounce_.enabled()) return on_debounced(edge.t_ns, active, out);
    if (!active) return false;
    ++stats_.crank_edges;
    return on_crank(edge.t_ns, out);
  }
  if (edge.channel == params_.cam_channel && params_.cam_pattern.n > 0) return on_cam_pattern_edge(edge);
  if (edge.channel == params_.cam_channel && (edge.level != 0) == params_.cam_rising) {
    ++stats_.cam_edges;
    if (params_.use_cam) on_cam(edge.t_ns);
  }
  return false;
}

// Cam-synced wheel: the edges of the polarities the pattern lists, placed at the next crank tooth. Not
// inlined, like on_debounced(): both are off the common edge path, and inlined they made on_edge() 4 % slower
// (bench_io BM_DecodeEdges, 117 vs 123 M edges/s).
[[gnu::noinline]] bool CrankDecoder::on_cam_pattern_edge(const EdgeEvent& edge) noexcept {
  bool listed = false;
  for (int j = 0; j < params_.cam_pattern.n; ++j)
    listed = listed || params_.cam_pattern.edges[static_cast<std::size_t>(j)].rising == (edge.level != 0);
  if (!listed || !params_.use_cam) return false;
  ++stats_.cam_edges;
  if (!pattern_.add_cam_edge(edge.t_ns, edge.level != 0))
    ++stats_.cam_phase_errors;  // more cam edges in one tooth interval than any pattern has
  return false;
}

[[gnu::noinline]] bool CrankDecoder::on_debounced(std::int64_t t_ns, bool active, ToothEvent& out) noexcept {
  std::int64_t tooth_t_ns = 0;
  switch (debounce_.on_edge(t_ns, active, tooth_t_ns)) {
    case EdgeDebounce::Result::kGlitch:
      ++stats_.debounced_edges;
      ++stats_.rejected_edges;
      pending_flags_ |= kToothNoiseRejected;
      return false;
    case EdgeDebounce::Result::kTooth:
      ++stats_.crank_edges;
      return on_crank(tooth_t_ns, out);
    case EdgeDebounce::Result::kNone:
      break;
  }
  return false;
}

bool CrankDecoder::poll(std::int64_t now_ns) noexcept {
  if (!have_edge_ || state_ == SyncState::kStalled || state_ == SyncState::kNoSignal) return false;
  if (now_ns - last_t_ns_ <= params_.stall_timeout_ns) return false;
  ++stats_.stalls;
  note(DecoderEventKind::kStalled, now_ns, state_, SyncState::kStalled, SyncLossReason::kStall, -1);
  reset_sync(SyncState::kStalled);
  return true;
}

bool CrankDecoder::on_crank(std::int64_t t_ns, ToothEvent& out) noexcept {
  if (!have_edge_) {
    have_edge_ = true;
    last_t_ns_ = t_ns;
    note(DecoderEventKind::kFirstEdge, t_ns, state_, SyncState::kSyncing, SyncLossReason::kNone, -1);
    state_ = SyncState::kSyncing;
    return false;  // one edge is no period yet
  }
  const std::int64_t period = t_ns - last_t_ns_;
  if (period <= 0) {  // duplicate or backwards timestamp: cannot be a tooth
    reject_noise();
    return false;
  }
  if (period > params_.stall_timeout_ns) return restart_after_stall(t_ns, out);
  if (state_ == SyncState::kStalled) state_ = SyncState::kSyncing;
  if (state_ == SyncState::kSynced) return synced_step(t_ns, period, out);
  return pattern_wheel_ ? pattern_syncing_step(t_ns, period, out) : gap_syncing_step(t_ns, period, out);
}

// Engine stopped (or signal lost) and restarted: begin a new sync from this edge.
bool CrankDecoder::restart_after_stall(std::int64_t t_ns, ToothEvent& out) noexcept {
  if (state_ != SyncState::kStalled) {
    ++stats_.stalls;
    note(DecoderEventKind::kStalled, t_ns, state_, SyncState::kStalled, SyncLossReason::kStall, -1);
  }
  reset_sync(SyncState::kSyncing);
  pattern_.drop_pending_cam();  // cam edges from before the stall belong to no tooth interval
  last_t_ns_ = t_ns;
  emit_unsynced(t_ns, SyncState::kStalled, out);
  return true;
}

void CrankDecoder::reject_noise() noexcept {
  if (state_ == SyncState::kSynced) burst_teeth_ = params_.burst_teeth;
  ++stats_.noise_edges;
  ++stats_.rejected_edges;
  pending_flags_ |= kToothNoiseRejected;
}

bool CrankDecoder::gap_syncing_step(std::int64_t t_ns, std::int64_t period, ToothEvent& out) noexcept {
  state_ = SyncState::kSyncing;
  const GapSync::Step step = gap_.on_period(period, wheel_, params_, stats_);
  if (step == GapSync::Step::kNoise) {
    reject_noise();
    return false;
  }
  if (step == GapSync::Step::kIdentified) {
    const int tooth = gap_.identified_tooth();
    if (gap_.identified_new_rev())
      rev_ ^= 1;  // keep rev_ meaning "revolution of tooth_"; phase from the cam anyway
    enter_synced(t_ns, period, rev_ * wheel_.teeth + tooth, gap_.identified_at_gap() ? kToothGap : 0u, out);
    return true;
  }
  emit_syncing(t_ns, period, step == GapSync::Step::kNormal, out);
  return true;
}

bool CrankDecoder::pattern_syncing_step(std::int64_t t_ns, std::int64_t period, ToothEvent& out) noexcept {
  state_ = SyncState::kSyncing;
  const int idx = pattern_.syncing_step(t_ns, last_t_ns_, period, rev_, wheel_, params_);
  if (idx == PatternSync::kNoise) {
    reject_noise();
    return false;
  }
  if (idx >= 0) {
    cam_.set_known(params_.cam_pattern.n > 0);  // a cam pattern gives the phase too, a width code does not
    enter_synced(t_ns, period, idx, 0u, out);
    return true;
  }
  emit_syncing(t_ns, period, true, out);
  return true;
}

void CrankDecoder::enter_synced(std::int64_t t_ns, std::int64_t period, int idx, std::uint32_t flags,
                                ToothEvent& out) noexcept {
  state_ = SyncState::kSynced;
  ++stats_.syncs;
  lost_this_rev_ = 0;
  tooth_ = idx % wheel_.teeth;
  rev_ = idx / wheel_.teeth;
  note(DecoderEventKind::kSynced, t_ns, SyncState::kSyncing, SyncState::kSynced, SyncLossReason::kNone, idx);
  period_ns_ = period;
  const double w = wheel_.width_of(tooth_);
  last_width_rad_ = w;
  u1_ = static_cast<double>(period) / w;
  u2_ = u3_ = 0.0;
  burst_teeth_ = 0;
  held_n_ = 0;
  suspect_period_ns_ = 0;
  resolved_t_ns_ = 0;
  retime_t0_ns_ = 0;
  last_t_ns_ = t_ns;
  pending_flags_ |= flags | (stats_.syncs > 1 ? kToothResynced : 0u);
  emit(t_ns, idx, w, period, out);
}

// A tooth event with no tooth index (syncing, lost sync, stalled); carries the pending event flags.
void CrankDecoder::emit_unsynced(std::int64_t t_ns, SyncState s, ToothEvent& out) noexcept {
  out = ToothEvent{};
  out.t_ns = out.source_t_ns = t_ns;
  out.tooth = -1;
  out.sync = s;
  out.events = pending_flags_;
  pending_flags_ = 0;
  ++stats_.teeth;
}

// Syncing: a period was accepted; tooth_period = it was a tooth period (one pitch wide), else no width.
void CrankDecoder::emit_syncing(std::int64_t t_ns, std::int64_t period, bool tooth_period,
                                ToothEvent& out) noexcept {
  period_ns_ = period;
  last_t_ns_ = t_ns;
  emit_unsynced(t_ns, SyncState::kSyncing, out);
  out.width_rad = tooth_period ? wheel_.pitch_rad : 0.0;
  out.speed_rad_s = tooth_period ? wheel_.pitch_rad / (static_cast<double>(period) * 1e-9) : 0.0;
}

bool CrankDecoder::synced_step(std::int64_t t_ns, std::int64_t period, ToothEvent& out) noexcept {
  const std::int64_t retime_t0 = retime_t0_ns_;
  retime_t0_ns_ = 0;  // only the first edge after a tooth may retime it
  if (suspect_period_ns_ > 0 && suspect_resolves_as_glitch(period)) return false;
  int i = wheel_.next(tooth_);
  double w = wheel_.width_of(i);
  // Expected period from the last one, scaled by the true widths (constant speed over one tooth), with and
  // without the speed trend of the last two: on real signals the tooth-to-tooth jitter (±20 % on cranking
  // captures) makes the trend alone swing the prediction, so a period fitting either prediction is a tooth.
  const double trend = u2_ > 0.0 ? clamp_trend(u1_ / u2_, params_.max_trend) : 1.0;
  const double q_flat = static_cast<double>(period) / (u1_ * w);
  const double q_trend = q_flat / trend;
  const bool burst = burst_teeth_ > 0;
  const double q_run = static_cast<double>(period) / (running_u() * w);
  if (is_synced_noise(period, u1_ * std::min(trend, 1.0), q_run)) {
    reject_noise();
    if (!retime_last_tooth(retime_t0, t_ns)) hold_rejected(t_ns);
    return false;
  }
  bool normal = fits_one_tooth(q_flat, trend, q_run, burst);
  if (const std::int64_t p = period_from_resolved(t_ns, w, trend, burst); p > 0) {
    normal = true;
    period = p;
  }
  const double q = std::max(q_flat, q_trend) > params_.sync_ratio_max ? std::min(q_flat, q_trend) : q_trend;
  int advance = 1;
  const bool gap_tooth = w > 1.5 * wheel_.pitch_rad;
  const int i2 = wheel_.next(i);
  const double q_lost = (w + wheel_.width_of(i2)) / w;  // q if tooth i was not seen
  // At low speed (cranking, stopping) a period can double from one tooth to the next: then a long period is a
  // slowdown and must not be explained by a lost tooth (that would shift every index after it). A period
  // inside the normal window is never a lost tooth.
  const double speed_rpm = last_width_rad_ / (static_cast<double>(period_ns_) * 1e-9) * (60.0 / kTwoPi);
  // In a noise burst the speed and q come from edges a glitch may have stood in for: no lost-tooth guess,
  // unless an edge rejected in this period was tooth i after all (held_tooth_time: the half-rate lock).
  const double w2 = wheel_.width_of(i2);
  const std::int64_t held_t = burst ? held_tooth_time(t_ns, w, w2, u1_ * std::min(trend, 1.0)) : 0;
  const bool held_tooth = held_t > 0;
  const bool lost_possible = !normal && !burst && speed_rpm >= params_.lost_tooth_min_rpm &&
                             q_lost >= params_.lost_tooth_min_ratio && q > std::sqrt(q_lost) &&
                             q >= q_lost * params_.sync_ratio_min && q <= q_lost * params_.sync_ratio_max;
  if (held_tooth || lost_possible) {
    ++lost_this_rev_;
    ++stats_.lost_teeth;
    if (lost_this_rev_ > params_.max_lost_teeth_per_rev) {
      lose_sync(SyncLossReason::kTooManyLostTeeth, t_ns);
    } else {
      pending_flags_ |= kToothLostRecovered;
      advance = 2;
      w += wheel_.width_of(i2);
      i = i2;
    }
  } else if (!normal) {
    lose_sync_on_period(gap_tooth, q, t_ns);
  }
  if (state_ != SyncState::kSynced) return emit_lost(t_ns, out);
  // A tooth earlier than both the running period and the trend prediction may be a glitch standing in for the
  // tooth it precedes (the first edge of a noise burst, before any edge was early enough to be rejected). It
  // shortens u1_ and the trend, so the true tooth's remainder would pass as the next tooth and shift every
  // index after it. Held as a suspect: the next edge resolves it (suspect_resolves_as_glitch()).
  // Only between one-pitch teeth: next to a gap one tooth more or less is not a factor of two in time.
  const bool suspect = !burst && advance == 1 && u3_ > 0.0 && !gap_tooth &&
                       wheel_.width_of(i2) < 1.5 * wheel_.pitch_rad &&
                       q_run < params_.burst_tooth_ratio_min && q_trend < params_.burst_tooth_ratio_min;
  const double u_pred = u1_ * trend, u_run = running_u();  // expected per radian, from before this tooth
  const double w_i = wheel_.width_of(wheel_.next(tooth_));
  const std::int64_t t_prev = last_t_ns_;
  const bool retimable = advance == 1 && steady_for_retime(speed_rpm);
  accept_tooth(t_ns, period, i, w, advance, gap_tooth, out);
  if (retimable && state_ == SyncState::kSynced) arm_retime(t_prev, u_run);
  if (held_tooth && advance == 2 && state_ == SyncState::kSynced)
    restart_running_period(held_t, t_ns, w_i, w2);
  if (suspect && state_ == SyncState::kSynced) {  // (a pattern check in accept_tooth may have lost sync)
    suspect_u_ = u_pred;
    suspect_u_run_ = u_run;
    suspect_w_ = w;
    suspect_period_ns_ = period;
  }
  return true;
}

// Synced noise: earlier than runt_fraction of a one-pitch period at the slower of the last period and the
// trend prediction (u_pred, per radian; also at a gap: a tooth where the gap should be is a missing gap, not
// noise). In a noise burst (a noise edge rejected within the last burst_teeth teeth) the last period and the
// trend may come from a glitch taken for the tooth it preceded; the running period (median of the last three)
// cannot. There an edge well short of the running period (q_run under burst_tooth_ratio_min: a real tooth
// period does not shorten by a fifth against the three before it while the signal is noisy enough to tell;
// outside bursts the wider runt_fraction / sync_ratio_min windows apply) is a glitch too, and a period that
// fits the running one is a tooth: so no glitch of the burst is counted as one more tooth (that shifted every
// index after it until the next gap, each glitch shortening the prediction for the next).
bool CrankDecoder::is_synced_noise(std::int64_t period, double u_pred, double q_run) const noexcept {
  return static_cast<double>(period) < params_.runt_fraction * u_pred * wheel_.pitch_rad ||
         (burst_teeth_ > 0 && q_run < params_.burst_tooth_ratio_min);
}

// One tooth period: q (period over the expected one) within [sync_ratio_min, sync_ratio_max] against the last
// period, the trend prediction (q_flat / trend) or, in a burst, the running period (q_run).
bool CrankDecoder::fits_one_tooth(double q_flat, double trend, double q_run, bool burst) const noexcept {
  auto in_window = [&](double q) { return q >= params_.sync_ratio_min && q <= params_.sync_ratio_max; };
  return in_window(q_flat) || in_window(q_flat / trend) || (burst && in_window(q_run));
}

// The tooth after one found behind a glitch (suspect_resolves_as_glitch): timed from the glitch, which kept
// the tooth's index, its period is 1 - a pitch too long (a = the glitch's place in the period, 0.56-0.8), so
// a compression right after the glitch (1.3 pitches) went over sync_ratio_max and dropped sync, and the
// tooth's speed was reported 1.2-1.44 times too low. Its period is timed from the found tooth's edge instead
// when that is one tooth period (in the window, fits_one_tooth): returned, 0 = none (the period from
// the glitch stands). A noise test on it as well (is_synced_noise) changed no test and, on a grid of a second
// glitch during an abrupt slow-down, turned 4 quick sync losses into a revolution of wrong indices: not kept.
// The noise checks on the edge itself still time from the glitch: moving the decoder's last edge time there
// (last_t_ns_) moved 34 teeth to a wrong index in DecoderBurstResync (194 against 160: the glitches after it
// were judged against a different edge).
std::int64_t CrankDecoder::period_from_resolved(std::int64_t t_ns, double w, double trend,
                                                bool burst) const noexcept {
  if (resolved_t_ns_ <= 0 || resolved_t_ns_ >= t_ns) return 0;
  const std::int64_t period = t_ns - resolved_t_ns_;
  const auto p = static_cast<double>(period);
  const double q_run = p / (running_u() * w);
  return fits_one_tooth(p / (u1_ * w), trend, q_run, burst) ? period : 0;
}

// A period outside the normal window that no lost tooth explains: too short (a missing gap if tooth i is the
// gap) or too long (a gap where none was expected).
void CrankDecoder::lose_sync_on_period(bool gap_tooth, double q, std::int64_t t_ns) noexcept {
  if (q < params_.sync_ratio_min)
    lose_sync(gap_tooth ? SyncLossReason::kGapMissing : SyncLossReason::kPeriodTooShort, t_ns);
  else
    lose_sync(SyncLossReason::kUnexpectedGap, t_ns);
}

// Report the failing edge; the decoder restarts syncing from here. The failing period (a glitch, a gap where
// none was expected) is no reference (reset_sync dropped it): the next period starts a new one.
bool CrankDecoder::emit_lost(std::int64_t t_ns, ToothEvent& out) noexcept {
  last_t_ns_ = t_ns;
  emit_unsynced(t_ns, SyncState::kLostSync, out);
  return true;
}

// retime_last_tooth()'s gates, checked before the tooth is accepted: the last three periods per radian within
// burst_tooth_ratio_min of each other, and at least lost_tooth_min_rpm.
bool CrankDecoder::steady_for_retime(double speed_rpm) const noexcept {
  return u3_ > 0.0 && speed_rpm >= params_.lost_tooth_min_rpm &&
         std::max({u1_, u2_, u3_}) * params_.burst_tooth_ratio_min <= std::min({u1_, u2_, u3_});
}

void CrankDecoder::arm_retime(std::int64_t t_prev, double u_run) noexcept {
  retime_t0_ns_ = t_prev;
  retime_u_ = u_run;
}

// The first edge after a tooth, rejected as noise: was it the tooth, and the edge accepted before it a glitch
// standing in? At idle a glitch at 0.8-1 of a pitch fits the running period and the true tooth right after it
// is a runt; each later glitch of a dense burst was then judged from the one before it, 0.85 of a pitch apart
// is a tooth again, and one glitch too many ran every index after it one ahead until the gap dropped sync.
// Taken as the tooth's time when the accepted edge came early (its period from the tooth before, t0, under
// the running period before it, retime_u_) and this edge makes that period closer to the running one and
// within [burst_tooth_ratio_min, 1 / burst_tooth_ratio_min] of it. The tooth keeps its index (already
// reported); its period and the next edge's timing restart from this edge, so the glitches after it are
// judged against the true tooth. Armed (retime_t0_ns_) only after a one-tooth step at a steady speed (the
// last three periods per radian within burst_tooth_ratio_min of each other) of at least lost_tooth_min_rpm:
// in cranking, where the period swings by tens of percent from tooth to tooth, the running period is no
// reference for this choice (DecoderBurstResync: 86 wrong indices with both gates, 414 without the speed
// gate, 755 without either, 163 without the steady one). Returns true when retimed.
bool CrankDecoder::retime_last_tooth(std::int64_t t0, std::int64_t t_ns) noexcept {
  if (t0 <= 0 || t0 >= last_t_ns_ || t_ns <= last_t_ns_) return false;
  const double expected = retime_u_ * last_width_rad_;
  const auto dev = [&](std::int64_t p) { return std::abs(std::log(static_cast<double>(p) / expected)); };
  const std::int64_t p_new = t_ns - t0;
  const double r = params_.burst_tooth_ratio_min;
  const double q = static_cast<double>(p_new) / expected;
  const auto p_old = static_cast<double>(last_t_ns_ - t0);
  if (p_old >= expected || q < r || q * r > 1.0 || dev(p_new) >= dev(last_t_ns_ - t0)) return false;
  period_ns_ = p_new;
  u1_ = static_cast<double>(p_new) / last_width_rad_;
  last_t_ns_ = t_ns;
  suspect_period_ns_ = 0;
  resolved_t_ns_ = 0;
  return true;
}

// Synced: keep the latest kHeld edges rejected as noise since the last accepted tooth.
void CrankDecoder::hold_rejected(std::int64_t t_ns) noexcept {
  if (held_n_ == kHeld) {
    std::copy(held_t_ns_.begin() + 1, held_t_ns_.end(), held_t_ns_.begin());
    --held_n_;
  }
  held_t_ns_[static_cast<std::size_t>(held_n_++)] = t_ns;
}

// The half-rate lock: in a burst the running period (median of three) lags a fast speed change (cranking
// accelerates ~10 % per tooth), so a true tooth i can fall under burst_tooth_ratio_min of it and be rejected;
// the next period then spans two teeth, and taken as one it makes every later true tooth a runt against it.
// Tooth i was among the rejected edges if the period from the last tooth to this edge is at least the
// geometric mean of one and two teeth (the lost-tooth rule's sqrt(q_lost)) against both the running period
// and the trend prediction (u_pred), and a rejected edge splits it into two periods per radian within
// [burst_tooth_ratio_min, 1 / burst_tooth_ratio_min] of each other: the same bound on the crank's angular
// acceleration from one tooth to the next that the burst rule applies. A glitch within one tooth period makes
// the whole period about one tooth long, under the geometric mean. Of several such edges, the one splitting
// the period most evenly is the tooth. Returns its time (0 = none).
std::int64_t CrankDecoder::held_tooth_time(std::int64_t t_ns, double w, double w2,
                                           double u_pred) const noexcept {
  if (held_n_ == 0) return 0;
  // After a suspect resolved as a glitch the period starts at the true tooth's edge (resolved_t_ns_), as
  // period_from_resolved times it; an edge held before it splits nothing.
  const std::int64_t t0 = resolved_t_ns_ > 0 && resolved_t_ns_ < t_ns ? resolved_t_ns_ : last_t_ns_;
  const auto total = static_cast<double>(t_ns - t0);
  const double need = std::sqrt((w + w2) / w) * w;
  if (total < need * running_u() || total < need * u_pred) return 0;
  const double r = params_.burst_tooth_ratio_min;
  std::int64_t best = 0;
  double best_dev = std::numeric_limits<double>::infinity();
  for (int k = 0; k < held_n_; ++k) {
    const auto t_h = held_t_ns_[static_cast<std::size_t>(k)];
    if (t_h >= t_ns || t_h <= t0) continue;  // a duplicate timestamp splits nothing
    const double x = (static_cast<double>(t_h - t0) / w) / (static_cast<double>(t_ns - t_h) / w2);
    const double dev = std::abs(std::log(x));
    if (x >= r && x * r <= 1.0 && dev < best_dev) {
      best = t_h;
      best_dev = dev;
    }
  }
  return best;
}

// A held edge was tooth i (held_tooth_time): its two periods are the freshest one-tooth periods there are,
// and they replace the running ones, which lagged the speed change (else the next true tooth is rejected
// against them again and the lock comes back).
void CrankDecoder::restart_running_period(std::int64_t t_i, std::int64_t t_ns, double w, double w2) noexcept {
  u3_ = u2_ = static_cast<double>(t_i - (t_ns - period_ns_)) / w;
  u1_ = static_cast<double>(t_ns - t_i) / w2;
}

// The edge after a suspect tooth: if the two periods together make the one tooth period expected before the
// suspect, both from the last period and trend and from the running period (each within
// [burst_tooth_ratio_min, 1 / burst_tooth_ratio_min]), and this period is clearly shorter than the suspect's
// (under burst_tooth_ratio_min of it: a glitch at 0.56-0.8 of a pitch leaves at most 0.8 of itself, while two
// true teeth of a sudden speed-up are about equal), the suspect was a glitch standing in for this tooth: this
// edge is noise (the suspect keeps the tooth's index) and the tooth's period is restored. The next period is
// timed from this edge when it is one tooth period (resolved_t_ns_, period_from_resolved), not from the
// glitch (2 - a pitches against a one-pitch prediction). Two true teeth take longer. A speed-up
// that halves the period within two teeth (the 36-1 stopping engine at 80 % ripple, out of a compression)
// fits the running period (1.08-1.15) but gives 1.3 times the trend prediction; tooth-to-tooth jitter (real
// cranking captures, +-20 %) can make the trend prediction fit but not the running period (2).
bool CrankDecoder::suspect_resolves_as_glitch(std::int64_t period) noexcept {
  if (suspect_period_ns_ <= 0) return false;
  const std::int64_t suspect = suspect_period_ns_;
  const auto combined = static_cast<double>(period + suspect);
  suspect_period_ns_ = 0;
  const double r = params_.burst_tooth_ratio_min;
  const auto fits = [&](double u) {
    const double q = combined / (u * suspect_w_);
    return q >= r && q * r <= 1.0;
  };
  if (!fits(suspect_u_) || !fits(suspect_u_run_)) return false;
  if (!(static_cast<double>(period) < r * static_cast<double>(suspect))) return false;
  u1_ = combined / suspect_w_;
  resolved_t_ns_ = last_t_ns_ + period;
  reject_noise();
  return true;
}

// Synced: tooth i (advance teeth after the last one; 2 = one lost tooth recovered) closes a period of width
// w.
void CrankDecoder::accept_tooth(std::int64_t t_ns, std::int64_t period, int i, double w, int advance,
                                bool gap_tooth, ToothEvent& out) noexcept {
  // Crossing tooth 0 starts the other revolution of the 720° cycle.
  for (int k = 0, j = tooth_; k < advance; ++k) {
    j = wheel_.next(j);
    if (j == 0) {
      rev_ ^= 1;
      lost_this_rev_ = advance > 1 ? 1 : 0;
    }
  }
  if (gap_tooth || (advance > 1 && wheel_.width_of(i) > 1.5 * wheel_.pitch_rad)) {
    pending_flags_ |= kToothGap;
    ++stats_.gaps;
  }
  tooth_ = i;
  period_ns_ = period;
  last_width_rad_ = w;
  u3_ = u2_;
  u2_ = u1_;
  u1_ = static_cast<double>(period) / w;
  if (burst_teeth_ > 0) --burst_teeth_;
  held_n_ = 0;
  resolved_t_ns_ = 0;
  last_t_ns_ = t_ns;
  const int t = wheel_.teeth;
  const int idx = rev_ * t + i;
  const int prev = (idx - advance + 2 * t) % (2 * t);
  if (pattern_wheel_ && pattern_.check_synced(t_ns, period, prev, idx, advance, wheel_, params_, stats_))
    lose_sync(SyncLossReason::kPattern, t_ns);  // the tooth is still reported, without the phase
  ++stats_.synced_teeth;
  emit(t_ns, idx, w + corr_[static_cast<std::size_t>(idx)] - corr_[static_cast<std::size_t>(prev)], period,
       out);
}

void CrankDecoder::lose_sync(SyncLossReason reason, std::int64_t t_ns) noexcept {
  ++stats_.sync_losses;
  note(DecoderEventKind::kLost, t_ns, state_, SyncState::kLostSync, reason, -1);
  stats_.last_loss_reason = reason;
  stats_.last_loss_t_ns = t_ns;
  reset_sync(SyncState::kLostSync);
}

void CrankDecoder::emit(std::int64_t t_ns, int tooth, double width_rad, std::int64_t period_ns,
                        ToothEvent& out) noexcept {
  const int t = wheel_.teeth;
  out.t_ns = t_ns;
  out.source_t_ns = t_ns;
  out.tooth = tooth;
  out.angle_rad =
      wheel_.angle_of(tooth % t) + (tooth >= t ? kTwoPi : 0.0) + corr_[static_cast<std::size_t>(tooth)];
  out.width_rad = width_rad;
  out.speed_rad_s = width_rad / (static_cast<double>(period_ns) * 1e-9);
  out.sync = SyncState::kSynced;
  out.phase_known = cam_.known();
  out.events = pending_flags_;
  pending_flags_ = 0;
  ++stats_.teeth;
}

// Cam edge (gap-synced wheels): its crank angle in the revolution decides the 720° phase (CamPhase).
void CrankDecoder::on_cam(std::int64_t t_ns) noexcept {
  if (state_ != SyncState::kSynced || period_ns_ <= 0) return;
  // Crank angle of the cam edge within the revolution: last tooth + elapsed time at the last tooth's speed,
  // capped at the next tooth (the cam edge cannot be past a tooth we have not seen yet).
  const double w_next = wheel_.width_of(wheel_.next(tooth_));
  const double dt = static_cast<double>(t_ns - last_t_ns_);
  const double advance = std::min(dt * (last_width_rad_ / static_cast<double>(period_ns_)), w_next);
  const double a_deg = (wheel_.angle_of(tooth_) + advance) / kDegToRad;
  const CamPhase::Result r = cam_.on_edge(a_deg, rev_, params_);
  stats_.cam_angle_deg = cam_.angle_deg();
  if (r == CamPhase::Result::kFlipped) {
    ++stats_.cam_phase_errors;  // phase flipped: trust the cam, flag the next tooth
    note(DecoderEventKind::kCamPhase, t_ns, state_, state_, SyncLossReason::kCamPhase, -1);
    stats_.last_loss_reason = SyncLossReason::kCamPhase;
    stats_.last_loss_t_ns = t_ns;
    pending_flags_ |= kToothResynced;
  } else if (r == CamPhase::Result::kOutside) {
    ++stats_.cam_phase_errors;  // outside the window in both revolutions (or window covers both: ambiguous)
    note(DecoderEventKind::kCamPhase, t_ns, state_, state_, SyncLossReason::kCamPhase, -1);
  }
}

}  // namespace torqued
