// Crank decoder gap sync. See gap_sync.hpp; comments here explain the why.
#include "gap_sync.hpp"

#include <algorithm>
#include <cmath>

#include "crank_decoder.hpp"

namespace torqued {

std::string GapSync::find_gaps(const WheelTables& w) {
  // A gap is a period clearly longer than the pitch (1.5x: halfway between one and two pitches).
  min_gap_ratio_ = 1e9;
  for (int i = 0; i < w.teeth; ++i) {
    const double ratio = w.width_of(i) / w.pitch_rad;
    if (ratio > 1.5) {
      if (num_gaps_ == kMaxGaps) return "wheel: more than " + std::to_string(kMaxGaps) + " gaps";
      gap_tooth_[static_cast<std::size_t>(num_gaps_++)] = i;
      min_gap_ratio_ = std::min(min_gap_ratio_, ratio);
    }
  }
  return {};
}

std::string GapSync::init_identification(const WheelTables& w, const DecoderParams& p) {
  if (num_gaps_ == 0) return "wheel: no gap (missing tooth) to sync on";
  const int t = w.teeth;
  teeth_ = t;
  for (int j = 0; j < num_gaps_; ++j) {
    const int prev = gap_tooth_[static_cast<std::size_t>((j + num_gaps_ - 1) % num_gaps_)];
    const int d = (gap_tooth_[static_cast<std::size_t>(j)] - prev + t) % t;
    gap_count_[static_cast<std::size_t>(j)] = d == 0 ? t : d;
    max_count_ = std::max(max_count_, gap_count_[static_cast<std::size_t>(j)]);
  }
  // Longest run of consecutive gap periods the wheel has (36-2-2-2: a gap, one tooth, a gap = two in a row).
  max_gap_run_ = 1;
  for (int j = 0, run = 0; j < 2 * num_gaps_; ++j) {
    run = gap_count_[static_cast<std::size_t>(j % num_gaps_)] == 1 ? run + 1 : 0;
    max_gap_run_ = std::min(num_gaps_, std::max(max_gap_run_, run + 1));
  }
  // Gap candidate threshold: gap_ratio_min x the smallest gap, but never below the geometric midpoint between
  // a tooth (1) and that gap (on 36-1 a cranking period may grow 30 % from one tooth to the next).
  gap_threshold_ = std::max(p.gap_ratio_min * min_gap_ratio_, std::sqrt(min_gap_ratio_));
  if (gap_threshold_ <= 1.05) return "decoder: the gap threshold must exceed 1.05 to tell a gap from a tooth";
  // Smallest history of gap-to-gap tooth counts that identifies the gap uniquely.
  history_needed_ = shortest_identifying_window(std::span<const int>(gap_count_.data(), num_gaps_));
  if (history_needed_ == 0)
    return "wheel: gap pattern is rotationally symmetric; the position cannot be identified";
  return {};
}

void GapSync::reset(bool after_loss) noexcept {
  after_loss_ = after_loss;
  ref_period_ns_ = 0;
  ref_prev_ns_ = 0;
  ref_provisional_ = false;
  since_gap_ = -1;
  hist_len_ = 0;
  normal_run_ = 0;
  gap_run_ = 0;
  post_gap_ns_ = 0;
  post_len_ = 0;
  identified_after_ = 0;
}

void GapSync::restart_reference(std::int64_t period_ns) noexcept {
  since_gap_ = -1;
  hist_len_ = 0;
  ref_prev_ns_ = 0;
  ref_period_ns_ = period_ns;
}

GapSync::Step GapSync::on_period(std::int64_t period, const WheelTables& w, const DecoderParams& p,
                                 DecoderStats& stats) noexcept {
  const bool pending = post_gap_ns_ > 0;
  identified_after_ = 0;
  post_started_ = false;
  const Step step = classify(period, w, p, stats);
  if (!pending || post_started_ || step == Step::kIdentified) {
    if (step == Step::kIdentified) post_gap_ns_ = 0;
    return step;
  }
  return on_post_gap_period(period, step, w, p);
}

// After a sync loss the gap right after a burst may have too few clean teeth before it (run_fits_gap fails).
// It is then judged by the kResyncRunBeforeGap periods after it, with the same steadiness test: the decoder
// syncs a few teeth after that gap instead of waiting a revolution for the next one. Any noise edge or gap
// edge drops it; any other period counts (a glitch-shortened reference may make the teeth after the gap look
// like gaps to the search; the steadiness test judges them) unless it is a new candidate, which starts its
// own wait.
GapSync::Step GapSync::on_post_gap_period(std::int64_t period, Step step, const WheelTables& w,
                                          const DecoderParams& p) noexcept {
  const double nominal = w.width_of(gap_tooth_[0]) / w.pitch_rad;
  if (step == Step::kNoise) {
    // Runt against the search's reference; the reference may be the gap itself (rebuilt from it). A period
    // of at least runt_fraction of the gap's pitch is a tooth: it rebuilds the reference and counts.
    if (static_cast<double>(period) < p.runt_fraction * static_cast<double>(post_gap_ns_) / nominal) {
      post_gap_ns_ = 0;
      return step;
    }
    ref_period_ns_ = period;
    ref_prev_ns_ = 0;
    ref_provisional_ = false;
    step = Step::kOther;
  }
  post_[static_cast<std::size_t>(post_len_++)] = period;
  if (post_len_ < kResyncRunBeforeGap) return step;
  const double gap_over_pitch = static_cast<double>(post_gap_ns_) / nominal;
  post_gap_ns_ = 0;
  if (!steady_run_fits(post_, gap_over_pitch, p)) return step;
  match_ = 0;
  identified_after_ = kResyncRunBeforeGap;
  return Step::kIdentified;
}

GapSync::Step GapSync::classify(std::int64_t period, const WheelTables& w, const DecoderParams& p,
                                DecoderStats& stats) noexcept {
  bool normal = false;
  if (ref_period_ns_ == 0) {
    // First period after (re)start: it may itself be a gap, so it is only a provisional reference.
    ref_period_ns_ = period;
    ref_prev_ns_ = 0;
    ref_provisional_ = true;
    since_gap_ = -1;
    gap_run_ = 0;
  } else {
    // Predicted normal period: the last one times the trend of the last two (clamped).
    double pred = static_cast<double>(ref_period_ns_);
    if (ref_prev_ns_ > 0)
      pred *=
          clamp_trend(static_cast<double>(ref_period_ns_) / static_cast<double>(ref_prev_ns_), p.max_trend);
    const double r = static_cast<double>(period) / pred;
    const bool provisional = ref_provisional_;
    ref_provisional_ = false;
    if (provisional && r < 1.0 / gap_threshold_) {
      // The provisional reference was a gap: count it, and this (shorter) period is the reference.
      ++stats.gaps;
      ref_prev_ns_ = 0;
      ref_period_ns_ = period;
      since_gap_ = 0;
      normal = true;
    } else if (r < p.syncing_runt_fraction) {
      return Step::kNoise;
    } else if (r >= gap_threshold_) {
      if (on_gap_candidate(period, r, w, p, stats) == Step::kIdentified) return Step::kIdentified;
    } else {
      normal = true;
      gap_run_ = 0;
      ref_prev_ns_ = ref_period_ns_;
      ref_period_ns_ = period;
    }
  }
  if (normal) run_[static_cast<std::size_t>(normal_run_ % kResyncRunBeforeGap)] = period;
  normal_run_ = normal ? normal_run_ + 1 : 0;
  if (normal && since_gap_ >= 0 && ++since_gap_ > max_count_ + 1) {
    // No gap where one had to be: the last candidate was not a gap.
    since_gap_ = -1;
    hist_len_ = 0;
  }
  return normal ? Step::kNormal : Step::kOther;
}

// The period is a gap candidate (r = period / predicted tooth period). kIdentified when the gap identifies
// the wheel's position, else kOther.
GapSync::Step GapSync::on_gap_candidate(std::int64_t period, double r, const WheelTables& w,
                                        const DecoderParams& p, DecoderStats& stats) noexcept {
  if (after_loss_ && num_gaps_ == 1 && 2 * period > post_gap_ns_) {
    // A candidate to confirm by the run after it unless identified now (also when the reference is rebuilt
    // below: a glitch-shortened reference makes the true gap look far too long or one gap too many). A tooth
    // after a waiting gap may look like a gap to the search when the reference was glitch-shortened: it does
    // not replace the waiting one unless it is more than half as long.
    post_gap_ns_ = period;
    post_len_ = 0;
    post_started_ = true;
  }
  if (r > p.gap_ratio_max * (w.width_of(gap_tooth_[0]) / w.pitch_rad) * 4.0) {
    restart_reference(period);  // far too slow for any gap: speed collapsed; start over from this period
    return Step::kOther;
  }
  if (++gap_run_ > max_gap_run_) {
    // More gaps in a row than the wheel has: the reference is no tooth period (the rest of a glitch's period
    // after a sync loss); rebuild it from this period.
    gap_run_ = 0;
    restart_reference(period);
    return Step::kOther;
  }
  ++stats.gaps;
  ref_prev_ns_ = 0;  // the trend does not carry across a gap
  const int run_before_gap = normal_run_;
  normal_run_after_gap_check_ = normal_run_;
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
  // the first one; multi-gap wheels need the tooth counts between their last gaps. Without a previous gap
  // the teeth counted before this one must fit (half a revolution at least, no more than a revolution), else
  // noise would sync on any long period.
  // After a sync loss the signal has been seen to be this wheel: a gap with kResyncRunBeforeGap clean teeth
  // before it identifies the position again, whatever counts the noise left in the history (a burst just
  // before a gap would otherwise cost a revolution, and miscounted gap-to-gap counts would keep matching
  // from ever succeeding). Nor does the run's length bound it from above: a run longer than a revolution
  // means the search missed a gap while the burst still set its reference (a glitch inside the gap split it
  // in two; or a glitch period and the true tooth after it made a trend that a cranking compression had
  // clamped at max_trend, and the true gap came under gap_threshold_ of it: counted as a tooth period). That
  // is the burst's state, not this candidate's; run_fits_gap judges the candidate by its own clean run.
  const bool single_ok =
      num_gaps_ == 1 &&
      (after_loss_ ? run_before_gap >= std::min(w.teeth / 2, kResyncRunBeforeGap)
                   : hist_len_ == 0 && run_before_gap >= w.teeth / 2 && run_before_gap < w.teeth);
  const int need = single_ok ? 0 : history_needed_;
  if (hist_len_ < need) return Step::kOther;
  match_ = match_gap(need, r, w, p);
  if (match_ < 0) return Step::kOther;
  // Resyncing (noise just cost the sync): inside a burst a glitch can shorten the reference period so that a
  // normal tooth period looks like the gap. The clean run before the gap must be one steady tooth period and
  // the gap must be the matched gap's width in units of it (not of the last period alone).
  if (after_loss_ &&
      !run_fits_gap(static_cast<double>(period) /
                        (w.width_of(gap_tooth_[static_cast<std::size_t>(match_)]) / w.pitch_rad),
                    p))
    return Step::kOther;
  return Step::kIdentified;
}

// The unbroken run of normal periods just before the gap candidate is at least kResyncRunBeforeGap long, its
// last kResyncRunBeforeGap periods lie within [x, 1/x] of their median (x = burst_tooth_ratio_min), and
// gap_over_pitch (the gap period divided by its nominal width in pitches) is within [x, 1/x] of that median
// (steady_run_fits). gap_ratio_min/max are not used here: match_gap applies them to r (gap period over the
// reference period) against the gap's nominal width.
bool GapSync::run_fits_gap(double gap_over_pitch, const DecoderParams& p) const noexcept {
  if (normal_run_after_gap_check_ < kResyncRunBeforeGap) return false;
  return steady_run_fits(run_, gap_over_pitch, p);
}

// The periods v lie within [x, 1/x] of their median (x = burst_tooth_ratio_min) and gap_over_pitch is within
// [x, 1/x] of that median.
bool GapSync::steady_run_fits(std::array<std::int64_t, kResyncRunBeforeGap> v, double gap_over_pitch,
                              const DecoderParams& p) noexcept {
  std::sort(v.begin(), v.end());
  const double med = 0.5 * static_cast<double>(v[(v.size() - 1) / 2] + v[v.size() / 2]);
  const double x = p.burst_tooth_ratio_min;
  if (static_cast<double>(v.front()) < x * med || static_cast<double>(v.back()) * x > med) return false;
  const double g = gap_over_pitch / med;
  return g >= x && g * x <= 1.0;
}

// The one gap of the wheel whose recent history (need counts) and nominal ratio fit; -1 if none or several.
int GapSync::match_gap(int need, double r, const WheelTables& w, const DecoderParams& p) const noexcept {
  int match = -1, matches = 0;
  for (int j = 0; j < num_gaps_; ++j) {
    bool ok = true;
    for (int k = 0; k < need && ok; ++k) {
      ok = hist_[static_cast<std::size_t>(hist_len_ - 1 - k)] ==
           gap_count_[static_cast<std::size_t>((j - k + 2 * num_gaps_) % num_gaps_)];
    }
    const double nominal = w.width_of(gap_tooth_[static_cast<std::size_t>(j)]) / w.pitch_rad;
    ok = ok && r >= p.gap_ratio_min * nominal && r <= p.gap_ratio_max * nominal;
    if (ok) {
      match = j;
      ++matches;
    }
  }
  return matches == 1 ? match : -1;
}

}  // namespace torqued
