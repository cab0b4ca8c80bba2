#include "cycle_energy.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kFourPi = 4.0 * std::numbers::pi;
constexpr double kDeg = std::numbers::pi / 180.0;

double wrap4pi(double a) noexcept {
  a = std::fmod(a, kFourPi);
  return a < 0.0 ? a + kFourPi : a;
}
/// Signed angular distance a − b wrapped to [−2π, 2π).
double diff720(double a, double b) noexcept {
  double d = wrap4pi(a - b);
  return d >= kTwoPi ? d - kFourPi : d;
}
}  // namespace

/// Nominal edges of one revolution: N−M wheel (tooth 0 first after the gap) or explicit angles.
void nominal_wheel_edges(const WheelGeometry& wheel, std::vector<double>& edge, std::vector<double>& width) {
  const int t = wheel.teeth();
  edge.assign(static_cast<std::size_t>(t), 0.0);
  width.assign(static_cast<std::size_t>(t), 0.0);
  if (wheel.tooth_count > 0) {
    const double a0 = wheel.tooth_angles_deg[0];
    for (int k = 0; k < t; ++k)
      edge[static_cast<std::size_t>(k)] = (wheel.tooth_angles_deg[static_cast<std::size_t>(k)] - a0) * kDeg;
    for (int k = 0; k < t; ++k) {
      const double prev =
          k == 0 ? edge[static_cast<std::size_t>(t - 1)] - kTwoPi : edge[static_cast<std::size_t>(k - 1)];
      width[static_cast<std::size_t>(k)] = edge[static_cast<std::size_t>(k)] - prev;
    }
  } else {
    const double pitch = kTwoPi / wheel.positions;
    for (int k = 0; k < t; ++k) {
      edge[static_cast<std::size_t>(k)] = k * pitch;
      width[static_cast<std::size_t>(k)] = k == 0 ? (wheel.missing + 1) * pitch : pitch;
    }
  }
}

CycleEnergy::CycleEnergy(const EngineGeometry& engine, const WheelGeometry& wheel,
                         const EnergiesParams& params)
    : CycleEnergy(engine, wheel, params, params.energy_window_deg, 0.5 * params.energy_window_deg) {}

CycleEnergy::CycleEnergy(const EngineGeometry& engine, const WheelGeometry& wheel,
                         const EnergiesParams& params, double window_deg, double window_end_deg,
                         double taper) {
  const CrankKinematics kin(engine);
  ncyl_ = engine.cylinders;
  std::vector<double> e1, w1;
  nominal_wheel_edges(wheel, e1, w1);
  const int t = wheel.teeth();
  samples_ = 2 * t;
  const auto n = static_cast<std::size_t>(samples_);
  center_.resize(n);
  width_.resize(n);
  j_center_.resize(n);
  kern_w_.resize(n);
  window_of_.assign(n, -1);
  window_first_.assign(n, 0);
  window_last_.assign(n, 0);
  segment_of_.assign(n, 0);
  for (int k = 0; k < samples_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const int turn = k / t;  // the crank turn of sample k (0 or 1)
    const double e = turn * kTwoPi + e1[static_cast<std::size_t>(k % t)];
    width_[i] = w1[static_cast<std::size_t>(k % t)];
    center_[i] = wrap4pi(e - 0.5 * width_[i] - engine.tdc_offset_rad);
    j_center_[i] = kin.inertia(center_[i]);
    kern_w_[i] = width_[i];  // rectangle (taper 0): the tooth's width, bit for bit
  }
  const double seg = kFourPi / ncyl_;
  // Window [end − w, end) around each boundary; the centred ±w/2 gives exactly −hi (×2 is exact in binary).
  const double hi = window_end_deg * kDeg;
  const double lo = hi - window_deg * kDeg;
  for (int b = 0; b < ncyl_; ++b)
    boundary_[static_cast<std::size_t>(b)] = wrap4pi(b * seg + params.segment_offset_deg * kDeg);
  for (int k = 0; k < samples_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    for (int b = 0; b < ncyl_; ++b) {
      // Half-open windows [end − w, end) with a tolerance: a centre exactly on a window edge (36-1 wheel: 10°
      // pitch, ±15° window) must fall on the same side at every boundary despite rounding.
      constexpr double kEps = 1e-9;
      const double d = diff720(center_[i] + kEps, boundary_[static_cast<std::size_t>(b)]);
      if (d >= lo && d < hi) window_of_[i] = b;
      if (d >= lo && d < hi && taper > 0.0) {
        // −1 … 1 across the angle the window's periods cover, [lo − w/2, hi − w/2) (centres in [lo, hi))
        const double x = (d - 0.5 * (lo + hi - width_[i])) / (0.5 * (hi - lo));
        kern_w_[i] = width_[i] * (1.0 - std::min(taper, 1.0) * x * x);
      }
      // Segment b spans [boundary_b, boundary_b + seg).
      const double ds = wrap4pi(center_[i] + kEps - boundary_[static_cast<std::size_t>(b)]);
      if (ds < seg) segment_of_[i] = b;
    }
  }
  // First / last tooth of each window in sequence order (windows may straddle the wrap at tooth 0).
  for (int k = 0; k < samples_; ++k) {
    const int w = window_of_[static_cast<std::size_t>(k)];
    if (w < 0) continue;
    const int prev = (k + samples_ - 1) % samples_;
    const int next = (k + 1) % samples_;
    if (window_of_[static_cast<std::size_t>(prev)] != w) window_first_[static_cast<std::size_t>(k)] = 1;
    if (window_of_[static_cast<std::size_t>(next)] != w) window_last_[static_cast<std::size_t>(k)] = 1;
  }
  // CAN load delay line: room for τ at 8 teeth per 0.1 ms (60-2 wheel above 8000 rpm) plus two cycles' worth.
  const double tau =
      std::isfinite(params.can_load_latency_s) ? std::max(0.0, params.can_load_latency_s) : 0.0;
  latency_ns_ = static_cast<std::int64_t>(std::llround(tau * 1e9));
  if (latency_ns_ > 0)
    pending_.resize(static_cast<std::size_t>(2 * samples_) + static_cast<std::size_t>(std::ceil(tau * 8e4)));
  reset();
}

void CycleEnergy::add_load(int segment, double width_rad, double load_nm, bool load_valid) noexcept {
  const auto c = static_cast<std::size_t>(segment);
  if (load_valid && std::isfinite(load_nm)) {
    seg_load_w_[c] += load_nm * width_rad;
  } else {
    seg_load_ok_[c] = false;
  }
  seg_w_[c] += width_rad;
}

void CycleEnergy::flush_pending(double load_nm, bool load_valid) noexcept {
  // The load of the last τ of the ended segment has not arrived yet: hold the newest value. (A linear
  // extrapolation along the recent slope removed more of the ramp error at 4000 rpm but overshot after steps
  // and load decays, e.g. when the clutch opens before a fuel cut-off, and biased the friction learned
  // there.)
  while (pend_count_ > 0) {
    const PendingTooth& p = pending_[pend_head_];
    add_load(p.segment, p.width_rad, load_nm, load_valid);
    pend_head_ = ring_next(pend_head_);
    --pend_count_;
  }
}

void CycleEnergy::reset() noexcept {
  expected_tooth_ = -1;
  win_ke_w_ = win_w_ = win_speed_w_ = 0.0;
  win_open_ = false;
  seg_load_w_.fill(0.0);
  seg_w_.fill(0.0);
  seg_load_ok_.fill(false);
  ke_.fill(0.0);
  t_.fill(0);
  ke_valid_.fill(false);
  seg_ok_.fill(false);
  seg_load_mean_.fill(0.0);
  seg_load_mean_ok_.fill(false);
  seg_angle_.fill(0.0);
  last_boundary_ = -1;
  pend_head_ = pend_count_ = 0;
  seg_ = SegmentEnergy{};
}

void CycleEnergy::invalidate() noexcept {
  win_open_ = false;
  pend_count_ = 0;
  ke_valid_.fill(false);
  seg_ok_.fill(false);
  seg_load_ok_.fill(false);
  seg_load_mean_ok_.fill(false);
  last_boundary_ = -1;
}

// Load work per segment (angle-mean load over the segment), each tooth period's load taken τ after it.
void CycleEnergy::track_load(const ToothSample& s, bool first_after_break, double load_nm,
                             bool load_valid) noexcept {
  const int k = s.tooth;
  const auto i = static_cast<std::size_t>(k);
  const int sg = segment_of_[i];
  const int prev_sg = segment_of_[static_cast<std::size_t>(k == 0 ? samples_ - 1 : k - 1)];
  if (sg != prev_sg || first_after_break) {
    if (!first_after_break) {
      flush_pending(load_nm, load_valid);
      const auto p = static_cast<std::size_t>(prev_sg);
      seg_load_mean_[p] = seg_w_[p] > 0.0 ? seg_load_w_[p] / seg_w_[p] : 0.0;
      seg_load_mean_ok_[p] = seg_load_ok_[p];
    }
    const auto c = static_cast<std::size_t>(sg);
    seg_load_w_[c] = 0.0;
    seg_w_[c] = 0.0;
    seg_load_ok_[c] = !first_after_break;  // a segment entered mid-way (after a break) is incomplete
  }
  if (latency_ns_ <= 0) {
    add_load(sg, width_[i], load_nm, load_valid);
  } else {
    // The load seen now is the flange torque of now − τ: it belongs to the pending teeth of that time.
    while (pend_count_ > 0 && pending_[pend_head_].t_ns + latency_ns_ <= s.t_ns) {
      const PendingTooth& p = pending_[pend_head_];
      add_load(p.segment, p.width_rad, load_nm, load_valid);
      pend_head_ = ring_next(pend_head_);
      --pend_count_;
    }
    if (pend_count_ == pending_.size()) {  // τ longer than the line holds: extrapolate the oldest (counted)
      const PendingTooth& p = pending_[pend_head_];
      add_load(p.segment, p.width_rad, load_nm, load_valid);
      pend_head_ = ring_next(pend_head_);
      --pend_count_;
      ++overflows_;
    }
    std::size_t tail = pend_head_ + pend_count_;  // < 2 size: one compare instead of a 64-bit division
    if (tail >= pending_.size()) tail -= pending_.size();
    pending_[tail] = PendingTooth{s.t_ns, sg, width_[i]};
    ++pend_count_;
  }
}

// The kinetic-energy window around boundary b closed on tooth s: the segment (and, at a full cycle, the
// cycle) energy balance.
void CycleEnergy::finish_window(const ToothSample& s, int b) noexcept {
  const auto bi = static_cast<std::size_t>(b);
  const double ke = win_ke_w_ / win_w_;
  const int prev_b = (b + ncyl_ - 1) % ncyl_;
  const auto pb = static_cast<std::size_t>(prev_b);
  SegmentEnergy out;
  out.t_ns = s.t_ns;
  out.boundary = b;
  out.ended_position = prev_b;
  out.ke_j = ke;
  out.speed_rad_s = win_speed_w_ / win_w_;
  out.segment_valid = last_boundary_ == prev_b && ke_valid_[pb];
  out.segment_rad = wrap4pi(boundary_[bi] - boundary_[pb]);
  if (ncyl_ == 1) out.segment_rad = kFourPi;
  if (out.segment_valid) {
    out.d_ke_segment_j = ke - ke_[pb];
    out.segment_dt_s = static_cast<double>(s.t_ns - t_[pb]) * 1e-9;
  }
  out.load_mean_nm = seg_load_mean_[pb];
  out.load_valid = out.segment_valid && seg_load_mean_ok_[pb];
  seg_ok_[pb] = out.segment_valid;
  seg_angle_[pb] = out.segment_rad;
  if (!out.segment_valid) seg_load_mean_ok_[pb] = false;

  bool all_ok = ke_valid_[bi];
  bool load_ok = true;
  double load_w = 0.0;
  for (int c = 0; c < ncyl_; ++c) {
    const auto ci = static_cast<std::size_t>(c);
    all_ok = all_ok && seg_ok_[ci];
    load_ok = load_ok && seg_load_mean_ok_[ci];
    load_w += seg_load_mean_[ci] * seg_angle_[ci];
  }
  out.cycle_valid = all_ok;
  if (all_ok) {
    out.d_ke_cycle_j = ke - ke_[bi];
    out.cycle_dt_s = static_cast<double>(s.t_ns - t_[bi]) * 1e-9;
    out.cycle_load_valid = load_ok;
    out.cycle_load_mean_nm = load_w / kFourPi;
  }
  ke_[bi] = ke;
  t_[bi] = s.t_ns;
  ke_valid_[bi] = true;
  last_boundary_ = b;
  seg_ = out;
}

bool CycleEnergy::update(const ToothSample& s, double load_nm, bool load_valid) noexcept {
  if (!s.synced || s.tooth < 0 || s.tooth >= samples_ || !(s.dt_s > 0.0) || !(s.width_rad > 0.0) ||
      !std::isfinite(s.dt_s) || !std::isfinite(s.width_rad)) {
    if (expected_tooth_ >= 0) ++breaks_;
    expected_tooth_ = -1;
    invalidate();
    return false;
  }
  return update_checked(s, load_nm, load_valid);
}

// update() after its sample checks (AnglePipeline::on_tooth makes the same ones once per tooth).
bool CycleEnergy::update_checked(const ToothSample& s, double load_nm, bool load_valid) noexcept {
  const int k = s.tooth;
  const auto i = static_cast<std::size_t>(k);
  if (expected_tooth_ >= 0 && k != expected_tooth_) {
    // A tooth went missing: everything spanning the hole is unusable.
    ++breaks_;
    invalidate();
  }
  const bool first_after_break = expected_tooth_ < 0 || k != expected_tooth_;
  expected_tooth_ = k + 1 == samples_ ? 0 : k + 1;  // (k + 1) mod samples_, k in [0, samples_)

  track_load(s, first_after_break, load_nm, load_valid);

  // Kinetic energy window around a boundary.
  const int b = window_of_[i];
  if (b < 0) return false;
  if (window_first_[i]) {
    win_open_ = true;
    win_ke_w_ = win_w_ = win_speed_w_ = 0.0;
  }
  if (!win_open_) return false;
  const double speed = s.width_rad / s.dt_s;
  const double w = kern_w_[i];
  win_ke_w_ += 0.5 * j_center_[i] * speed * speed * w;
  win_speed_w_ += speed * w;
  win_w_ += w;
  if (!window_last_[i]) return false;
  win_open_ = false;

  finish_window(s, b);
  return true;
}

}  // namespace torqued
