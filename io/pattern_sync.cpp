// Crank decoder pattern sync (cam-synced and pulse-width-coded wheels). See pattern_sync.hpp.
#include "pattern_sync.hpp"

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
double cycle_angle_deg(int idx, const WheelTables& w) noexcept {
  idx %= 2 * w.teeth;
  if (idx < 0) idx += 2 * w.teeth;
  return w.angle_of(idx % w.teeth) * kRadToDeg + (idx >= w.teeth ? 360.0 : 0.0);
}
bool cam_edge_fits(double angle_deg, bool rising, double tol, const CamPattern& cp) noexcept {
  for (int j = 0; j < cp.n; ++j) {
    const CamEdgeSpec& e = cp.edges[static_cast<std::size_t>(j)];
    if (e.rising == rising && circ_dist720(angle_deg, e.angle_deg) <= tol) return true;
  }
  return false;
}
}  // namespace

bool PatternSync::used(const DecoderParams& p) noexcept { return p.cam_pattern.n > 0 || p.width_coded; }

std::string PatternSync::init(const WheelTables& w, const DecoderParams& p) {
  const CamPattern& cp = p.cam_pattern;
  if (cp.n > 0) {
    if (cp.n > CamPattern::kMaxEdges) return "cam pattern: more than 8 edges";
    if (!(cp.tolerance_deg > 0.0 && cp.tolerance_deg < 90.0))
      return "cam pattern: tolerance must be in (0, 90) deg";
    for (int j = 0; j < cp.n; ++j) {
      const double a = cp.edges[static_cast<std::size_t>(j)].angle_deg;
      if (!(a >= 0.0 && a < 720.0)) return "cam pattern: edge angles must lie in [0, 720)";
    }
  }
  if (p.width_coded) {
    if (w.teeth > 32) return "width-coded wheel: at most 32 teeth";
    if (!(p.width_code_threshold > 0.0 && p.width_code_threshold < 1.0))
      return "width-coded wheel: threshold must be in (0, 1)";
    // Smallest window of consecutive bits that identifies the rotation.
    std::array<int, 32> bits{};
    for (int i = 0; i < w.teeth; ++i) bits[static_cast<std::size_t>(i)] = (p.width_code >> i) & 1u;
    code_window_ = shortest_identifying_window(std::span<const int>(bits.data(), w.teeth));
    if (code_window_ == 0) return "width-coded wheel: the code is rotationally symmetric";
  }
  return {};
}

void PatternSync::reset() noexcept {
  restart();
  count_ = span_start_ = 0;
  ref_period_ns_ = 0;
  cam_obs_n_ = cam_pend_n_ = 0;
  bits_ = 0;
  nbits_ = 0;
  last_opp_t_ns_ = -1;
}

bool PatternSync::add_cam_edge(std::int64_t t_ns, bool rising) noexcept {
  if (cam_pend_n_ == static_cast<int>(cam_pend_.size())) return false;
  cam_pend_[static_cast<std::size_t>(cam_pend_n_++)] = CamPending{t_ns, rising};
  return true;
}

// Bit of the period ending at t_ns: 1 (narrow) when the opposite edge came before the threshold fraction,
// 0 (wide) after it, -1 when no opposite edge fell inside the period.
int PatternSync::width_bit(std::int64_t t_ns, std::int64_t last_t_ns, const DecoderParams& p) const noexcept {
  if (last_opp_t_ns_ <= last_t_ns || last_opp_t_ns_ >= t_ns) return -1;
  const double f = static_cast<double>(last_opp_t_ns_ - last_t_ns) / static_cast<double>(t_ns - last_t_ns);
  return f < p.width_code_threshold ? 1 : 0;
}

// Places the cam edges seen since the previous tooth (counter count_-2) in the interval ending now.
void PatternSync::collect(std::int64_t t_ns, std::int64_t last_t_ns, const WheelTables& w) noexcept {
  for (int j = 0; j < cam_pend_n_; ++j) {
    const CamPending& c = cam_pend_[static_cast<std::size_t>(j)];
    if (c.t_ns <= last_t_ns || c.t_ns > t_ns) continue;  // before the span started
    if (cam_obs_n_ == kCamRing) {
      for (int k = 1; k < kCamRing; ++k)
        cam_obs_[static_cast<std::size_t>(k - 1)] = cam_obs_[static_cast<std::size_t>(k)];
      --cam_obs_n_;
      span_start_ = static_cast<int>(cam_obs_[0].pos);  // the span may not start before the oldest kept edge
    }
    const double f = static_cast<double>(c.t_ns - last_t_ns) / static_cast<double>(t_ns - last_t_ns);
    cam_obs_[static_cast<std::size_t>(cam_obs_n_++)] = CamObs{count_ - 2 + f, c.rising};
  }
  cam_pend_n_ = 0;
  // Keep at most one cycle of observations.
  if (count_ - 1 - span_start_ > 2 * w.teeth) {
    span_start_ = count_ - 1 - 2 * w.teeth;
    int n = 0;
    for (int j = 0; j < cam_obs_n_; ++j) {
      if (cam_obs_[static_cast<std::size_t>(j)].pos >= span_start_)
        cam_obs_[static_cast<std::size_t>(n++)] = cam_obs_[static_cast<std::size_t>(j)];
    }
    cam_obs_n_ = n;
  }
}

// k: cycle index of tooth counter 0. True when exactly one k fits.
bool PatternSync::cam_match(int& k_out, const WheelTables& w, const DecoderParams& p) const noexcept {
  const CamPattern& cp = p.cam_pattern;
  if (cam_obs_n_ == 0) return false;
  const double tol = cp.tolerance_deg;
  const int t = w.teeth;
  // Angle in the cycle of observation o when tooth counter 0 is cycle index k.
  auto obs_angle = [&](const CamObs& o, int k) {
    const int n = static_cast<int>(o.pos);
    return cycle_angle_deg(k + n, w) + (o.pos - n) * (w.width_of((k + n + 1) % t) * kRadToDeg);
  };
  int matches = 0;
  for (int k = 0; k < 2 * t; ++k) {
    bool ok = true;
    for (int j = 0; j < cam_obs_n_ && ok; ++j) {
      const CamObs& o = cam_obs_[static_cast<std::size_t>(j)];
      ok = cam_edge_fits(obs_angle(o, k), o.rising, tol, cp);
    }
    // Completeness: a pattern edge well inside the observed span must have been seen.
    const double a0 = cycle_angle_deg(k + span_start_, w);
    double span = 0.0;
    for (int n = span_start_ + 1; n < count_; ++n) span += w.width_of((k + n) % t) * kRadToDeg;
    for (int e = 0; e < cp.n && ok; ++e) {
      const CamEdgeSpec& pe = cp.edges[static_cast<std::size_t>(e)];
      const double d = wrap720(pe.angle_deg - a0);
      if (d < tol || d > span - tol) continue;
      bool seen = false;
      for (int j = 0; j < cam_obs_n_ && !seen; ++j) {
        const CamObs& o = cam_obs_[static_cast<std::size_t>(j)];
        seen = o.rising == pe.rising && circ_dist720(obs_angle(o, k), pe.angle_deg) <= tol;
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
bool PatternSync::width_match(int& k_out, const WheelTables& w, const DecoderParams& p) const noexcept {
  const int t = w.teeth;
  const int need = std::min(t, code_window_ + 2);
  if (nbits_ < need) return false;
  int matches = 0;
  for (int k = 0; k < t; ++k) {
    bool ok = true;
    for (int j = 0; j < need && ok; ++j)
      ok = ((bits_ >> j) & 1u) == ((p.width_code >> ((k - j + t) % t)) & 1u);
    if (ok) {
      ++matches;
      k_out = k;
    }
  }
  return matches == 1;
}

int PatternSync::syncing_step(std::int64_t t_ns, std::int64_t last_t_ns, std::int64_t period, int rev,
                              const WheelTables& w, const DecoderParams& p) noexcept {
  if (fresh_) {  // the previous accepted tooth is counter 0 of a new search
    fresh_ = false;
    count_ = 1;
    span_start_ = 0;
    cam_obs_n_ = 0;
    nbits_ = 0;
    bits_ = 0;
    ref_period_ns_ = 0;
  }
  if (ref_period_ns_ > 0 &&
      static_cast<double>(period) < p.syncing_runt_fraction * static_cast<double>(ref_period_ns_))
    return kNoise;
  ++count_;
  const int bit = p.width_coded ? width_bit(t_ns, last_t_ns, p) : 0;
  if (bit < 0) {
    nbits_ = 0;
  } else {
    bits_ = (bits_ << 1) | static_cast<std::uint64_t>(bit);
    nbits_ = std::min(nbits_ + 1, 63);
  }
  const bool cam = p.cam_pattern.n > 0;
  if (cam) collect(t_ns, last_t_ns, w);
  ref_period_ns_ = period;
  int k = 0;
  if (!(cam ? cam_match(k, w, p) : width_match(k, w, p))) return kSearching;
  misses_ = 0;
  return cam ? (k + count_ - 1) % (2 * w.teeth) : rev * w.teeth + k;
}

bool PatternSync::check_synced(std::int64_t t_ns, std::int64_t period_ns, int prev_idx, int idx, int advance,
                               const WheelTables& w, const DecoderParams& p, DecoderStats& stats) noexcept {
  const std::int64_t t_prev = t_ns - period_ns;
  bool miss = false;
  if (p.width_coded && advance == 1 && last_opp_t_ns_ > t_prev && last_opp_t_ns_ < t_ns) {
    const double f = static_cast<double>(last_opp_t_ns_ - t_prev) / static_cast<double>(period_ns);
    const std::uint32_t bit = f < p.width_code_threshold ? 1u : 0u;
    if (bit != ((p.width_code >> (idx % w.teeth)) & 1u)) {
      ++stats.width_code_errors;
      miss = true;
    }
  }
  if (p.cam_pattern.n > 0) {
    const double a0 = cycle_angle_deg(prev_idx, w);
    double span = 0.0;
    for (int j = 1; j <= advance; ++j) span += w.width_of((prev_idx + j) % w.teeth) * kRadToDeg;
    for (int j = 0; j < cam_pend_n_; ++j) {
      const CamPending& c = cam_pend_[static_cast<std::size_t>(j)];
      if (c.t_ns <= t_prev || c.t_ns > t_ns) continue;
      const double f = static_cast<double>(c.t_ns - t_prev) / static_cast<double>(period_ns);
      if (!cam_edge_fits(a0 + f * span, c.rising, 1.5 * p.cam_pattern.tolerance_deg, p.cam_pattern)) {
        ++stats.cam_phase_errors;
        miss = true;
      }
    }
    cam_pend_n_ = 0;
  }
  misses_ = miss ? misses_ + 1 : 0;
  if (misses_ < 2) return false;
  misses_ = 0;
  return true;
}

}  // namespace torqued
