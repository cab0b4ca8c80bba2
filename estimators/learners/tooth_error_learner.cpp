#include "tooth_error_learner.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

const char* to_string(ToothOrderSource s) noexcept {
  switch (s) {
    case ToothOrderSource::kHeld:
      return "held";
    case ToothOrderSource::kOverrun:
      return "overrun";
    case ToothOrderSource::kOverrunSpeeds:
      return "overrun-speeds";
    case ToothOrderSource::kSpeeds:
      return "speeds";
    case ToothOrderSource::kFiring:
      return "firing";
  }
  return "?";
}

const char* to_string(ToothLearnQuality q) noexcept {
  switch (q) {
    case ToothLearnQuality::kNone:
      return "none";
    case ToothLearnQuality::kHighOrders:
      return "high-orders";
    case ToothLearnQuality::kFiring:
      return "firing";
    case ToothLearnQuality::kSpeedLaws:
      return "speed-laws";
  }
  return "?";
}

namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
/// Prior 1σ of a per-revolution order's edge-angle coefficient (rad) for independent edge errors, from the
/// RMS hf_rms of the widths' higher orders (identify_orders, ToothOrderId::edge_se_rad).
double held_edge_se_rad(double hf_rms, int teeth) noexcept {
  const double n = teeth > 0 ? static_cast<double>(teeth) : 1.0;
  return hf_rms > 0.0 ? hf_rms * (kTwoPi / n) / std::sqrt(n) : -1.0;
}

// The wheel's part of z = −½(E/Ē − 1) for a width ratio ρ = w_true/w is ½(1 − ρ⁻²) up to a constant: E is
// measured with the nominal width, E ∝ (w/dt)² = ρ⁻²·E_true. It is ln ρ − (ln ρ)² + …, not ln ρ: taking z for
// ln ρ left the square of the machining error (0.012 RMS per width on a 0.05° wheel, i.e. 1.4e-4 per tooth,
// as large as the firing-order coefficients) in the table, mostly at the higher orders and at the orders
// learned from the overrun mean (balanced I4 at 6000 rpm 2.6 -> 1.0 pp). Exact in both directions.
double width_ratio_of(double z) noexcept { return 1.0 / std::sqrt(std::max(1.0 - 2.0 * z, 1e-6)); }
double z_of_width_ratio(double ratio) noexcept { return 0.5 * (1.0 - 1.0 / (ratio * ratio)); }
constexpr double kRpm = std::numbers::pi / 30.0;
constexpr double kRefSpeed = 100.0;  ///< x = (ω_ref/ω̄)² keeps the regression sums O(1) (rad/s)
constexpr double kRefMap = 1e5;      ///< u = (MAP/p_ref)·x of the load law (Pa)
constexpr double kRefSpark = 15.0;  ///< spark column u·(spark − ref)/scale: O(u) sums (deg); the intercept
constexpr double kSparkScale = 10.0;  ///< does not depend on either (the law holds u itself) (deg)
}  // namespace

ToothErrorLearner::ToothErrorLearner(const EngineGeometry& engine, const WheelGeometry& wheel,
                                     const ToothLearnParams& params)
    : params_(params), table_(ToothAngleTable::build(engine, wheel)) {
  const int kk = table_.samples;
  const int h = std::clamp(params_.fit_harmonics, 1, std::min(kMaxFitHarmonics, kk / 4));
  // Smooth basis of the engine's speed ripple: every cycle harmonic up to H. Odd ones (half orders) never
  // hold wheel error; even ones are per-revolution orders that hold both and are separated in recompute().
  std::vector<int> harmonics;
  for (int hh = 1; hh <= h; ++hh) harmonics.push_back(hh);
  nb_ = 2 * static_cast<int>(harmonics.size()) + 2;
  col_per_rev_.assign(static_cast<std::size_t>(nb_), 0);
  col_firing_.assign(static_cast<std::size_t>(nb_), 0);
  for (std::size_t q = 0; q < harmonics.size(); ++q) {
    col_per_rev_[2 * q + 2] = col_per_rev_[2 * q + 3] = harmonics[q] % 2 == 0 ? 1 : 0;
    col_firing_[2 * q + 2] = col_firing_[2 * q + 3] = harmonics[q] % engine.cylinders == 0 ? 1 : 0;
    if (harmonics[q] % 2 == 0) {
      ToothOrderId id;
      id.order = harmonics[q] / 2;
      id.firing = harmonics[q] % engine.cylinders == 0;
      ids_.push_back(id);
    }
  }
  const auto ks = static_cast<std::size_t>(kk);
  const auto nbs = static_cast<std::size_t>(nb_);
  basis_.resize(ks * nbs);
  trend_.assign(ks, 0.0);
  Eigen::MatrixXd b(kk, nb_);
  for (int k = 0; k < kk; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const double c = table_.edge_rad[i] - 0.5 * table_.width_rad[i];  // period centre, wheel angle in 720°
    b(k, 0) = 1.0;
    // Speed change within the cycle: the linear trend (c − 2π)/2π is NOT orthogonal to per-revolution
    // patterns (its per-rev sawtooth part took ≈ half of the wheel's first order, 0.025° edge error): the
    // trend is removed with the measured revolution times (finish_cycle) and only its anti-periodic part (a
    // step between the two revolutions, orthogonal to any wheel pattern) is fitted.
    trend_[static_cast<std::size_t>(k)] = (c - kTwoPi) / kTwoPi;
    b(k, 1) = k < table_.teeth ? -0.5 : 0.5;
    for (std::size_t q = 0; q < harmonics.size(); ++q) {
      b(k, static_cast<int>(2 * q + 2)) = std::cos(harmonics[q] * c / 2.0);
      b(k, static_cast<int>(2 * q + 3)) = std::sin(harmonics[q] * c / 2.0);
    }
    for (int j = 0; j < nb_; ++j) basis_[i * nbs + static_cast<std::size_t>(j)] = b(k, j);
  }
  for (int j = 2; j < nb_; ++j)
    if (col_per_rev_[static_cast<std::size_t>(j)] != 0) per_rev_cols_.push_back(j);
  const Eigen::MatrixXd g = (b.transpose() * b).ldlt().solve(b.transpose());
  pinv_.resize(nbs * ks);
  for (int j = 0; j < nb_; ++j)
    for (int k = 0; k < kk; ++k)
      pinv_[static_cast<std::size_t>(j) * ks + static_cast<std::size_t>(k)] = g(j, k);
  z_.assign(ks, 0.0);
  resid_sum_.assign(ks, 0.0);
  resid_sq_.assign(ks, 0.0);
  zw_sum_.assign(ks, 0.0);
  cw_sum_.assign(nbs, 0.0);
  coef_.assign(nbs, 0.0);
  const std::size_t slot_cols = static_cast<std::size_t>(kLoadSlots) * nbs;
  sb_.assign(slot_cols, 0.0);
  sxb_.assign(slot_cols, 0.0);
  sfb_.assign(slot_cols, 0.0);
  sbb_.assign(slot_cols, 0.0);
  cb_.assign(nbs, 0.0);
  cxb_.assign(nbs, 0.0);
  fb_.assign(nbs, 0.0);
  fxb_.assign(nbs, 0.0);
  ffb_.assign(nbs, 0.0);
  fbb_.assign(nbs, 0.0);
  smb_.assign(4 * nbs, 0.0);
  smbb_.assign(nbs, 0.0);
  low_coef_.assign(nbs, 0.0);
  imp_coef_.assign(nbs, 0.0);
  const auto ts = static_cast<std::size_t>(table_.teeth);
  eps_.assign(ts, 0.0);
  eps_import_.assign(ts, 0.0);
  ratio_.assign(ts, 1.0);
  reset();
}

void ToothErrorLearner::reset() noexcept {
  std::fill(resid_sum_.begin(), resid_sum_.end(), 0.0);
  std::fill(resid_sq_.begin(), resid_sq_.end(), 0.0);
  w2sum_ = 0.0;
  distrusted_ = false;
  check_ = ToothImportCheck{};
  std::fill(zw_sum_.begin(), zw_sum_.end(), 0.0);
  std::fill(cw_sum_.begin(), cw_sum_.end(), 0.0);
  since_solve_ = 0;
  solved_ready_ = false;
  slots_ = {};
  std::fill(sb_.begin(), sb_.end(), 0.0);
  std::fill(sxb_.begin(), sxb_.end(), 0.0);
  std::fill(sfb_.begin(), sfb_.end(), 0.0);
  std::fill(sbb_.begin(), sbb_.end(), 0.0);
  fire_ = LoadSlot{};
  for (auto* v : {&fb_, &fxb_, &ffb_, &fbb_, &smb_, &smbb_}) std::fill(v->begin(), v->end(), 0.0);
  sm_ = {};
  std::fill(cb_.begin(), cb_.end(), 0.0);
  std::fill(cxb_.begin(), cxb_.end(), 0.0);
  std::fill(imp_coef_.begin(), imp_coef_.end(), 0.0);
  nc_ = cx_ = cxx_ = 0.0;
  prev_all_cutoff_ = false;
  for (auto& id : ids_) {
    id.source = ToothOrderSource::kHeld;
    id.cycles = 0.0;
    id.edge_amplitude_rad = 0.0;
    id.firing_se_frac = -1.0;
    id.edge_se_rad = -1.0;
    id.spark = false;
  }
  std::fill(eps_.begin(), eps_.end(), 0.0);
  std::fill(eps_import_.begin(), eps_import_.end(), 0.0);
  std::fill(ratio_.begin(), ratio_.end(), 1.0);
  import_weight_ = 0.0;
  n_ = 0.0;
  wsum_ = 0.0;
  next_tooth_ = -1;
  collected_ = 0;
  low_orders_ok_ = false;
  stats_ = ToothLearnStats{};
}

bool ToothErrorLearner::ready() const noexcept { return n_ + import_weight_ >= params_.min_cycles; }

ToothLearnQuality ToothErrorLearner::quality() const noexcept {
  if (!ready()) return ToothLearnQuality::kNone;
  if (!low_orders_ok_) return ToothLearnQuality::kHighOrders;
  for (const auto& id : ids_)
    if (id.source == ToothOrderSource::kFiring) return ToothLearnQuality::kFiring;
  return ToothLearnQuality::kSpeedLaws;
}

void ToothErrorLearner::update(const ToothSample& s) noexcept {
  const int kk = table_.samples;
  if (!params_.learn) return;
  const bool ok = s.synced && s.dt_s > 0.0 && std::isfinite(s.dt_s) && s.tooth >= 0 && s.tooth < kk;
  if (!ok) {
    if (collected_ > 0) ++stats_.cycles_rejected;
    next_tooth_ = -1;
    collected_ = 0;
    prev_all_cutoff_ = false;
    return;
  }
  if (s.tooth == 0) {
    if (collected_ == kk) finish_cycle();
    collected_ = 0;
    cycle_time_s_ = 0.0;
    first_dt_s_ = 0.0;
    last_dt_s_ = 0.0;
    cycle_cutoff_ = cutoff_;
    cycle_all_cutoff_ = cutoff_;
    cycle_map_valid_ = map_valid_;
    cycle_map_sum_ = 0.0;
    cycle_map_min_ = cycle_map_max_ = map_pa_;
    cycle_spark_valid_ = spark_valid_;
    cycle_spark_sum_ = 0.0;
    next_tooth_ = 0;
  }
  if (s.tooth != next_tooth_) {
    if (collected_ > 0) ++stats_.cycles_rejected;
    next_tooth_ = -1;
    collected_ = 0;
    return;
  }
  const auto i = static_cast<std::size_t>(s.tooth);
  const double w = table_.width_rad[i] / s.dt_s;  // speed from the nominal width
  z_[i] = table_.j_center[i] * w * w;             // 2 × kinetic energy, normalised at the cycle end
  // time of the first and second revolution (equal angle spans) measure the change of speed over the cycle
  if (s.tooth < table_.teeth)
    first_dt_s_ += s.dt_s;
  else
    last_dt_s_ += s.dt_s;
  cycle_time_s_ += s.dt_s;
  cycle_cutoff_ = cycle_cutoff_ || cutoff_;
  cycle_all_cutoff_ = cycle_all_cutoff_ && cutoff_;
  cycle_map_valid_ = cycle_map_valid_ && map_valid_;
  cycle_map_sum_ += map_pa_;
  cycle_map_min_ = std::min(cycle_map_min_, map_pa_);
  cycle_map_max_ = std::max(cycle_map_max_, map_pa_);
  cycle_spark_valid_ = cycle_spark_valid_ && spark_valid_;
  cycle_spark_sum_ += spark_valid_ ? spark_deg_ : 0.0;
  ++collected_;
  next_tooth_ = (s.tooth + 1) % kk;
}

void ToothErrorLearner::finish_cycle() noexcept {
  const int kk = table_.samples;
  const auto ks = static_cast<std::size_t>(kk);
  const double omega = 2.0 * kTwoPi / cycle_time_s_;
  const double accel_frac = std::abs(last_dt_s_ - first_dt_s_) / first_dt_s_;
  // Overrun: this whole cycle and the previous one in cut-off (the last fired expansion has ended).
  const bool overrun = cycle_all_cutoff_ && prev_all_cutoff_;
  prev_all_cutoff_ = cycle_all_cutoff_;
  if (omega < params_.min_rpm * kRpm || omega > params_.max_rpm * kRpm ||
      accel_frac > params_.max_accel_frac) {
    ++stats_.cycles_rejected;
    return;
  }
  // z_k = −½ (E_k/Ē − 1): E = ½J(w/dt)² is E0 + W(θ) (linear in the ripple W) times (1 + ε_p)^−2 ≈ 1 − 2ε_p.
  double mean = 0.0;
  for (std::size_t k = 0; k < ks; ++k) mean += z_[k];
  mean /= kk;
  // Measured speed change: rev means ω1, ω2 from the exact revolution times (immune to tooth errors); with
  // E ∝ θ̇², z ≈ −(θ̇/ω̄ − 1) holds the trend −(ω2 − ω1)/ω̄ · (c − 2π)/2π (rev centres 2π apart).
  const double trend = -(kTwoPi / last_dt_s_ - kTwoPi / first_dt_s_) / omega;
  for (std::size_t k = 0; k < ks; ++k) z_[k] = -0.5 * (z_[k] / mean - 1.0) - trend * trend_[k];
  fit_cycle();
  // The leftover ripple (orders above the fit) falls as 1/ω̄², jitter noise grows with ω̄ but averages out:
  // weight the residuals by (ω̄/ω_ref)^p so that high-speed (and cut-off) cycles dominate.
  // The residual z − Bβ is linear in z and β: its weighted sum is formed from these two sums at the solve.
  const double wgt = std::pow(omega / (1000.0 * kRpm), params_.speed_weight_exp);
  for (std::size_t k = 0; k < ks; ++k) zw_sum_[k] += wgt * z_[k];
  if (import_weight_ > 0.0) accumulate_import_scatter(wgt);
  wsum_ += wgt;
  w2sum_ += wgt * wgt;
  n_ += 1.0;
  ++stats_.cycles_used;
  if (cycle_cutoff_) ++stats_.cycles_cutoff;
  const double x = (kRefSpeed / omega) * (kRefSpeed / omega);
  if (overrun) {
    ++stats_.cycles_overrun;
    nc_ += 1.0;
    cx_ += x;
    cxx_ += x * x;
    for (std::size_t j = 0; j < static_cast<std::size_t>(nb_); ++j) {
      cb_[j] += coef_[j];
      cxb_[j] += x * coef_[j];
    }
  }
  if (!cycle_cutoff_) regress(omega);  // the ripple of motored cycles follows another law: firing cycles only
  // Solve every solve_every_cycles cycles, at once when the table becomes usable (its first use), and at
  // every fuel cut-off cycle: the overrun identifies orders (and the friction learner reads the motored
  // cycles) within a short cut-off; a table lagging 7 cycles there moved the demo's second-run indicated
  // torque 0.79 -> 0.88 N m RMS.
  if (++since_solve_ >= params_.solve_every_cycles || (ready() && !solved_ready_) || cycle_cutoff_) solve();
}

void ToothErrorLearner::solve() noexcept {
  since_solve_ = 0;
  solved_ready_ = ready();
  recompute();
}

void ToothErrorLearner::fit_cycle() noexcept {
  const auto ks = static_cast<std::size_t>(table_.samples);
  // Least-squares fit of the smooth part, β = G z (G = (BᵀB)⁻¹Bᵀ precomputed), for the per-revolution
  // columns only: they are the ones the order laws read per cycle. The other columns enter only the
  // residual, whose sum over cycles is linear in z and formed at the solve (form_residual_sums).
  // Four rows at a time: each sum keeps its own order, the four chains of additions overlap.
  const std::size_t nr = per_rev_cols_.size();
  std::size_t r = 0;
  for (; r + 4 <= nr; r += 4) {
    const auto j0 = static_cast<std::size_t>(per_rev_cols_[r]),
               j1 = static_cast<std::size_t>(per_rev_cols_[r + 1]);
    const auto j2 = static_cast<std::size_t>(per_rev_cols_[r + 2]),
               j3 = static_cast<std::size_t>(per_rev_cols_[r + 3]);
    const double* g0 = &pinv_[j0 * ks];
    const double* g1 = &pinv_[j1 * ks];
    const double* g2 = &pinv_[j2 * ks];
    const double* g3 = &pinv_[j3 * ks];
    double a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
    for (std::size_t k = 0; k < ks; ++k) {
      const double zk = z_[k];
      a0 += g0[k] * zk;
      a1 += g1[k] * zk;
      a2 += g2[k] * zk;
      a3 += g3[k] * zk;
    }
    coef_[j0] = a0;
    coef_[j1] = a1;
    coef_[j2] = a2;
    coef_[j3] = a3;
  }
  for (; r < nr; ++r) {
    const auto j = static_cast<std::size_t>(per_rev_cols_[r]);
    const double* g = &pinv_[j * ks];
    double acc = 0.0;
    for (std::size_t k = 0; k < ks; ++k) acc += g[k] * z_[k];
    coef_[j] = acc;
  }
}

// Load slot of the cycle just collected: MAP known and steady over the cycle (within ±load_slot_frac of its
// mean), then the slot whose MAP is within ±load_slot_frac of it, else a free slot, else the least used one
// (its sums restart: a load visited briefly gives way to a new one). −1: no slot (the cycle is not used).
int ToothErrorLearner::load_slot() noexcept {
  const double frac = params_.load_slot_frac;
  const double map = cycle_map_sum_ / table_.samples;
  const bool load_steady = cycle_map_valid_ && map > 0.0 && cycle_map_max_ <= map * (1.0 + frac) &&
                           cycle_map_min_ >= map * (1.0 - frac);
  if (!load_steady) return -1;
  int least = 0;
  for (int s = 0; s < kLoadSlots; ++s) {
    const LoadSlot& sl = slots_[static_cast<std::size_t>(s)];
    if (sl.map_pa > 0.0 && std::abs(map / sl.map_pa - 1.0) <= frac) return s;
    if (sl.n < slots_[static_cast<std::size_t>(least)].n) least = s;
  }
  LoadSlot& sl = slots_[static_cast<std::size_t>(least)];
  sl = LoadSlot{};
  sl.map_pa = map;
  const auto nbs = static_cast<std::size_t>(nb_);
  const auto off = static_cast<std::size_t>(least) * nbs;
  for (std::size_t j = off; j < off + nbs; ++j) sb_[j] = sxb_[j] = sfb_[j] = sbb_[j] = 0.0;
  return least;
}

void ToothErrorLearner::regress(double omega) noexcept {
  // The speed ripple in each coefficient scales as ΔE/E ∝ load/ω̄²; the tooth-error part does not: per load.
  const int s = load_slot();
  if (s < 0) return;
  LoadSlot& sl = slots_[static_cast<std::size_t>(s)];
  const double x = (kRefSpeed / omega) * (kRefSpeed / omega);
  sl.n += 1.0;
  const double f = x * std::log(x);  // the ripple's drift with speed (firing orders' third column)
  sl.sx += x;
  sl.sxx += x * x;
  sl.sf += f;
  sl.sxf += x * f;
  sl.sff += f * f;
  const auto off = static_cast<std::size_t>(s) * static_cast<std::size_t>(nb_);
  // Load law over every steady firing cycle: β = a + b·u + c·x, u = (MAP/p_ref)·x. The cylinder pressures
  // scale with MAP (compression from MAP at IVC, combustion with the charge), the pumping strokes' ripple
  // with p_exh − MAP, so the engine's ripple is (b·MAP + c)/ω̄²; the wheel's part a is neither (non-firing
  // orders: [1, u], an imbalance scales with the load). A ripple ∝ u·ln x (the same-load law's drift) in
  // place of x left the I4's firing orders 0.02-0.03° off (in-cycle lag 2-2.6°) on the bed's tuning engines.
  const double u = sl.map_pa / kRefMap * x;
  const double g = x;
  fire_.n += 1.0;
  fire_.sx += u;
  fire_.sxx += u * u;
  fire_.sf += g;
  fire_.sxf += u * g;
  fire_.sff += g * g;
  // The spark column (only cycles with a fresh spark advance at every tooth; the others stay in [1, u, x]).
  const bool spark = params_.spark_column && cycle_spark_valid_;
  const double col[4] = {1.0, u, g, u * (cycle_spark_sum_ / table_.samples - kRefSpark) / kSparkScale};
  if (spark) {
    for (std::size_t r = 0; r < 4; ++r)
      for (std::size_t c = 0; c < 4; ++c) sm_[r * 4 + c] += col[r] * col[c];
  } else if (params_.spark_column) {
    ++stats_.cycles_no_spark;
  }
  for (std::size_t j = 0; j < static_cast<std::size_t>(nb_); ++j) {
    if (spark) {
      for (std::size_t c = 0; c < 4; ++c) smb_[j * 4 + c] += col[c] * coef_[j];
      smbb_[j] += coef_[j] * coef_[j];
    }
    const double b = coef_[j];
    sb_[off + j] += b;
    sxb_[off + j] += x * b;
    sfb_[off + j] += f * b;
    sbb_[off + j] += b * b;
    fb_[j] += b;
    fxb_[j] += u * b;
    ffb_[j] += g * b;
    fbb_[j] += b * b;
  }
}

bool ToothErrorLearner::law_intercept(const LoadSlot& sl, const double* sb, const double* sxb,
                                      const double* sfb, const double* sbb, std::size_t j0, bool firing,
                                      double* v, double* var) const noexcept {
  constexpr double kMinSlotCycles = 6.0;  // at least twice the 3 parameters of the quadratic law
  const double spread = params_.min_speed_spread_frac;
  const double m00 = sl.n, m01 = sl.sx, m02 = sl.sf, m11 = sl.sxx, m12 = sl.sxf, m22 = sl.sff;
  const double vx = sl.n * sl.sxx - sl.sx * sl.sx;
  const double det =
      m00 * (m11 * m22 - m12 * m12) - m01 * (m01 * m22 - m12 * m02) + m02 * (m01 * m12 - m11 * m02);
  const double params = firing ? 3.0 : 2.0;
  const bool speeds_spread = vx > spread * spread * sl.sx * sl.sx;
  const bool usable = sl.n >= kMinSlotCycles && sl.n > params + 1.0 && speeds_spread &&
                      (!firing || std::abs(det) > 1e-12 * sl.n);
  if (!usable) return false;
  double rss = 0.0;
  for (std::size_t c = 0; c < 2; ++c) {
    const std::size_t j = j0 + c;
    const double r0 = sb[j], r1 = sxb[j], r2 = sfb[j];
    if (firing) {
      v[c] = (r0 * (m11 * m22 - m12 * m12) - m01 * (r1 * m22 - m12 * r2) + m02 * (r1 * m12 - m11 * r2)) / det;
      const double g =
          (m00 * (r1 * m22 - m12 * r2) - r0 * (m01 * m22 - m12 * m02) + m02 * (m01 * r2 - r1 * m02)) / det;
      const double e =
          (m00 * (m11 * r2 - r1 * m12) - m01 * (m01 * r2 - r1 * m02) + r0 * (m01 * m12 - m11 * m02)) / det;
      rss += sbb[j] - v[c] * r0 - g * r1 - e * r2;
    } else {
      v[c] = (sl.sxx * r0 - sl.sx * r1) / vx;
      const double g = (sl.n * r1 - sl.sx * r0) / vx;
      rss += sbb[j] - v[c] * r0 - g * r1;
    }
  }
  const double s2 = std::max(rss, 0.0) / (2.0 * (sl.n - params));
  const double m_inv00 = firing ? (m11 * m22 - m12 * m12) / det : sl.sxx / vx;
  *var = std::max(s2 * m_inv00, 1e-30);
  return true;
}

// The spark law's normal equations M·p = r (4 columns, Cholesky): intercept p₀ per cos/sin column and its
// variance s²·(M⁻¹)₀₀, s² = RSS/(n − 4) pooled over the two columns, as law_intercept(). A column that the
// others explain (a spark advance that moves with u and x alone) gives a vanishing pivot: not identified.
bool ToothErrorLearner::spark_law_intercept(std::size_t j0, double* v, double* var) const noexcept {
  constexpr std::size_t kP = 4;
  constexpr double kMinCycles = 8.0;  // twice the 4 parameters
  const double n = sm_[0];
  if (n < kMinCycles) return false;
  double l[kP * kP] = {};
  for (std::size_t i = 0; i < kP; ++i) {
    for (std::size_t k = 0; k <= i; ++k) {
      double acc = sm_[i * kP + k];
      for (std::size_t m = 0; m < k; ++m) acc -= l[i * kP + m] * l[k * kP + m];
      if (k < i) {
        l[i * kP + k] = acc / l[k * kP + k];
      } else {
        if (!(acc > 1e-9 * sm_[i * kP + i])) return false;  // this column is (almost) the others'
        l[i * kP + i] = std::sqrt(acc);
      }
    }
  }
  // M⁻¹·b by forward and back substitution with L.
  const auto solve = [&l](const double* b, double* x) {
    double y[kP];
    for (std::size_t i = 0; i < kP; ++i) {
      double acc = b[i];
      for (std::size_t m = 0; m < i; ++m) acc -= l[i * kP + m] * y[m];
      y[i] = acc / l[i * kP + i];
    }
    for (std::size_t i = kP; i-- > 0;) {
      double acc = y[i];
      for (std::size_t m = i + 1; m < kP; ++m) acc -= l[m * kP + i] * x[m];
      x[i] = acc / l[i * kP + i];
    }
  };
  double rss = 0.0;
  for (std::size_t c = 0; c < 2; ++c) {
    const double* r = &smb_[(j0 + c) * kP];
    double p[kP];
    solve(r, p);
    v[c] = p[0];
    rss += smbb_[j0 + c] - (p[0] * r[0] + p[1] * r[1] + p[2] * r[2] + p[3] * r[3]);
  }
  const double e0[kP] = {1.0, 0.0, 0.0, 0.0};
  double inv0[kP];
  solve(e0, inv0);
  const double s2 = std::max(rss, 0.0) / (2.0 * (n - static_cast<double>(kP)));
  *var = std::max(s2 * inv0[0], 1e-30);
  return true;
}

// Per slot: β_j = β_j0 + γ_j x (non-firing: only an imbalance, small enough for the linear law) or + η_j x ln
// x (firing: the full gas-torque ripple x·A(ω), whose A drifts with the speed; see the header); normal
// equations, Cramer's rule. Intercept variance s²·(M⁻¹)₀₀, s² = RSS/(n − p) pooled over the two columns.
// Needs min_cycles_per_slot cycles and a spread of speeds: 1σ of x above min_speed_spread_frac of its mean.
bool ToothErrorLearner::slot_intercept(std::size_t j0, bool firing, double* v, double* var,
                                       double* cycles) const noexcept {
  double w_sum = 0.0, acc[2] = {0.0, 0.0}, n_sum = 0.0;
  for (std::size_t s = 0; s < slots_.size(); ++s) {
    const std::size_t off = s * static_cast<std::size_t>(nb_);
    double a[2], var_a = 0.0;
    if (!law_intercept(slots_[s], &sb_[off], &sxb_[off], &sfb_[off], &sbb_[off], j0, firing, a, &var_a))
      continue;
    w_sum += 1.0 / var_a;
    acc[0] += a[0] / var_a;
    acc[1] += a[1] / var_a;
    n_sum += slots_[s].n;
  }
  if (w_sum <= 0.0) return false;
  v[0] = acc[0] / w_sum;
  v[1] = acc[1] / w_sum;
  *var = 1.0 / w_sum;
  *cycles = n_sum;
  return true;
}

double wheel_table_accel_var(std::span<const ToothOrderId> ids) noexcept {
  double v = 0.0;
  for (const ToothOrderId& id : ids) {
    if (id.edge_se_rad < 0.0 || !id.firing) continue;
    const double r2 = static_cast<double>(id.order) * id.order;
    v += r2 * r2 * id.edge_se_rad * id.edge_se_rad;
  }
  return v;
}

void ToothErrorLearner::identify_orders(double* low, double hf_rms) noexcept {
  const bool learn = params_.learn_low_orders;
  // Overrun: mean (non-firing orders) or linear regression on x (firing orders, needs a spread of speeds).
  const bool ov_mean = learn && nc_ >= params_.min_overrun_cycles;
  const double vcx = nc_ * cxx_ - cx_ * cx_;
  const double spread = params_.min_speed_spread_frac;
  const bool ov_speeds = ov_mean && vcx > spread * spread * cx_ * cx_;
  // The firing orders' load law [1, u, x] needs loads that vary apart from the speed: at one load (or a load
  // tied to the speed) u ∝ x and the law is [1, x] without the speed drift the same-load slots model.
  const LoadSlot& fl = fire_;
  const double suu = fl.sxx - fl.sx * fl.sx / std::max(fl.n, 1.0);
  const double sxx = fl.sff - fl.sf * fl.sf / std::max(fl.n, 1.0);
  const double sux = fl.sxf - fl.sx * fl.sf / std::max(fl.n, 1.0);
  const bool fire_loads_vary =
      suu > 0.0 && sxx > 0.0 && 1.0 - sux * sux / (suu * sxx) >= params_.firing_law_min_load_spread;
  for (std::size_t q = 0; q < ids_.size(); ++q) {
    ToothOrderId& id = ids_[q];
    const auto j0 = static_cast<std::size_t>(2 * id.order * 2);  // harmonic h = 2·order → columns 2h, 2h + 1
    id.source = ToothOrderSource::kHeld;
    id.cycles = 0.0;
    double sv[2] = {0.0, 0.0}, var = 0.0, cycles = 0.0;
    // Variance check: the intercept's standard error (per column) small against the wheel's higher orders.
    const bool speeds = learn && slot_intercept(j0, id.firing, sv, &var, &cycles) &&
                        std::sqrt(var) <= params_.max_low_order_se_frac * hf_rms;
    // Load law over all firing cycles: the convergence measure is reported whether or not it is used.
    double fv[2] = {0.0, 0.0}, fvar = 0.0;
    const bool fire_fit =
        learn && params_.firing_load_law &&
        law_intercept(fire_, fb_.data(), fxb_.data(), ffb_.data(), fbb_.data(), j0, id.firing, fv, &fvar);
    // The firing orders: the law with the spark column where the cycles with a spark advance identify it.
    double pv[2] = {0.0, 0.0}, pvar = 0.0;
    id.spark = fire_fit && id.firing && params_.spark_column && spark_law_intercept(j0, pv, &pvar) &&
               std::sqrt(pvar) <= params_.max_low_order_se_frac * hf_rms;
    if (id.spark) {
      fv[0] = pv[0];
      fv[1] = pv[1];
      fvar = pvar;
    }
    id.firing_se_frac = fire_fit && hf_rms > 0.0 ? std::sqrt(fvar) / hf_rms : -1.0;
    const bool fire_ok = fire_fit && std::sqrt(fvar) <= params_.max_low_order_se_frac * hf_rms &&
                         (!id.firing || fire_loads_vary);
    if (!id.firing && ov_mean) {
      id.source = ToothOrderSource::kOverrun;
      id.cycles = nc_;
    } else if (id.firing && ov_speeds) {
      id.source = ToothOrderSource::kOverrunSpeeds;
      id.cycles = nc_;
    } else if (fire_ok) {  // ahead of the same-load slots: all cycles, no load slot with a few cycles only
      id.source = ToothOrderSource::kFiring;
      id.cycles = id.spark ? sm_[0] : fire_.n;
    } else if (speeds) {
      id.source = ToothOrderSource::kSpeeds;
      id.cycles = cycles;
    }
    // The used law's standard error per coefficient (z domain; over the order: edge angle). A held order
    // without an imported table holds zero against a wheel error of unknown size: the prior of edges with
    // independent errors (as the plausibility check in recompute() assumes), σ_e ≈ hf_rms·w/√2 from the
    // widths' higher orders (z_p ≈ (e_p − e_{p−1})/w, w = 2π/teeth), and a Fourier coefficient of N such
    // edges has 1σ σ_e·√(2/N) = hf_rms·w/√N (rad) whatever the order.
    const double se_z = id.source == ToothOrderSource::kSpeeds ? std::sqrt(var)
                        : fire_fit                             ? std::sqrt(fvar)
                                                               : -1.0;
    id.edge_se_rad = se_z >= 0.0 ? se_z / id.order : -1.0;
    if (id.source == ToothOrderSource::kHeld && import_weight_ <= 0.0)
      id.edge_se_rad = held_edge_se_rad(hf_rms, table_.teeth);
    for (std::size_t j = j0; j < j0 + 2; ++j) {
      double v = 0.0;
      switch (id.source) {
        case ToothOrderSource::kOverrun:
          v = cb_[j] / nc_;
          break;
        case ToothOrderSource::kOverrunSpeeds:
          v = (cxx_ * cb_[j] - cx_ * cxb_[j]) / vcx;
          break;
        case ToothOrderSource::kSpeeds:
          v = sv[j - j0];
          break;
        case ToothOrderSource::kFiring:
          v = fv[j - j0];
          break;
        case ToothOrderSource::kHeld:
          v = imp_coef_[j];
          break;
      }
      low[j] = v;
    }
  }
}

// The imported table against the fresh evidence, per physical tooth above the fit's orders (the part the
// per-cycle fit cannot absorb, learned from this run's cycles only): the fresh weighted mean residual
// h_p = ½(m_p + m_{p+T}) and its standard error from the cycles' weighted scatter (effective count
// (Σw)²/Σw²), against the imported table's z minus its projection on the per-revolution columns. Both as
// width errors (× nominal width, rad), means removed (the constant column is not compared). A disagreement
// beyond distrust_gate_sigma standard errors AND distrust_floor_deg (RMS over the teeth) discards the import.
void ToothErrorLearner::check_import() noexcept {
  if (import_weight_ <= 0.0 || n_ < params_.distrust_min_cycles || wsum_ <= 0.0 || w2sum_ <= 0.0) return;
  const int t = table_.teeth;
  const auto nbs = static_cast<std::size_t>(nb_);
  const double n_eff = wsum_ * wsum_ / w2sum_;
  double d_sum = 0.0, d_ss = 0.0, se_ss = 0.0;
  for (int p = 0; p < t; ++p) {
    const auto i = static_cast<std::size_t>(p);
    double h = 0.0, var = 0.0;
    for (int rev = 0; rev < 2; ++rev) {
      const auto k = static_cast<std::size_t>(p + rev * t);
      const double m = resid_sum_[k] / wsum_;
      h += 0.5 * m;
      var += 0.25 * std::max(resid_sq_[k] / wsum_ - m * m, 0.0) / n_eff;
    }
    const double* b = &basis_[i * nbs];
    double lo_imp = 0.0;
    for (std::size_t j = 2; j < nbs; ++j)
      if (col_per_rev_[j] != 0) lo_imp += b[j] * imp_coef_[j];
    const double w = table_.width_rad[i];
    const double d = (h - (eps_import_[i] - lo_imp)) * w;
    d_sum += d;
    d_ss += d * d;
    se_ss += var * w * w;
  }
  const double tt = static_cast<double>(t);
  check_.disagreement_rad = std::sqrt(std::max(d_ss / tt - (d_sum / tt) * (d_sum / tt), 0.0));
  check_.se_rad = std::sqrt(se_ss / tt);
  check_.cycles = n_;
  const double floor_rad = params_.distrust_floor_deg * std::numbers::pi / 180.0;
  if (check_.disagreement_rad <= params_.distrust_gate_sigma * check_.se_rad ||
      check_.disagreement_rad <= floor_rad)
    return;
  distrusted_ = true;
  ++stats_.tables_distrusted;
  import_weight_ = 0.0;
  std::fill(eps_import_.begin(), eps_import_.end(), 0.0);
  std::fill(imp_coef_.begin(), imp_coef_.end(), 0.0);
}

// While an imported table is held: the cycle's full fit β = G z (every column) and Σ w·(z − Bβ)² per sample,
// the scatter check_import() needs (a square is not linear in z: it cannot be formed from the sums at the
// solve). Runs only while a table from the state file awaits its check.
void ToothErrorLearner::accumulate_import_scatter(double wgt) noexcept {
  const std::size_t ks = z_.size();
  const auto nbs = static_cast<std::size_t>(nb_);
  for (std::size_t j = 0; j < nbs; ++j) {
    const double* g = &pinv_[j * ks];
    double acc = 0.0;
    for (std::size_t k = 0; k < ks; ++k) acc += g[k] * z_[k];
    cw_sum_[j] = acc;  // scratch (form_residual_sums overwrites it at the solve)
  }
  for (std::size_t k = 0; k < ks; ++k) {
    const double* b = &basis_[k * nbs];
    double fit = 0.0;
    for (std::size_t j = 0; j < nbs; ++j) fit += b[j] * cw_sum_[j];
    const double r = z_[k] - fit;
    resid_sq_[k] += wgt * r * r;
  }
}

// Σw·(z − Bβ) = Σw·z − B·G·Σw·z per sample (β = G z is linear); four samples at a time, each sum in order.
void ToothErrorLearner::form_residual_sums() noexcept {
  const std::size_t ks = resid_sum_.size();
  const auto nbs = static_cast<std::size_t>(nb_);
  for (std::size_t j = 0; j < nbs; ++j) {  // Σw·β = G·Σw·z
    const double* g = &pinv_[j * ks];
    double acc = 0.0;
    for (std::size_t k = 0; k < ks; ++k) acc += g[k] * zw_sum_[k];
    cw_sum_[j] = acc;
  }
  const double* c = cw_sum_.data();
  std::size_t k = 0;
  for (; k + 4 <= ks; k += 4) {
    const double* b0 = &basis_[k * nbs];
    const double* b1 = b0 + nbs;
    const double* b2 = b1 + nbs;
    const double* b3 = b2 + nbs;
    double f0 = 0.0, f1 = 0.0, f2 = 0.0, f3 = 0.0;
    for (std::size_t j = 0; j < nbs; ++j) {
      f0 += b0[j] * c[j];
      f1 += b1[j] * c[j];
      f2 += b2[j] * c[j];
      f3 += b3[j] * c[j];
    }
    resid_sum_[k] = zw_sum_[k] - f0;
    resid_sum_[k + 1] = zw_sum_[k + 1] - f1;
    resid_sum_[k + 2] = zw_sum_[k + 2] - f2;
    resid_sum_[k + 3] = zw_sum_[k + 3] - f3;
  }
  for (; k < ks; ++k) {
    const double* b = &basis_[k * nbs];
    double f = 0.0;
    for (std::size_t j = 0; j < nbs; ++j) f += b[j] * c[j];
    resid_sum_[k] = zw_sum_[k] - f;
  }
}

void ToothErrorLearner::recompute() noexcept {
  const int t = table_.teeth;
  const auto nbs = static_cast<std::size_t>(nb_);
  form_residual_sums();
  check_import();  // before the held orders take the imported values (reads the residual sums)
  std::fill(low_coef_.begin(), low_coef_.end(), 0.0);
  const double wsum0 = wsum_ > 0.0 ? wsum_ : 1.0;
  double hf_ms = 0.0;  // mean square of the learned higher orders per sample (the variance check's scale)
  for (std::size_t k = 0; k < resid_sum_.size(); ++k)
    hf_ms += (resid_sum_[k] / wsum0) * (resid_sum_[k] / wsum0);
  const double hf_rms = std::sqrt(hf_ms / static_cast<double>(resid_sum_.size()));
  identify_orders(low_coef_.data(), hf_rms);
  // Plausibility of the 1/ω̄² regressions (firing or overrun): machining errors are independent per edge, so
  // the width error holds little at the low orders (a few % of its RMS). A larger part means the ripple did
  // not follow 1/ω̄² (mixed loads, a coast-down with falling MAP, transients): hold those orders instead.
  const auto regressed = [](ToothOrderSource src) {
    return src == ToothOrderSource::kSpeeds || src == ToothOrderSource::kOverrunSpeeds ||
           src == ToothOrderSource::kFiring;
  };
  double hf_ss = 0.0, sp_ss = 0.0;
  const double wsum = wsum_ > 0.0 ? wsum_ : 1.0;
  std::array<std::size_t, kMaxFitHarmonics> reg_j0{};  // first column of each regressed order, in order
  std::size_t n_reg = 0;
  for (const auto& id : ids_)
    if (regressed(id.source)) reg_j0[n_reg++] = static_cast<std::size_t>(4 * id.order);
  for (int p = 0; p < t; ++p) {
    double hf = 0.0, sp = 0.0;
    for (int rev = 0; rev < 2; ++rev) {
      const auto k = static_cast<std::size_t>(p + rev * t);
      hf += resid_sum_[k] / wsum;
      const double* b = &basis_[k * nbs];
      for (std::size_t r = 0; r < n_reg; ++r) {
        const std::size_t j0 = reg_j0[r];
        sp += b[j0] * low_coef_[j0] + b[j0 + 1] * low_coef_[j0 + 1];
      }
    }
    eps_[static_cast<std::size_t>(p)] = 0.5 * hf;
    hf_ss += hf * hf;
    sp_ss += sp * sp;
  }
  if (sp_ss >= 0.25 * hf_ss) {
    for (auto& id : ids_) {
      if (!regressed(id.source)) continue;
      id.source = ToothOrderSource::kHeld;
      id.cycles = 0.0;
      if (import_weight_ <= 0.0) id.edge_se_rad = held_edge_se_rad(hf_rms, t);
      const auto j0 = static_cast<std::size_t>(4 * id.order);
      low_coef_[j0] = imp_coef_[j0];
      low_coef_[j0 + 1] = imp_coef_[j0 + 1];
    }
  }
  bool all = !ids_.empty();
  for (auto& id : ids_) {
    const auto j0 = static_cast<std::size_t>(4 * id.order);
    if (id.source == ToothOrderSource::kHeld) {
      all = false;
    } else {  // blend with the imported table by weight
      for (std::size_t j = j0; j < j0 + 2; ++j)
        low_coef_[j] =
            (import_weight_ * imp_coef_[j] + id.cycles * low_coef_[j]) / (import_weight_ + id.cycles);
      if (id.edge_se_rad > 0.0) id.edge_se_rad *= id.cycles / (import_weight_ + id.cycles);
    }
    id.edge_amplitude_rad = std::hypot(low_coef_[j0], low_coef_[j0 + 1]) / id.order;
  }
  low_orders_ok_ = all;
  // High orders: residual blended with the imported table's part above the fit; low orders: identified or
  // held.
  double norm = 0.0;
  for (int p = 0; p < t; ++p) {
    const auto i = static_cast<std::size_t>(p);
    const double* b = &basis_[i * nbs];
    double lo = 0.0, lo_imp = 0.0;
    for (const int jj : per_rev_cols_) {  // the per-revolution columns, ascending
      const auto j = static_cast<std::size_t>(jj);
      lo += b[j] * low_coef_[j];
      lo_imp += b[j] * imp_coef_[j];
    }
    const double hi = (import_weight_ * (eps_import_[i] - lo_imp) + n_ * eps_[i]) / (import_weight_ + n_);
    ratio_[i] = width_ratio_of(hi + lo);
    norm += ratio_[i] * table_.width_rad[i];
  }
  norm /= kTwoPi;  // the true widths add up to one revolution
  for (auto& r : ratio_) r /= norm;
}

double ToothErrorLearner::width_ratio(int p) const noexcept {
  return ready() ? ratio_[static_cast<std::size_t>(p)] : 1.0;
}

double ToothErrorLearner::corrected_width(int k) const noexcept {
  return table_.width_rad[static_cast<std::size_t>(k)] * width_ratio(k % table_.teeth);
}

void ToothErrorLearner::edge_corrections(std::span<double> out_rad) const noexcept {
  const int t = std::min<int>(table_.teeth, static_cast<int>(out_rad.size()));
  double delta = 0.0;
  for (int p = 0; p < t; ++p) {
    if (p > 0) delta += (width_ratio(p) - 1.0) * table_.width_rad[static_cast<std::size_t>(p)];
    out_rad[static_cast<std::size_t>(p)] = delta;
  }
}

bool ToothErrorLearner::import_table(std::span<const double> edge_rad, int weight_cycles) noexcept {
  const int t = table_.teeth;
  if (static_cast<int>(edge_rad.size()) != t || weight_cycles <= 0) return false;
  for (int p = 0; p < t; ++p) {
    const auto i = static_cast<std::size_t>(p);
    const double prev = edge_rad[static_cast<std::size_t>((p + t - 1) % t)];
    const double w_true = table_.width_rad[i] + edge_rad[i] - prev;
    if (!(w_true > 0.0) || !std::isfinite(w_true)) return false;
    eps_import_[i] = z_of_width_ratio(w_true / table_.width_rad[i]);
  }
  import_weight_ = weight_cycles;
  since_solve_ = 0;
  solved_ready_ = ready();
  // Project the imported table on the per-revolution columns (the value an order keeps while nothing
  // identifies it).
  const auto ks = static_cast<std::size_t>(table_.samples);
  for (std::size_t j = 0; j < static_cast<std::size_t>(nb_); ++j) {
    double acc = 0.0;
    if (col_per_rev_[j] != 0) {
      for (std::size_t k = 0; k < ks; ++k)
        acc += pinv_[j * ks + k] * eps_import_[k % static_cast<std::size_t>(t)];
    }
    imp_coef_[j] = acc;
  }
  recompute();
  return true;
}

}  // namespace torqued
