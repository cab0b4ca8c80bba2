// Crank decoder implementation. See crank_decoder.hpp for the model; comments here explain the why.
#include "crank_decoder.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {
namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kDegToRad = std::numbers::pi / 180.0;

bool in_window_deg(double pos_deg, double start_deg, double end_deg) noexcept {
  pos_deg = std::fmod(pos_deg, 720.0);
  if (pos_deg < 0.0) pos_deg += 720.0;
  if (start_deg <= end_deg) return pos_deg >= start_deg && pos_deg < end_deg;
  return pos_deg >= start_deg || pos_deg < end_deg;  // window wraps through 720°/0°
}
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
    : wheel_(wheel), params_(params) {
  min_pulse_ns_ = static_cast<std::int64_t>(std::llround(params.min_pulse_us * 1e3));
  cam_win_start_ = params.cam_window_start_deg;
  cam_win_end_ = params.cam_window_end_deg;
  error_ = init_angles();
  if (error_.empty()) error_ = init_gaps();
  if (!error_.empty()) return;
  if (pattern_sync()) {  // the cam pattern or the width code gives the position, not the gaps
    error_ = check_pattern();
    return;
  }
  if (num_gaps_ == 0) {
    error_ = "wheel: no gap (missing tooth) to sync on";
    return;
  }
  error_ = init_gap_identification();
}

// Tooth count and nominal tooth angles (listed, or N-M with equal pitch).
std::string CrankDecoder::init_angles() {
  const int t = wheel_.teeth();
  if (t < 2 || t > kMaxTeeth)
    return "wheel: tooth count " + std::to_string(t) + " outside 2.." + std::to_string(kMaxTeeth);
  teeth_ = t;
  if (wheel_.tooth_count > 0) {
    for (int i = 0; i < t; ++i) {
      const double a = wheel_.tooth_angles_deg[static_cast<std::size_t>(i)];
      if (!(a >= 0.0 && a < 360.0) ||
          (i > 0 && !(a > wheel_.tooth_angles_deg[static_cast<std::size_t>(i - 1)]))) {
        return "wheel: tooth_angles_deg must be strictly increasing in [0, 360); entry " + std::to_string(i) +
               " is " + std::to_string(a);
      }
      angle_[static_cast<std::size_t>(i)] = a * kDegToRad;
    }
    return {};
  }
  if (wheel_.positions < 2 || wheel_.missing < 1 || wheel_.missing >= wheel_.positions)
    return "wheel: need positions >= 2 and 1 <= missing < positions (a gap is required for sync)";
  for (int i = 0; i < t; ++i) angle_[static_cast<std::size_t>(i)] = kTwoPi * i / wheel_.positions;
  return {};
}

// Period widths, the pitch (smallest width) and the gap teeth.
std::string CrankDecoder::init_gaps() {
  const int t = teeth_;
  pitch_rad_ = kTwoPi;
  for (int i = 0; i < t; ++i) {
    const double prev =
        i == 0 ? angle_[static_cast<std::size_t>(t - 1)] - kTwoPi : angle_[static_cast<std::size_t>(i - 1)];
    width_[static_cast<std::size_t>(i)] = angle_[static_cast<std::size_t>(i)] - prev;
    pitch_rad_ = std::min(pitch_rad_, width_[static_cast<std::size_t>(i)]);
  }
  // A gap is a period clearly longer than the pitch (1.5x: halfway between one and two pitches).
  min_gap_ratio_ = 1e9;
  for (int i = 0; i < t; ++i) {
    const double ratio = width_[static_cast<std::size_t>(i)] / pitch_rad_;
    if (ratio > 1.5) {
      if (num_gaps_ == kMaxGaps) return "wheel: more than " + std::to_string(kMaxGaps) + " gaps";
      gap_tooth_[static_cast<std::size_t>(num_gaps_++)] = i;
      min_gap_ratio_ = std::min(min_gap_ratio_, ratio);
    }
  }
  return {};
}

// Gap-synced wheels: tooth counts between gaps, the gap threshold and the history that identifies a gap.
std::string CrankDecoder::init_gap_identification() {
  const int t = teeth_;
  for (int j = 0; j < num_gaps_; ++j) {
    const int prev = gap_tooth_[static_cast<std::size_t>((j + num_gaps_ - 1) % num_gaps_)];
    const int d = (gap_tooth_[static_cast<std::size_t>(j)] - prev + t) % t;
    gap_count_[static_cast<std::size_t>(j)] = d == 0 ? t : d;
  }
  // Longest run of consecutive gap periods the wheel has (36-2-2-2: a gap, one tooth, a gap = two in a row).
  max_gap_run_ = 1;
  for (int j = 0, run = 0; j < 2 * num_gaps_; ++j) {
    run = gap_count_[static_cast<std::size_t>(j % num_gaps_)] == 1 ? run + 1 : 0;
    max_gap_run_ = std::min(num_gaps_, std::max(max_gap_run_, run + 1));
  }
  // Gap candidate threshold: gap_ratio_min x the smallest gap, but never below the geometric midpoint between
  // a tooth (1) and that gap (on 36-1 a cranking period may grow 30 % from one tooth to the next).
  gap_threshold_ = std::max(params_.gap_ratio_min * min_gap_ratio_, std::sqrt(min_gap_ratio_));
  if (gap_threshold_ <= 1.05) return "decoder: the gap threshold must exceed 1.05 to tell a gap from a tooth";
  history_needed_ = gap_history_needed();
  if (history_needed_ == 0)
    return "wheel: gap pattern is rotationally symmetric; the position cannot be identified";
  return {};
}

// Smallest history of gap-to-gap tooth counts that identifies the gap uniquely (0: none does).
int CrankDecoder::gap_history_needed() const noexcept {
  for (int len = 1; len <= num_gaps_; ++len) {
    bool unique = true;
    for (int a = 0; a < num_gaps_ && unique; ++a) {
      for (int b = a + 1; b < num_gaps_ && unique; ++b) {
        bool same = true;
        for (int k = 0; k < len && same; ++k) {
          same = gap_count_[static_cast<std::size_t>((a - k + 2 * num_gaps_) % num_gaps_)] ==
                 gap_count_[static_cast<std::size_t>((b - k + 2 * num_gaps_) % num_gaps_)];
        }
        if (same) unique = false;
      }
    }
    if (unique) return len;
  }
  return 0;
}

bool CrankDecoder::set_tooth_corrections(std::span<const double> rad) noexcept {
  const auto t = static_cast<std::size_t>(teeth_);
  if (t == 0 || (rad.size() != t && rad.size() != 2 * t)) return false;
  for (const double v : rad) {
    if (!std::isfinite(v) || std::abs(v) > 0.5 * pitch_rad_) return false;
  }
  for (std::size_t i = 0; i < 2 * t; ++i) corr_[i] = rad[i % rad.size()];
  return true;
}

void CrankDecoder::clear_tooth_corrections() noexcept { corr_.fill(0.0); }

void CrankDecoder::reset() noexcept {
  state_ = SyncState::kNoSignal;
  phase_known_ = false;
  rev_ = 0;
  tooth_ = 0;
  have_edge_ = false;
  period_ns_ = 0;
  ref_period_ns_ = 0;
  ref_prev_ns_ = 0;
  u1_ = u2_ = 0.0;
  since_gap_ = -1;
  hist_len_ = 0;
  normal_run_ = 0;
  lost_this_rev_ = 0;
  pending_flags_ = 0;
  has_pending_ = have_inactive_ = false;
  pattern_fresh_ = true;
}

bool CrankDecoder::on_edge(const EdgeEvent& edge, ToothEvent& out) noexcept {
  ++stats_.edges;
  if (teeth_ == 0) return false;
  if (edge.channel == params_.crank_channel) {
    const bool active = (edge.level != 0) == wheel_.rising_edge;
    if (!active) last_opp_t_ns_ = edge.t_ns;
    if (min_pulse_ns_ > 0) return debounce(edge.t_ns, active, out);
    if (!active) return false;
    ++stats_.crank_edges;
    return on_crank(edge.t_ns, out);
  }
  if (edge.channel == params_.cam_channel && params_.cam_pattern.n > 0) {
    // Cam-synced wheel: the edges of the polarities the pattern lists, placed at the next crank tooth.
    bool listed = false;
    for (int j = 0; j < params_.cam_pattern.n; ++j)
      listed = listed || params_.cam_pattern.edges[static_cast<std::size_t>(j)].rising == (edge.level != 0);
    if (!listed || !params_.use_cam) return false;
    ++stats_.cam_edges;
    if (cam_pend_n_ < static_cast<int>(cam_pend_.size()))
      cam_pend_[static_cast<std::size_t>(cam_pend_n_++)] = CamPending{edge.t_ns, edge.level != 0};
    else
      ++stats_.cam_phase_errors;  // more cam edges in one tooth interval than any pattern has
    return false;
  }
  if (edge.channel == params_.cam_channel && (edge.level != 0) == params_.cam_rising) {
    ++stats_.cam_edges;
    if (params_.use_cam) on_cam(edge.t_ns);
  }
  return false;
}

// Debounce: a tooth edge is held until the opposite crank edge shows the pulse was at least min_pulse wide;
// a narrower pulse (a glitch) is dropped whole, so neither of its edges shifts a tooth time.
bool CrankDecoder::debounce(std::int64_t t_ns, bool active, ToothEvent& out) noexcept {
  if (active) {
    if (have_inactive_ && t_ns - last_inactive_t_ns_ < min_pulse_ns_) {  // end of a narrow gap-glitch
      ++stats_.debounced_edges;
      ++stats_.rejected_edges;
      pending_flags_ |= kToothNoiseRejected;
      return false;
    }
    bool emitted = false;
    if (has_pending_) {  // two tooth edges in a row (opposite edge missing): the older one stands
      ++stats_.crank_edges;
      emitted = on_crank(pending_t_ns_, out);
    }
    has_pending_ = true;
    pending_t_ns_ = t_ns;
    return emitted;
  }
  have_inactive_ = true;
  last_inactive_t_ns_ = t_ns;
  if (!has_pending_) return false;
  has_pending_ = false;
  if (t_ns - pending_t_ns_ < min_pulse_ns_) {
    ++stats_.debounced_edges;
    ++stats_.rejected_edges;
    pending_flags_ |= kToothNoiseRejected;
    return false;
  }
  ++stats_.crank_edges;
  return on_crank(pending_t_ns_, out);
}

bool CrankDecoder::poll(std::int64_t now_ns) noexcept {
  if (!have_edge_ || state_ == SyncState::kStalled || state_ == SyncState::kNoSignal) return false;
  if (now_ns - last_t_ns_ <= params_.stall_timeout_ns) return false;
  ++stats_.stalls;
  note(DecoderEventKind::kStalled, now_ns, state_, SyncState::kStalled, SyncLossReason::kStall, -1);
  state_ = SyncState::kStalled;
  phase_known_ = false;
  since_gap_ = -1;
  hist_len_ = 0;
  ref_period_ns_ = 0;
  ref_prev_ns_ = 0;
  u1_ = u2_ = 0.0;
  period_ns_ = 0;
  pattern_fresh_ = true;
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
    ++stats_.noise_edges;
    ++stats_.rejected_edges;
    pending_flags_ |= kToothNoiseRejected;
    return false;
  }
  if (period > params_.stall_timeout_ns) {
    // Engine stopped (or signal lost) and restarted: begin a new sync from this edge.
    if (state_ != SyncState::kStalled) {
      ++stats_.stalls;
      note(DecoderEventKind::kStalled, t_ns, state_, SyncState::kStalled, SyncLossReason::kStall, -1);
    }
    state_ = SyncState::kSyncing;
    phase_known_ = false;
    since_gap_ = -1;
    hist_len_ = 0;
    ref_period_ns_ = 0;
    ref_prev_ns_ = 0;
    u1_ = u2_ = 0.0;
    ref_provisional_ = false;
    period_ns_ = 0;
    last_t_ns_ = t_ns;
    pattern_fresh_ = true;
    cam_pend_n_ = 0;
    emit_unsynced(t_ns, SyncState::kStalled, out);
    return true;
  }
  if (state_ == SyncState::kStalled) state_ = SyncState::kSyncing;
  if (state_ == SyncState::kSynced) return synced_step(t_ns, period, out);
  return pattern_sync() ? pattern_syncing_step(t_ns, period, out) : syncing_step(t_ns, period, out);
}

bool CrankDecoder::syncing_step(std::int64_t t_ns, std::int64_t period, ToothEvent& out) noexcept {
  state_ = SyncState::kSyncing;
  bool normal = false;
  if (ref_period_ns_ == 0) {
    // First period after (re)start: it may itself be a gap, so it is only a provisional reference.
    ref_period_ns_ = period;
    ref_prev_ns_ = 0;
    ref_provisional_ = true;
    u1_ = u2_ = 0.0;
    since_gap_ = -1;
    gap_run_ = 0;
  } else {
    // Predicted normal period: the last one times the trend of the last two (clamped).
    double pred = static_cast<double>(ref_period_ns_);
    if (ref_prev_ns_ > 0)
      pred *= clamp_trend(static_cast<double>(ref_period_ns_) / static_cast<double>(ref_prev_ns_));
    const double r = static_cast<double>(period) / pred;
    const bool provisional = ref_provisional_;
    ref_provisional_ = false;
    if (provisional && r < 1.0 / gap_threshold_) {
      // The provisional reference was a gap: count it, and this (shorter) period is the reference.
      ++stats_.gaps;
      ref_prev_ns_ = 0;
      ref_period_ns_ = period;
      since_gap_ = 0;
      normal = true;
    } else if (r < params_.syncing_runt_fraction) {
      ++stats_.noise_edges;
      ++stats_.rejected_edges;
      pending_flags_ |= kToothNoiseRejected;
      return false;
    } else if (r >= gap_threshold_) {
      if (syncing_gap(t_ns, period, r, out)) return true;
    } else {
      normal = true;
      gap_run_ = 0;
      ref_prev_ns_ = ref_period_ns_;
      ref_period_ns_ = period;
    }
  }
  normal_run_ = normal ? normal_run_ + 1 : 0;
  if (normal && since_gap_ >= 0) {
    ++since_gap_;
    int max_count = 0;
    for (int j = 0; j < num_gaps_; ++j)
      max_count = std::max(max_count, gap_count_[static_cast<std::size_t>(j)]);
    if (since_gap_ > max_count + 1) {  // no gap where one had to be: the last candidate was not a gap
      since_gap_ = -1;
      hist_len_ = 0;
    }
  }
  period_ns_ = period;
  last_t_ns_ = t_ns;
  emit_unsynced(t_ns, SyncState::kSyncing, out);
  out.width_rad = normal ? pitch_rad_ : 0.0;
  out.speed_rad_s = normal ? pitch_rad_ / (static_cast<double>(period) * 1e-9) : 0.0;
  return true;
}

// Syncing: the period is a gap candidate (r = period / predicted tooth period). Returns true when the gap
// identifies the wheel's position: the decoder is synced and `out` holds the gap tooth.
bool CrankDecoder::syncing_gap(std::int64_t t_ns, std::int64_t period, double r, ToothEvent& out) noexcept {
  if (r > params_.gap_ratio_max * (width_[static_cast<std::size_t>(gap_tooth_[0])] / pitch_rad_) * 4.0) {
    restart_reference(period);  // far too slow for any gap: speed collapsed; start over from this period
    return false;
  }
  if (++gap_run_ > max_gap_run_) {
    // More gaps in a row than the wheel has: the reference is no tooth period (the rest of a glitch's
    // period after a sync loss); rebuild it from this period.
    gap_run_ = 0;
    restart_reference(period);
    return false;
  }
  ++stats_.gaps;
  ref_prev_ns_ = 0;  // the trend does not carry across a gap
  const int run_before_gap = normal_run_;
  normal_run_ = 0;
  if (since_gap_ >= 0) {
    if (hist_len_ == kMaxGaps) {
      std::copy(hist_.begin() + 1, hist_.end(), hist_.begin());
      --hist_len_;
    }
    hist_[static_cast<std::size_t>(hist_len_++)] = since_gap_ + 1;
  }
  since_gap_ = 0;
  // Plausibility: the recent gap-to-gap tooth counts must match exactly one position of the wheel, and this
  // gap's size must fit that gap's nominal ratio. A single-gap wheel is identified by its gap alone: sync at
  // the first one; multi-gap wheels need the tooth counts between their last gaps. Without a
  // previous gap the teeth counted before this one must fit (half a revolution at least, no more than a
  // revolution), else noise would sync on any long period.
  const bool single_ok =
      num_gaps_ == 1 && hist_len_ == 0 && run_before_gap >= teeth_ / 2 && run_before_gap < teeth_;
  const int need = single_ok ? 0 : history_needed_;
  if (hist_len_ < need) return false;
  const int match = match_gap(need, r);
  if (match < 0) return false;
  sync_at_gap(t_ns, period, match, out);
  return true;
}

// The one gap of the wheel whose recent history (need counts) and nominal ratio fit; -1 if none or several.
int CrankDecoder::match_gap(int need, double r) const noexcept {
  int match = -1, matches = 0;
  for (int j = 0; j < num_gaps_; ++j) {
    bool ok = true;
    for (int k = 0; k < need && ok; ++k) {
      ok = hist_[static_cast<std::size_t>(hist_len_ - 1 - k)] ==
           gap_count_[static_cast<std::size_t>((j - k + 2 * num_gaps_) % num_gaps_)];
    }
    const double nominal =
        width_[static_cast<std::size_t>(gap_tooth_[static_cast<std::size_t>(j)])] / pitch_rad_;
    ok = ok && r >= params_.gap_ratio_min * nominal && r <= params_.gap_ratio_max * nominal;
    if (ok) {
      match = j;
      ++matches;
    }
  }
  return matches == 1 ? match : -1;
}

void CrankDecoder::sync_at_gap(std::int64_t t_ns, std::int64_t period, int match, ToothEvent& out) noexcept {
  int tooth = gap_tooth_[static_cast<std::size_t>(match)];
  if (tooth == 0) rev_ ^= 1;  // keep rev_ meaning "revolution of tooth_"; phase from the cam anyway
  enter_synced(t_ns, period, rev_ * teeth_ + tooth, kToothGap, out);
}

void CrankDecoder::enter_synced(std::int64_t t_ns, std::int64_t period, int idx, std::uint32_t flags,
                                ToothEvent& out) noexcept {
  state_ = SyncState::kSynced;
  ++stats_.syncs;
  lost_this_rev_ = 0;
  tooth_ = idx % teeth_;
  rev_ = idx / teeth_;
  note(DecoderEventKind::kSynced, t_ns, SyncState::kSyncing, SyncState::kSynced, SyncLossReason::kNone, idx);
  period_ns_ = period;
  const double w = width_[static_cast<std::size_t>(tooth_)];
  last_width_rad_ = w;
  u1_ = static_cast<double>(period) / w;
  u2_ = 0.0;
  last_t_ns_ = t_ns;
  pending_flags_ |= flags | (stats_.syncs > 1 ? kToothResynced : 0u);
  emit(t_ns, idx, w, period, out);
}

void CrankDecoder::restart_reference(std::int64_t period) noexcept {
  since_gap_ = -1;
  hist_len_ = 0;
  ref_prev_ns_ = 0;
  ref_period_ns_ = period;
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

bool CrankDecoder::synced_step(std::int64_t t_ns, std::int64_t period, ToothEvent& out) noexcept {
  int i = next_tooth(tooth_);
  double w = width_[static_cast<std::size_t>(i)];
  // Expected period from the last one, scaled by the true widths (constant speed over one tooth), with and
  // without the speed trend of the last two: on real signals the tooth-to-tooth jitter (±20 % on cranking
  // captures) makes the trend alone swing the prediction, so a period fitting either prediction is a tooth.
  const double trend = u2_ > 0.0 ? clamp_trend(u1_ / u2_) : 1.0;
  const double q_flat = static_cast<double>(period) / (u1_ * w);
  const double q_trend = q_flat / trend;
  // Noise: earlier than runt_fraction of a one-pitch period (also at a gap: a tooth where the gap should be
  // is a missing gap, not noise).
  if (static_cast<double>(period) < params_.runt_fraction * u1_ * pitch_rad_ * std::min(trend, 1.0)) {
    ++stats_.noise_edges;
    ++stats_.rejected_edges;
    pending_flags_ |= kToothNoiseRejected;
    return false;
  }
  auto in_window = [&](double q) { return q >= params_.sync_ratio_min && q <= params_.sync_ratio_max; };
  const bool normal = in_window(q_flat) || in_window(q_trend);
  const double q = std::max(q_flat, q_trend) > params_.sync_ratio_max ? std::min(q_flat, q_trend) : q_trend;
  int advance = 1;
  const bool gap_tooth = w > 1.5 * pitch_rad_;
  const int i2 = next_tooth(i);
  const double q_lost = (w + width_[static_cast<std::size_t>(i2)]) / w;  // q if tooth i was not seen
  // At low speed (cranking, stopping) a period can double from one tooth to the next: then a long period is a
  // slowdown and must not be explained by a lost tooth (that would shift every index after it). A period
  // inside the normal window is never a lost tooth.
  const double speed_rpm = last_width_rad_ / (static_cast<double>(period_ns_) * 1e-9) * (60.0 / kTwoPi);
  const bool lost_possible = !normal && speed_rpm >= params_.lost_tooth_min_rpm &&
                             q_lost >= params_.lost_tooth_min_ratio && q > std::sqrt(q_lost) &&
                             q >= q_lost * params_.sync_ratio_min && q <= q_lost * params_.sync_ratio_max;
  if (lost_possible) {
    ++lost_this_rev_;
    ++stats_.lost_teeth;
    if (lost_this_rev_ > params_.max_lost_teeth_per_rev) {
      lose_sync(SyncLossReason::kTooManyLostTeeth, t_ns);
    } else {
      pending_flags_ |= kToothLostRecovered;
      advance = 2;
      w += width_[static_cast<std::size_t>(i2)];
      i = i2;
    }
  } else if (!normal && q < params_.sync_ratio_min) {
    lose_sync(gap_tooth ? SyncLossReason::kGapMissing : SyncLossReason::kPeriodTooShort, t_ns);
  } else if (!normal) {
    lose_sync(SyncLossReason::kUnexpectedGap, t_ns);
  }
  if (state_ != SyncState::kSynced) {
    // Report the failing edge; the decoder restarts syncing from here. The failing period (a glitch, a gap
    // where none was expected) is no reference: the next period starts a new one.
    ref_period_ns_ = 0;
    ref_prev_ns_ = 0;
    ref_provisional_ = false;
    u1_ = u2_ = 0.0;
    period_ns_ = period;
    last_t_ns_ = t_ns;
    emit_unsynced(t_ns, SyncState::kLostSync, out);
    return true;
  }
  accept_tooth(t_ns, period, i, w, advance, gap_tooth, out);
  return true;
}

// Synced: tooth i (advance teeth after the last one; 2 = one lost tooth recovered) closes a period of width
// w.
void CrankDecoder::accept_tooth(std::int64_t t_ns, std::int64_t period, int i, double w, int advance,
                                bool gap_tooth, ToothEvent& out) noexcept {
  // Crossing tooth 0 starts the other revolution of the 720° cycle.
  for (int k = 0, j = tooth_; k < advance; ++k) {
    j = next_tooth(j);
    if (j == 0) {
      rev_ ^= 1;
      lost_this_rev_ = advance > 1 ? 1 : 0;
    }
  }
  if (gap_tooth || (advance > 1 && width_[static_cast<std::size_t>(i)] > 1.5 * pitch_rad_)) {
    pending_flags_ |= kToothGap;
    ++stats_.gaps;
  }
  tooth_ = i;
  period_ns_ = period;
  last_width_rad_ = w;
  u2_ = u1_;
  u1_ = static_cast<double>(period) / w;
  last_t_ns_ = t_ns;
  const int idx = rev_ * teeth_ + i;
  const int prev = (idx - advance + 2 * teeth_) % (2 * teeth_);
  if (pattern_sync()) pattern_check_synced(t_ns, prev, idx, advance);
  ++stats_.synced_teeth;
  emit(t_ns, idx, w + corr_[static_cast<std::size_t>(idx)] - corr_[static_cast<std::size_t>(prev)], period,
       out);
}

void CrankDecoder::lose_sync(SyncLossReason reason, std::int64_t t_ns) noexcept {
  ++stats_.sync_losses;
  note(DecoderEventKind::kLost, t_ns, state_, SyncState::kLostSync, reason, -1);
  stats_.last_loss_reason = reason;
  stats_.last_loss_t_ns = t_ns;
  state_ = SyncState::kLostSync;
  phase_known_ = false;
  since_gap_ = -1;
  hist_len_ = 0;
  pattern_fresh_ = true;
}

void CrankDecoder::emit(std::int64_t t_ns, int tooth, double width_rad, std::int64_t period_ns,
                        ToothEvent& out) noexcept {
  out.t_ns = t_ns;
  out.source_t_ns = t_ns;
  out.tooth = tooth;
  const int in_rev = tooth % teeth_;
  out.angle_rad = angle_[static_cast<std::size_t>(in_rev)] + (tooth >= teeth_ ? kTwoPi : 0.0) +
                  corr_[static_cast<std::size_t>(tooth)];
  out.width_rad = width_rad;
  out.speed_rad_s = width_rad / (static_cast<double>(period_ns) * 1e-9);
  out.sync = SyncState::kSynced;
  out.phase_known = phase_known_;
  out.events = pending_flags_;
  pending_flags_ = 0;
  ++stats_.teeth;
}

void CrankDecoder::on_cam(std::int64_t t_ns) noexcept {
  if (state_ != SyncState::kSynced || period_ns_ <= 0) return;
  // Crank angle of the cam edge within the revolution: last tooth + elapsed time at the last tooth's speed,
  // capped at the next tooth (the cam edge cannot be past a tooth we have not seen yet).
  const int next = next_tooth(tooth_);
  const double w_next = width_[static_cast<std::size_t>(next)];
  const double dt = static_cast<double>(t_ns - last_t_ns_);
  const double advance = std::min(dt * (last_width_rad_ / static_cast<double>(period_ns_)), w_next);
  const double a_deg = (angle_[static_cast<std::size_t>(tooth_)] + advance) / kDegToRad;
  if (params_.cam_window_auto && !cam_learned_ && !cam_learn_step(a_deg)) return;
  const bool in_this = in_window_deg(a_deg + 360.0 * rev_, cam_win_start_, cam_win_end_);
  const bool in_other = in_window_deg(a_deg + 360.0 * (rev_ ^ 1), cam_win_start_, cam_win_end_);
  if (!params_.cam_window_auto) stats_.cam_angle_deg = a_deg + 360.0 * (in_this ? rev_ : rev_ ^ 1);
  if (in_this && (!in_other || phase_known_)) {
    phase_known_ = true;
    return;
  }
  if (in_other && !in_this) {
    if (phase_known_) {
      ++stats_.cam_phase_errors;  // phase flipped: trust the cam, flag the next tooth
      note(DecoderEventKind::kCamPhase, t_ns, state_, state_, SyncLossReason::kCamPhase, -1);
      stats_.last_loss_reason = SyncLossReason::kCamPhase;
      stats_.last_loss_t_ns = t_ns;
      pending_flags_ |= kToothResynced;
    }
    rev_ ^= 1;
    phase_known_ = true;
    return;
  }
  ++stats_.cam_phase_errors;  // outside the window in both revolutions (or window covers both: ambiguous)
  note(DecoderEventKind::kCamPhase, t_ns, state_, state_, SyncLossReason::kCamPhase, -1);
}

// cam_window: auto. a_deg: the cam edge's angle within the revolution. Returns true once learned (the window
// is then set around the mean angle, in the revolution of the first learning edge = revolution 0).
bool CrankDecoder::cam_learn_step(double a_deg) noexcept {
  double d = std::fmod(a_deg - cam_learn_first_ + 540.0, 360.0) - 180.0;
  if (cam_learn_n_ == 0 || std::abs(d) > params_.cam_auto_spread_deg) {  // (re)start
    cam_learn_n_ = 0;
    cam_learn_first_ = a_deg;
    cam_learn_sum_ = 0.0;
    d = 0.0;
    rev_ = 0;  // this edge's revolution is revolution 0
  }
  cam_learn_sum_ += d;
  if (++cam_learn_n_ < std::max(1, params_.cam_auto_edges)) return false;
  const double a = std::fmod(cam_learn_first_ + cam_learn_sum_ / cam_learn_n_ + 360.0, 360.0);
  cam_learned_ = true;
  stats_.cam_angle_deg = a;
  cam_win_start_ = std::fmod(a - 90.0 + 720.0, 720.0);
  cam_win_end_ = a + 90.0;
  return true;
}

}  // namespace torqued
