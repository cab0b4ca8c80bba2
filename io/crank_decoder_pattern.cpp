// Pattern sync of CrankDecoder: wheels whose crank teeth alone cannot identify the position.
//  - Cam-synced (4G63: 2 crank teeth, Nissan CAS: 12, Miata NB2: 4 at 70°/110°): each cam edge is placed at
//    the crank tooth that follows it, as a fraction of that tooth interval (exact, whatever the speed
//    ripple); the position is the one offset k of the 720° cycle at which every observed cam edge lies on a
//    pattern edge of its polarity, and every pattern edge inside the observed span was observed. Sync (with
//    the 720° phase) as soon as exactly one k fits.
//  - Pulse-width-coded (GM 24x): each tooth period carries one bit (opposite edge in the first or second part
//    of the period); the last code_window_ + 2 bits must match the code at exactly one rotation.
// Synced, every cam edge and width bit is checked against the decoded position: a contradiction is counted
// (cam_phase_errors / width_code_errors) and two in a row lose sync (reason "pattern") and resync.
#include <algorithm>
#include <cmath>

#include "crank_decoder.hpp"

namespace torqued {
namespace {
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

double wrap720(double a) noexcept {
  a = std::fmod(a, 720.0);
  return a < 0.0 ? a + 720.0 : a;
}
double circ_dist720(double a, double b) noexcept {
  const double d = wrap720(a - b);
  return d > 360.0 ? 720.0 - d : d;
}
}  // namespace

std::string CrankDecoder::check_pattern() noexcept {
  const CamPattern& cp = params_.cam_pattern;
  if (cp.n > 0) {
    if (cp.n > CamPattern::kMaxEdges) return "cam pattern: more than 8 edges";
    if (!(cp.tolerance_deg > 0.0 && cp.tolerance_deg < 90.0))
      return "cam pattern: tolerance must be in (0, 90) deg";
    for (int j = 0; j < cp.n; ++j) {
      const double a = cp.edges[static_cast<std::size_t>(j)].angle_deg;
      if (!(a >= 0.0 && a < 720.0)) return "cam pattern: edge angles must lie in [0, 720)";
    }
  }
  if (params_.width_coded) {
    if (teeth_ > 32) return "width-coded wheel: at most 32 teeth";
    if (!(params_.width_code_threshold > 0.0 && params_.width_code_threshold < 1.0))
      return "width-coded wheel: threshold must be in (0, 1)";
    // Smallest window of consecutive bits that identifies the rotation.
    for (int len = 1; len <= teeth_ && code_window_ == 0; ++len) {
      bool unique = true;
      for (int a = 0; a < teeth_ && unique; ++a) {
        for (int b = a + 1; b < teeth_ && unique; ++b) {
          bool same = true;
          for (int k = 0; k < len && same; ++k) {
            same = ((params_.width_code >> ((a - k + teeth_) % teeth_)) & 1u) ==
                   ((params_.width_code >> ((b - k + teeth_) % teeth_)) & 1u);
          }
          unique = !same;
        }
      }
      if (unique) code_window_ = len;
    }
    if (code_window_ == 0) return "width-coded wheel: the code is rotationally symmetric";
  }
  return {};
}

double CrankDecoder::cycle_angle_deg(int idx) const noexcept {
  idx %= 2 * teeth_;
  if (idx < 0) idx += 2 * teeth_;
  return angle_[static_cast<std::size_t>(idx % teeth_)] * kRadToDeg + (idx >= teeth_ ? 360.0 : 0.0);
}

bool CrankDecoder::cam_edge_fits(double angle_deg, bool rising, double tol) const noexcept {
  const CamPattern& cp = params_.cam_pattern;
  for (int j = 0; j < cp.n; ++j) {
    const CamEdgeSpec& e = cp.edges[static_cast<std::size_t>(j)];
    if (e.rising == rising && circ_dist720(angle_deg, e.angle_deg) <= tol) return true;
  }
  return false;
}

// Bit of the period ending at t_ns: 1 (narrow) when the opposite edge came before the threshold fraction,
// 0 (wide) after it, -1 when no opposite edge fell inside the period.
int CrankDecoder::width_bit(std::int64_t t_ns) const noexcept {
  if (last_opp_t_ns_ <= last_t_ns_ || last_opp_t_ns_ >= t_ns) return -1;
  const double f = static_cast<double>(last_opp_t_ns_ - last_t_ns_) / static_cast<double>(t_ns - last_t_ns_);
  return f < params_.width_code_threshold ? 1 : 0;
}

// Places the cam edges seen since the previous tooth (counter count_-2) in the interval ending now.
void CrankDecoder::pattern_collect(std::int64_t t_ns) noexcept {
  for (int j = 0; j < cam_pend_n_; ++j) {
    const CamPending& c = cam_pend_[static_cast<std::size_t>(j)];
    if (c.t_ns <= last_t_ns_ || c.t_ns > t_ns) continue;  // before the span started
    if (cam_obs_n_ == kCamRing) {
      for (int k = 1; k < kCamRing; ++k)
        cam_obs_[static_cast<std::size_t>(k - 1)] = cam_obs_[static_cast<std::size_t>(k)];
      --cam_obs_n_;
      span_start_ = static_cast<int>(cam_obs_[0].pos);  // the span may not start before the oldest kept edge
    }
    const double f = static_cast<double>(c.t_ns - last_t_ns_) / static_cast<double>(t_ns - last_t_ns_);
    cam_obs_[static_cast<std::size_t>(cam_obs_n_++)] = CamObs{count_ - 2 + f, c.rising};
  }
  cam_pend_n_ = 0;
  // Keep at most one cycle of observations.
  if (count_ - 1 - span_start_ > 2 * teeth_) {
    span_start_ = count_ - 1 - 2 * teeth_;
    int w = 0;
    for (int j = 0; j < cam_obs_n_; ++j) {
      if (cam_obs_[static_cast<std::size_t>(j)].pos >= span_start_)
        cam_obs_[static_cast<std::size_t>(w++)] = cam_obs_[static_cast<std::size_t>(j)];
    }
    cam_obs_n_ = w;
  }
}

// k: cycle index of tooth counter 0. True when exactly one k fits.
bool CrankDecoder::cam_match(int& k_out) const noexcept {
  const CamPattern& cp = params_.cam_pattern;
  if (cam_obs_n_ == 0) return false;
  const double tol = cp.tolerance_deg;
  int matches = 0;
  for (int k = 0; k < 2 * teeth_; ++k) {
    bool ok = true;
    for (int j = 0; j < cam_obs_n_ && ok; ++j) {
      const CamObs& o = cam_obs_[static_cast<std::size_t>(j)];
      const int n = static_cast<int>(o.pos);
      const double w = width_[static_cast<std::size_t>((k + n + 1) % teeth_)] * kRadToDeg;
      ok = cam_edge_fits(cycle_angle_deg(k + n) + (o.pos - n) * w, o.rising, tol);
    }
    // Completeness: a pattern edge well inside the observed span must have been seen.
    const double a0 = cycle_angle_deg(k + span_start_);
    double span = 0.0;
    for (int n = span_start_ + 1; n < count_; ++n)
      span += width_[static_cast<std::size_t>((k + n) % teeth_)] * kRadToDeg;
    for (int e = 0; e < cp.n && ok; ++e) {
      const CamEdgeSpec& pe = cp.edges[static_cast<std::size_t>(e)];
      const double d = wrap720(pe.angle_deg - a0);
      if (d < tol || d > span - tol) continue;
      bool seen = false;
      for (int j = 0; j < cam_obs_n_ && !seen; ++j) {
        const CamObs& o = cam_obs_[static_cast<std::size_t>(j)];
        const int n = static_cast<int>(o.pos);
        const double w = width_[static_cast<std::size_t>((k + n + 1) % teeth_)] * kRadToDeg;
        seen = o.rising == pe.rising &&
               circ_dist720(cycle_angle_deg(k + n) + (o.pos - n) * w, pe.angle_deg) <= tol;
      }
      ok = seen;
    }
    if (ok) {
      ++matches;
      k_out = k;
    }
  }
  return matches == 1;
}

// k: tooth (within a revolution) of the newest bit. True when exactly one rotation fits.
bool CrankDecoder::width_match(int& k_out) const noexcept {
  const int need = std::min(teeth_, code_window_ + 2);
  if (nbits_ < need) return false;
  int matches = 0;
  for (int k = 0; k < teeth_; ++k) {
    bool ok = true;
    for (int j = 0; j < need && ok; ++j)
      ok = ((bits_ >> j) & 1u) == ((params_.width_code >> ((k - j + teeth_) % teeth_)) & 1u);
    if (ok) {
      ++matches;
      k_out = k;
    }
  }
  return matches == 1;
}

bool CrankDecoder::pattern_syncing_step(std::int64_t t_ns, std::int64_t period, ToothEvent& out) noexcept {
  state_ = SyncState::kSyncing;
  if (pattern_fresh_) {  // the previous accepted tooth is counter 0 of a new search
    pattern_fresh_ = false;
    count_ = 1;
    span_start_ = 0;
    cam_obs_n_ = 0;
    nbits_ = 0;
    bits_ = 0;
    ref_period_ns_ = 0;
  }
  if (ref_period_ns_ > 0 &&
      static_cast<double>(period) < params_.syncing_runt_fraction * static_cast<double>(ref_period_ns_)) {
    ++stats_.noise_edges;
    ++stats_.rejected_edges;
    pending_flags_ |= kToothNoiseRejected;
    return false;
  }
  ++count_;
  const int bit = params_.width_coded ? width_bit(t_ns) : 0;
  if (bit < 0) {
    nbits_ = 0;
  } else {
    bits_ = (bits_ << 1) | static_cast<std::uint64_t>(bit);
    nbits_ = std::min(nbits_ + 1, 63);
  }
  if (params_.cam_pattern.n > 0) pattern_collect(t_ns);
  ref_period_ns_ = period;
  int k = 0;
  const bool found = params_.cam_pattern.n > 0 ? cam_match(k) : width_match(k);
  if (found) {
    const int idx = params_.cam_pattern.n > 0 ? (k + count_ - 1) % (2 * teeth_) : rev_ * teeth_ + k;
    pattern_misses_ = 0;
    phase_known_ = params_.cam_pattern.n > 0;
    enter_synced(t_ns, period, idx, 0u, out);
    return true;
  }
  period_ns_ = period;
  last_t_ns_ = t_ns;
  out = ToothEvent{};
  out.t_ns = out.source_t_ns = t_ns;
  out.tooth = -1;
  out.width_rad = pitch_rad_;
  out.speed_rad_s = pitch_rad_ / (static_cast<double>(period) * 1e-9);
  out.sync = SyncState::kSyncing;
  out.events = pending_flags_;
  pending_flags_ = 0;
  ++stats_.teeth;
  return true;
}

// Synced: the width bit of the period ending at tooth idx, and every cam edge since the previous tooth, must
// agree with the decoded position.
void CrankDecoder::pattern_check_synced(std::int64_t t_ns, int prev_idx, int idx, int advance) noexcept {
  const std::int64_t t_prev = t_ns - period_ns_;
  bool miss = false;
  if (params_.width_coded && advance == 1 && last_opp_t_ns_ > t_prev && last_opp_t_ns_ < t_ns) {
    const double f = static_cast<double>(last_opp_t_ns_ - t_prev) / static_cast<double>(period_ns_);
    const std::uint32_t bit = f < params_.width_code_threshold ? 1u : 0u;
    if (bit != ((params_.width_code >> (idx % teeth_)) & 1u)) {
      ++stats_.width_code_errors;
      miss = true;
    }
  }
  if (params_.cam_pattern.n > 0) {
    const double a0 = cycle_angle_deg(prev_idx);
    double span = 0.0;
    for (int j = 1; j <= advance; ++j)
      span += width_[static_cast<std::size_t>((prev_idx + j) % teeth_)] * kRadToDeg;
    for (int j = 0; j < cam_pend_n_; ++j) {
      const CamPending& c = cam_pend_[static_cast<std::size_t>(j)];
      if (c.t_ns <= t_prev || c.t_ns > t_ns) continue;
      const double f = static_cast<double>(c.t_ns - t_prev) / static_cast<double>(period_ns_);
      if (!cam_edge_fits(a0 + f * span, c.rising, 1.5 * params_.cam_pattern.tolerance_deg)) {
        ++stats_.cam_phase_errors;
        miss = true;
      }
    }
    cam_pend_n_ = 0;
  }
  pattern_misses_ = miss ? pattern_misses_ + 1 : 0;
  if (pattern_misses_ >= 2) {
    pattern_misses_ = 0;
    lose_sync(SyncLossReason::kPattern, t_ns);
  }
}

}  // namespace torqued
