#include "cylinder_torque.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

const char* to_string(MisfireDetection d) noexcept {
  switch (d) {
    case MisfireDetection::kActive:
      return "active";
    case MisfireDetection::kOverrun:
      return "overrun";
    case MisfireDetection::kLowLoad:
      return "low-load";
    case MisfireDetection::kWheelUnlearned:
      return "wheel-unlearned";
    case MisfireDetection::kInvalid:
      return "invalid";
    case MisfireDetection::kNoisy:
      return "noisy";
  }
  return "?";
}

namespace {
constexpr double kFourPi = 4.0 * std::numbers::pi;

/// Median of work[0..n) without element m (≤ 7 values, insertion sort; m < 0: of all n).
double median_of_others(const std::array<double, kMaxCylinders>& work, int n, int m) noexcept {
  std::array<double, kMaxCylinders> others{};
  int k = 0;
  for (int j = 0; j < n; ++j) {
    if (j != m) others[static_cast<std::size_t>(k++)] = work[static_cast<std::size_t>(j)];
  }
  for (int a = 1; a < k; ++a) {
    const double v = others[static_cast<std::size_t>(a)];
    int b = a - 1;
    while (b >= 0 && others[static_cast<std::size_t>(b)] > v) {
      others[static_cast<std::size_t>(b + 1)] = others[static_cast<std::size_t>(b)];
      --b;
    }
    others[static_cast<std::size_t>(b + 1)] = v;
  }
  if (k == 0) return 0.0;
  return (k % 2 == 1)
             ? others[static_cast<std::size_t>(k / 2)]
             : 0.5 * (others[static_cast<std::size_t>(k / 2 - 1)] + others[static_cast<std::size_t>(k / 2)]);
}
}  // namespace

CylinderTorque::CylinderTorque(const EngineGeometry& engine, const CylinderParams& params) noexcept
    : engine_(engine), params_(params) {
  const double swept_m3 = 0.25 * std::numbers::pi * engine.bore_m * engine.bore_m * engine.stroke_m;
  w_floor_j_ =
      params.share_floor_imep_bar * 1e5 * swept_m3;  // IMEP × V_d = indicated work per cylinder and cycle
  reset();
}

void CylinderTorque::reset() noexcept {
  work_.fill(0.0);
  valid_.fill(false);
  fired_.fill(false);
  ema_.fill(0.0);
  comb_.fill(0.0);
  ema_init_ = false;
  ema_cycles_ = 0;
  ema_var_ = 0.0;
  motored_j_ = 0.0;
  motored_known_ = false;
  cut_cycles_ = 0;
  after_cut_ = prev_combusting_ = false;
  level_j_ = 0.0;
  level_known_ = prev_last_misfire_ = false;
  noisy_ = true;
  share_var_ = params_.share_noise_prior * params_.share_noise_prior;
  cycles_ = 0;
  prev_cycle_t_ns_ = 0;
  out_ = CylinderCycle{};
  out_.cylinders = engine_.cylinders;
}

bool CylinderTorque::on_segment(std::int64_t t_ns, int position, double work_j, bool valid,
                                bool fired) noexcept {
  const int n = engine_.cylinders;
  if (position < 0 || position >= n) return false;
  const auto p = static_cast<std::size_t>(position);
  work_[p] = work_j;
  valid_[p] = valid && std::isfinite(work_j);
  fired_[p] = fired;
  if (position != n - 1) return false;

  // Cycle complete: positions 0..n−1 hold this cycle's segments.
  // A cycle longer than this is a gap in the record, not a cycle: the per-cycle weight applies.
  constexpr double kMaxCycleDtS = 1.0;
  double cycle_dt_s = prev_cycle_t_ns_ != 0 ? static_cast<double>(t_ns - prev_cycle_t_ns_) * 1e-9 : 0.0;
  if (!(cycle_dt_s > 0.0 && cycle_dt_s < kMaxCycleDtS)) cycle_dt_s = 0.0;
  prev_cycle_t_ns_ = t_ns;
  CylinderCycle o;
  o.t_ns = t_ns;
  o.cycle = ++cycles_;
  o.cylinders = n;
  const CycleSums c = sum_cycle(n);
  if (!c.all_valid) {
    o.health = Health::kInvalidInput;
    o.detection = MisfireDetection::kInvalid;
    o.imbalance_filtered_pct = out_.imbalance_filtered_pct;
    o.imbalance_sd_pct = out_.imbalance_sd_pct;
    out_ = o;
    prev_combusting_ = prev_last_misfire_ = false;
    return true;
  }
  const double seg_rad = kFourPi / n;
  o.mean_nm = c.sum / kFourPi;
  const CycleLevels lv = cycle_levels(n, c.sum / n);
  // Resume after a cut-off: the caller's fired flags come back only some cycles after the injections (they
  // arm late so that a flag leading the injections is no false alarm), but once a whole cycle combusted the
  // fuel is back on every cylinder (the resume runs in firing order), so a segment at the motored level is a
  // misfire.
  const bool resumed = !c.all_fired && after_cut_ && prev_combusting_;
  const bool low_load = lv.fired_level_j / seg_rad <= params_.min_mean_nm;
  const bool noisy = update_noisy(lv.sigma_j, lv.fired_level_j);
  o.detection = !(c.all_fired || resumed) ? MisfireDetection::kOverrun
                : low_load                ? MisfireDetection::kLowLoad
                : !wheel_learned_         ? MisfireDetection::kWheelUnlearned
                : noisy                   ? MisfireDetection::kNoisy
                                          : MisfireDetection::kActive;
  const int candidates = flag_misfires(o, lv, resumed);
  update_level(o.detection, candidates);
  update_filtered_imbalance(o, candidates, cycle_dt_s);
  o.imbalance_filtered_pct = despilled();
  o.imbalance_sd_pct = ema_cycles_ > 0 ? 100.0 * std::sqrt(ema_var_) : 0.0;
  o.health = health_of(o.detection);
  out_ = o;
  prev_combusting_ = all_combusting(n, seg_rad);
  track_overrun(c.any_fired, median_of_others(work_, n, -1));
  return true;
}

CylinderTorque::CycleSums CylinderTorque::sum_cycle(int n) noexcept {
  CycleSums c;
  for (int m = 0; m < n; ++m) {
    const auto mi = static_cast<std::size_t>(m);
    c.all_valid = c.all_valid && valid_[mi];
    c.all_fired = c.all_fired && fired_[mi];
    c.any_fired = c.any_fired || fired_[mi];
    c.sum += work_[mi];
    comb_[mi] = work_[mi] - motored_j_;  // combustion work: above the motored level (0 until a cut-off)
  }
  return c;
}

CylinderTorque::CycleLevels CylinderTorque::cycle_levels(int n, double mean_w) const noexcept {
  CycleLevels lv;
  lv.mean_w = mean_w;
  lv.scale = std::max(mean_w, w_floor_j_);        // > 0: shares stay bounded when the mean is small
  lv.sigma_j = std::sqrt(share_var_) * lv.scale;  // running cycle-to-cycle noise of a segment's work
  // Firing level of the cycle: the largest median of the others (robust to two misfires in one cycle), in
  // combustion work: at idle after a cut-off the pumping loss makes a firing segment's net work ≈ 0 while its
  // combustion (and what a misfire removes) is the whole step up from the motored level.
  // Anchored: the running firing level L applies where some segment still fires at its usual level.
  constexpr double kAnchor = 0.8;
  for (int m = 0; m < n && level_known_; ++m)
    lv.anchored = lv.anchored || comb_[static_cast<std::size_t>(m)] >= kAnchor * level_j_;
  lv.fired_level_j = -1e300;
  for (int m = 0; m < n; ++m) lv.fired_level_j = std::max(lv.fired_level_j, reference_j(n, m, lv.anchored));
  return lv;
}

int CylinderTorque::flag_misfires(CylinderCycle& o, const CycleLevels& lv, bool resumed) noexcept {
  const int n = engine_.cylinders;
  const double seg_rad = kFourPi / n;
  const bool decide = o.detection == MisfireDetection::kActive;
  int candidates = 0;  // segments below the threshold, decided or not: kept out of the noise estimate
  for (int m = 0; m < n; ++m) {
    const auto mi = static_cast<std::size_t>(m);
    const auto ci = static_cast<std::size_t>(engine_.firing_order[mi] - 1);
    o.torque_nm[ci] = work_[mi] / kFourPi;
    o.imbalance_pct[ci] = (work_[mi] - lv.mean_w) / lv.scale * 100.0;
    // Misfire: compare with the median of the other cylinders (robust to a second misfire in the same cycle).
    const double med = reference_j(n, m, lv.anchored);
    // and, once the cycle-to-cycle noise of the shares is known, a deficit beyond misfire_sigma·σ (high
    // speed: jitter makes single segments swing; a missing combustion is a deficit of ~100 % of the mean)
    const bool beyond_noise = med - comb_[mi] > params_.misfire_sigma * lv.sigma_j;
    const bool fired = fired_[mi] || resumed;
    // the segment after a misfire lacks that cylinder's expansion tail: a lower threshold there
    const bool after =
        m == 0 ? prev_last_misfire_ : o.misfire[static_cast<std::size_t>(engine_.firing_order[mi - 1] - 1)];
    const double threshold = params_.misfire_threshold * (after ? params_.misfire_after_factor : 1.0);
    const bool below = comb_[mi] < threshold * med;
    // a segment below the ordinary threshold is a candidate (kept out of the noise, the level and the
    // imbalance) even where the lower threshold after a misfire does not flag it
    if (fired && comb_[mi] < params_.misfire_threshold * med) ++candidates;
    if (decide && fired && med / seg_rad > params_.min_mean_nm && below && beyond_noise) {
      o.misfire[ci] = true;
      ++o.misfire_count;
      ++misfires_;
    }
  }
  prev_last_misfire_ = o.misfire[static_cast<std::size_t>(engine_.firing_order[n - 1] - 1)];
  return candidates;
}

void CylinderTorque::update_level(MisfireDetection detection, int candidates) noexcept {
  // Running firing level from cycles decided without any candidate (a clean firing cycle).
  constexpr double kLevelFilter = 0.2;  // EMA weight per clean cycle (≈ 5-cycle memory, as W_mot)
  if (detection == MisfireDetection::kActive && candidates == 0) {
    const double lv = median_of_others(comb_, engine_.cylinders, -1);
    level_j_ = level_known_ ? level_j_ + kLevelFilter * (lv - level_j_) : lv;
    level_known_ = true;
  } else if (detection == MisfireDetection::kOverrun) {
    level_known_ = false;  // the level after a cut-off is learned anew
  }
}

// d_m = (1 − s)·c_m + s·c_{m−1} around the cycle, solved by the fixed point c_m = (d_m − s·c_{m−1})/(1 − s):
// a contraction of ratio s/(1 − s) ≤ 2/3, 60 sweeps leave < 1e-10 of the pattern.
std::array<double, kMaxCylinders> CylinderTorque::despilled() const noexcept {
  if (spill_ <= 0.0) return ema_;
  const int n = engine_.cylinders;
  const auto cyl = [this](int m) {
    return static_cast<std::size_t>(engine_.firing_order[static_cast<std::size_t>(m)] - 1);
  };
  std::array<double, kMaxCylinders> c = ema_;
  constexpr int kSweeps = 60;
  for (int it = 0; it < kSweeps; ++it) {
    for (int m = 0; m < n; ++m)
      c[cyl(m)] = (ema_[cyl(m)] - spill_ * c[cyl((m + n - 1) % n)]) / (1.0 - spill_);
  }
  return c;
}

double expansion_spill(const EngineGeometry& g, double segment_end_atdc_deg, double window_deg,
                       double window_after_deg, double taper, double centroid_atdc_deg,
                       double evo_atdc_deg) noexcept {
  constexpr double kGamma = 1.3;
  constexpr int kSteps = 2000;
  const double deg = std::numbers::pi / 180.0;
  const double lam = g.crank_radius_m() / g.rod_m;
  const double half_cr = 0.5 * (g.compression_ratio - 1.0);
  const auto volume = [&](double th_deg) {  // V / V_c
    const double t = th_deg * deg, sn = lam * std::sin(t);
    return 1.0 + half_cr * ((1.0 - std::cos(t)) + (1.0 - std::sqrt(1.0 - sn * sn)) / lam);
  };
  // share of the window's weight before angle a (relative to the boundary): the KE average at the
  // boundary counts the work done before a with that share
  const double lo = window_after_deg - window_deg, t = std::clamp(taper, 0.0, 1.0);
  const auto cdf = [&](double a) {
    const double x = std::clamp((a - lo) / window_deg, 0.0, 1.0);
    const double y = 2.0 * x - 1.0;
    return (x - t * (y * y * y + 1.0) / 6.0) / (1.0 - t / 3.0);
  };
  if (!(evo_atdc_deg > centroid_atdc_deg) || !(window_deg > 0.0)) return 0.0;
  double total = 0.0, spill = 0.0;
  const double h = (evo_atdc_deg - centroid_atdc_deg) / kSteps;
  for (int i = 0; i < kSteps; ++i) {
    const double th = centroid_atdc_deg + (i + 0.5) * h;
    const double dw = std::pow(volume(th), -kGamma) * (volume(th + 0.5 * h) - volume(th - 0.5 * h));
    total += dw;
    spill += dw * cdf(th - segment_end_atdc_deg);  // the share after the boundary: the next segment's
  }
  return total > 0.0 ? spill / total : 0.0;
}

double CylinderTorque::reference_j(int n, int m, bool anchored) const noexcept {
  const double med = median_of_others(comb_, n, m);
  return anchored && med < params_.misfire_threshold * level_j_ ? level_j_ : med;
}

// Every segment combusted: each one's combustion work is at least misfire_threshold × the firing level and
// that level is above min_mean_nm (a cycle at the motored level, or with a segment there, is not).
bool CylinderTorque::all_combusting(int n, double seg_rad) const noexcept {
  if (!after_cut_) return false;  // the motored level is not known: nothing to compare with
  double level = -1e300;
  for (int m = 0; m < n; ++m) level = std::max(level, median_of_others(comb_, n, m));
  if (!(level / seg_rad > params_.min_mean_nm)) return false;
  for (int m = 0; m < n; ++m) {
    if (!(comb_[static_cast<std::size_t>(m)] >= params_.misfire_threshold * level)) return false;
  }
  return true;
}

// Motored level W_mot: the median segment work of cycles flagged in cut-off, from the third one running (the
// injections already under way when the flag rises still burn in the first ones), filtered over cycles. It
// is the pumping and compression loss of a cylinder that does not burn, ≤ 0 (a positive value is a biased
// load or friction term, not a motored cylinder). A cycle flagged fired throughout ends the after-cut state.
void CylinderTorque::track_overrun(bool any_fired, double median_work_j) noexcept {
  constexpr int kSteadyCutCycles = 3;
  constexpr double kMotoredFilter = 0.2;  // EMA weight per cut-off cycle (≈ 5-cycle memory)
  if (any_fired) {
    cut_cycles_ = 0;
  } else if (++cut_cycles_ >= kSteadyCutCycles && std::isfinite(median_work_j)) {
    const double w = std::min(median_work_j, 0.0);
    motored_j_ = motored_known_ ? motored_j_ + kMotoredFilter * (w - motored_j_) : w;
    motored_known_ = true;
    after_cut_ = true;
  }
  bool all_fired = true;
  for (int m = 0; m < engine_.cylinders; ++m) all_fired = all_fired && fired_[static_cast<std::size_t>(m)];
  if (all_fired) after_cut_ = false;
}

// Noisy: a cylinder at the misfire threshold (a deficit of (1 − threshold) × the firing level) would lie
// within misfire_sigma·σ of the share noise: the decision would rest on the noise gate alone, which a
// heavy-tailed noise (jitter at high speed and light load) trips now and then.
// Latched with hysteresis, starting noisy (on the prior σ): the state is left only below kNoisyExitRatio of
// the limit, so that a noise estimate hovering at the limit (6000 rpm, 45 kPa on the simulator) does not
// switch detection on for single cycles.
bool CylinderTorque::update_noisy(double sigma_j, double fired_level_j) noexcept {
  constexpr double kNoisyExitRatio = 0.8;
  const double limit_j = (1.0 - params_.misfire_threshold) * fired_level_j;
  const double noise_gate_j = params_.misfire_sigma * sigma_j;
  if (params_.misfire_sigma <= 0.0) {
    noisy_ = false;  // no noise gate: the threshold alone decides
  } else if (noise_gate_j >= limit_j) {
    noisy_ = true;
  } else if (noise_gate_j < kNoisyExitRatio * limit_j) {
    noisy_ = false;
  }
  return noisy_;
}

// Filtered imbalance over firing cycles without misfire where detection is active (or only the wheel
// unlearned, or the shares noisy), and the running share noise that gates the misfire decision.
void CylinderTorque::update_filtered_imbalance(const CylinderCycle& o, int candidates,
                                               double cycle_dt_s) noexcept {
  // kNoisy too: the noise estimate must keep following the shares, or a noisy state would never end
  const bool usable = o.detection == MisfireDetection::kActive ||
                      o.detection == MisfireDetection::kWheelUnlearned ||
                      o.detection == MisfireDetection::kNoisy;
  // a misfire not decided (kNoisy) must not raise the noise that keeps it undecided
  if (!usable || o.misfire_count != 0 || candidates != 0 || !(o.mean_nm > params_.min_mean_nm)) return;
  const int n = engine_.cylinders;
  // Weight per cycle: imbalance_filter, at most 1 − exp(−T_cycle/τ) (a fixed averaging time: at high speed
  // the jitter noise of the shares grows as ω² while the cycles get shorter).
  double a = params_.imbalance_filter;
  if (params_.imbalance_tau_s > 0.0 && cycle_dt_s > 0.0)
    a = std::min(a, 1.0 - std::exp(-cycle_dt_s / params_.imbalance_tau_s));
  // The mean of the cycles so far while it weighs each more than the EMA would (1 at the first).
  ++ema_cycles_;
  a = std::max(a, 1.0 / ema_cycles_);
  double var = 0.0;
  for (int c = 0; c < n; ++c) {
    const auto ci = static_cast<std::size_t>(c);
    const double d = 0.01 * (o.imbalance_pct[ci] - ema_[ci]);  // this cycle's share noise (fraction)
    var += d * d / n;
    ema_[ci] += a * (o.imbalance_pct[ci] - ema_[ci]);
  }
  if (ema_init_) share_var_ += params_.imbalance_filter * (var - share_var_);
  ema_init_ = true;
  // Each cycle's share noise (share_var_, white from cycle to cycle: jitter) enters ema_ with weight a.
  ema_var_ = (1.0 - a) * (1.0 - a) * ema_var_ + a * a * share_var_;
}

Health CylinderTorque::health_of(MisfireDetection d) noexcept {
  switch (d) {
    case MisfireDetection::kActive:
      return Health::kValid;
    case MisfireDetection::kOverrun:
    case MisfireDetection::kLowLoad:
    case MisfireDetection::kNoisy:
      return Health::kNotExcited;
    default:
      return Health::kNotConverged;
  }
}

}  // namespace torqued
