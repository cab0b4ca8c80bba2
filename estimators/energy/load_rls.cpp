#include "load_rls.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "crank_kinematics.hpp"
#include "cycle_energy.hpp"
#include "load_rls_model.hpp"
#include "table_cache.hpp"

namespace torqued {

using namespace load_rls_model;  // NOLINT(google-build-using-namespace): this file's own model

LoadRls::LoadRls(const EngineGeometry& engine, const WheelGeometry& wheel, const EnergiesParams& params,
                 bool spark_on_can)
    : engine_(engine), params_(params), kappa_(params.polytropic_kappa) {
  ripple_range(spark_on_can);
  const CrankKinematics kin(engine);
  v_c_ = kin.clearance_volume_m3();
  v_ivc_ = kin.volume((540.0 + params.ivc_abdc_deg) * kDeg);
  rip_motored_ = std::pow(v_ivc_ / v_c_, ripple_kappas(params).comp);
  std::vector<double> e1, w1;
  nominal_wheel_edges(wheel, e1, w1);
  const int t = wheel.teeth();
  samples_ = 2 * t;
  std::vector<double> center(static_cast<std::size_t>(samples_));
  for (int k = 0; k < samples_; ++k) {
    const int rev = k / t;  // whole revolutions before sample k
    const double e = rev * kTwoPi + e1[static_cast<std::size_t>(k % t)];
    center[static_cast<std::size_t>(k)] =
        wrap4pi(e - 0.5 * w1[static_cast<std::size_t>(k % t)] - engine.tdc_offset_rad);
  }
  const std::uint64_t key = tables_key(center);
  std::vector<double> flat;
  const bool cached = cached_table("load-rls", key, flat, 0, [&](std::vector<double>& tab) {
    build_tables(kin, center);
    pack_tables(tab);
  });
  if (cached && !unpack_tables(flat)) build_tables(kin, center);  // cannot happen with a checked cache
  open_.assign(windows_tab_.size(), 0);
  ke_first_.assign(windows_tab_.size(), 0.0);
  w2_first_.assign(windows_tab_.size(), 0.0);
  reset();
}

// Every input of build_tables(): the engine (kinematics, firing positions), the tooth-period centres, the
// pressure model's parameters and the windows (the code itself is the cache's part of the key).
std::uint64_t LoadRls::tables_key(const std::vector<double>& center) const noexcept {
  const EngineGeometry& e = engine_;
  const EnergiesParams& p = params_;
  TableKey key;
  key.add(std::string_view("load-rls 3")).add(kMaxCylinders).add(kCentroids).add(samples_).add(center);
  key.add(rip_lo_).add(rip_hi_);
  key.add(e);
  key.add(p.window_start_btdc_deg).add(p.window_end_btdc_deg).add(p.polytropic_kappa).add(p.ivc_abdc_deg);
  key.add(p.evo_atdc_deg).add(p.blowdown_end_atdc_deg).add(p.exhaust_pressure_pa).add(p.ivc_pressure_factor);
  key.add(p.rls_window_shifts).add(p.burn_centroid_atdc_deg).add(p.burn_duration_deg);
  key.add(p.incycle_compression_kappa).add(p.incycle_expansion_kappa).add(p.burn_wiebe_a).add(p.burn_wiebe_m);
  return key.value();
}

// The tables gas_ripple_nm() / ripple_p3() can be asked for: ripple_table() of every centroid the pipeline
// can use (AnglePipeline::ripple_centroid_deg: centroid_deg()'s clamp range with a spark advance, else the
// clamped fixed centroid; without spark phasing the base table), the upper one only where it gets a weight,
// and the base table (the pipeline's start value).
void LoadRls::ripple_range(bool spark_on_can) noexcept {
  rip_lo_ = rip_hi_ = kRippleBase;
  if (!params_.incycle_spark_phasing) return;
  const double fixed = centroid_deg(std::nan(""));
  const double lo = spark_on_can ? 0.0 : fixed, hi = spark_on_can ? kCentroids - 1.0 : fixed;
  int t = 0;
  double f = 0.0;
  table_pair(lo, 0, kRippleTables - 1, t, f);  // t grows with the centroid
  rip_lo_ = std::min(rip_lo_, t);
  table_pair(hi, 0, kRippleTables - 1, t, f);
  rip_hi_ = std::max(rip_hi_, f > 0.0 ? t + 1 : t);
}

void LoadRls::table_pair(double centroid_deg, int lo, int hi, int& t, double& frac) const noexcept {
  const double x = std::isfinite(centroid_deg)
                       ? kRippleBase + (centroid_deg - params_.burn_centroid_atdc_deg) / kRippleStepDeg
                       : static_cast<double>(kRippleBase);
  const double c = std::clamp(x, static_cast<double>(lo), static_cast<double>(hi));
  t = std::min(static_cast<int>(c), std::max(lo, hi - 1));
  frac = c - t;
}

void LoadRls::ripple_table(double centroid_deg, int& t, double& frac) const noexcept {
  // Within the tables built (ripple_first/last): a centroid they cannot reach (a spark advance given to a
  // model built without one) reads the nearest built table, never an unbuilt (zero) one.
  table_pair(centroid_deg, rip_lo_, rip_hi_, t, frac);
}

void LoadRls::ripple_p3(double map_pa, const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid,
                        std::array<double, kMaxCylinders>& p3_pa, int t) const noexcept {
  const auto tt = static_cast<std::size_t>(std::clamp(t, rip_lo_, rip_hi_));  // the pair's unused upper one
  for (int q = 0; q < engine_.cylinders; ++q) {
    const auto qi = static_cast<std::size_t>(q);
    p3_pa[qi] = works_valid ? (cyl_work_j[qi] - rip_cm_[tt] * map_pa - rip_ce_[tt]) / rip_cp_[tt]
                            : params_.ivc_pressure_factor * map_pa * rip_motored_;
  }
}

void LoadRls::reset() noexcept {
  std::fill(open_.begin(), open_.end(), 0);
  expected_tooth_ = -1;
  theta_ = {engine_.j_rot_kgm2, 0.0};
  p_ = {1e-4, 0.0, 0.0, 1e6};
  resid_var_ = 0.0;
  windows_ = 0;
  est_ = TorqueEstimate{};
  grp_sum_.fill(0.0);
  grp_n_.fill(0);
  hist_head_ = hist_count_ = 0;
  z_cycle_ = 0.0;
  z_valid_ = false;
  d_var_ = 0.0;
  zd_var_ = 0.0;
  d_n_ = 0;
  blend_ = 0.0;
  hold_groups_ = 0;
  load_changes_ = 0;
  fast_windows_ = 0;
  cusum_pos_ = cusum_neg_ = 0.0;
  trk_theta_ = 0.0;
  trk_p_ = 1e6;
  trk_ = TorqueEstimate{};
}

namespace {
constexpr int kFastCycles = 4;  // tracker memory held at one cycle for this many cycles after a load change
constexpr double kZConfirm = 2.5;  // |z − tracker| must exceed this many σ of its steady spread
constexpr int kStatsCycles = 10;   // steady cycles of innovation statistics before changes are detected
}  // namespace

void LoadRls::track(double obs, const Window& win) noexcept {
  const auto m = static_cast<std::size_t>(win.position);
  grp_sum_[m] += obs;
  ++grp_n_[m];
  if (!win.closes_group) return;
  const int n = engine_.cylinders;
  const double h = grp_sum_[m] / grp_n_[m];
  grp_sum_[m] = 0.0;
  grp_n_[m] = 0;
  constexpr int kHist = kMaxCylinders + 1;
  hist_head_ = (hist_head_ + 1) % kHist;
  hist_[static_cast<std::size_t>(hist_head_)] = h;
  hist_count_ = std::min(hist_count_ + 1, n + 1);
  if (hist_count_ < n + 1) return;
  // Trapezoid over the n firing intervals spanned by the last n + 1 firings (the same 720° as the energy
  // balance).
  double z = 0.0;
  for (int j = 0; j <= n; ++j) {
    const double v = hist_[static_cast<std::size_t>((hist_head_ - j + kHist) % kHist)];
    z += (j == 0 || j == n) ? 0.5 * v : v;
  }
  z_cycle_ = z / n;
  z_valid_ = true;
  if (params_.rls_change_threshold <= 0.0) return;  // rule 4 off: the RLS alone
  // Two-sided CUSUM (Page) on the per-firing innovations e = h − RLS in units of their steady 1σ: persistent
  // shifts add up, zero-mean noise drains by the allowance of 0.5σ per firing.
  const double e = h - trk_theta_;
  const double floor_sd = params_.rls_step_min_sd_nm;
  const double sd = std::sqrt(std::max(d_var_, floor_sd * floor_sd));
  const bool ready =
      windows_ >= static_cast<std::uint64_t>(params_.rls_min_windows) && d_n_ >= kStatsCycles * n;
  constexpr double kAllowance = 0.5;
  cusum_pos_ = std::max(0.0, cusum_pos_ + e / sd - kAllowance);
  cusum_neg_ = std::max(0.0, cusum_neg_ - e / sd - kAllowance);
  // The cycle mean must also have left the tracker by 3σ of its own steady spread: z − RLS is correlated from
  // firing to firing (z spans n + 1 firings, and at 4000 rpm the jitter noise wanders over several cycles),
  // which alone would let the CUSUM fire on noise.
  const double zd = z_cycle_ - trk_theta_;
  const double zsd = std::sqrt(std::max(zd_var_, floor_sd * floor_sd));
  // Only where the cycle mean is informative: at high speed its jitter noise (±10-20 N m at 4000 rpm) is
  // larger than the changes worth tracking, and the RLS average is the better value even in transients.
  const bool informative = zsd <= params_.rls_change_max_sd_nm;
  if (ready && informative && std::fabs(zd) > kZConfirm * zsd &&
      (cusum_pos_ > params_.rls_change_threshold || cusum_neg_ > params_.rls_change_threshold)) {
    // A load change: restart the tracker's memory at the cycle mean (worth one cycle of windows) and report
    // the cycle mean for one cycle.
    trk_theta_ = z_cycle_;
    trk_p_ = 1.0 / std::max(1.0, static_cast<double>(windows_tab_.size()));
    fast_windows_ = kFastCycles * static_cast<int>(windows_tab_.size());
    blend_ = 1.0;
    hold_groups_ = n;
    cusum_pos_ = cusum_neg_ = 0.0;
    ++load_changes_;
    return;
  }
  if (hold_groups_ > 0) {
    --hold_groups_;
    blend_ = 1.0;
    cusum_pos_ = cusum_neg_ = 0.0;
    return;
  }
  blend_ = 0.0;
  if (std::fabs(e) > 3.0 * sd && d_n_ >= kStatsCycles * n)
    return;  // an outlier or a change: not a steady sample
  ++d_n_;
  const double a = std::max(1.0 / d_n_, 0.05);
  d_var_ += a * (e * e - d_var_);
  zd_var_ += a * (zd * zd - zd_var_);
}

double LoadRls::centroid_deg(double spark_advance_deg) const noexcept {
  const double c = std::isfinite(spark_advance_deg) ? params_.burn_delay_deg - spark_advance_deg
                                                    : params_.burn_centroid_atdc_deg;
  return std::clamp(c, 0.0, static_cast<double>(kCentroids - 1));
}

double LoadRls::expansion_p3(double work_j, double map_pa, double spark_advance_deg) const noexcept {
  // Linear interpolation of the closure coefficients in the burn centroid.
  const double c = centroid_deg(spark_advance_deg);
  const int i = std::min(static_cast<int>(c), kCentroids - 2);
  const double f = c - i;
  const auto ii = static_cast<std::size_t>(i);
  const double cm = cyc_map_[ii] + f * (cyc_map_[ii + 1] - cyc_map_[ii]);
  const double cp = cyc_p3_[ii] + f * (cyc_p3_[ii + 1] - cyc_p3_[ii]);
  return (work_j - cm * map_pa - cyc_exh_ * params_.exhaust_pressure_pa) / cp;
}

double LoadRls::model_pressure(double local_rad, double map_pa, double p3_pa,
                               double spark_advance_deg) const noexcept {
  const CrankKinematics kin(engine_);
  const Weights w =
      model_weights(angle_terms(wrap4pi(local_rad), kin, params_, v_ivc_, v_c_, closure_kappas(params_)),
                    params_, centroid_deg(spark_advance_deg) * kDeg);
  return w.map * map_pa + w.exh * params_.exhaust_pressure_pa + w.p3 * p3_pa;
}

double LoadRls::motored_p3(double map_pa) const noexcept {
  // Motored: the compression end state p_IVC (V_IVC/V_c)^κ expands back along the same polytrope.
  return params_.ivc_pressure_factor * map_pa * std::pow(v_ivc_ / v_c_, kappa_);
}

double LoadRls::motored_torque_nm(double map_pa) const noexcept {
  // Motored: no heat release, the centroid does not matter (use 0).
  const double w =
      cyc_map_[0] * map_pa + cyc_exh_ * params_.exhaust_pressure_pa + cyc_p3_[0] * motored_p3(map_pa);
  return engine_.cylinders * w / kFourPi;
}

double LoadRls::window_gas_work(int w, double map_pa,
                                const std::array<double, kMaxCylinders>& p3_pa) const noexcept {
  const Window& win = windows_tab_[static_cast<std::size_t>(w)];
  double work =
      win.k_map * map_pa + win.k_exh * params_.exhaust_pressure_pa + win.k_cc * engine_.crankcase_pressure_pa;
  for (int q = 0; q < engine_.cylinders; ++q)
    work += win.k_p3[static_cast<std::size_t>(q)] * p3_pa[static_cast<std::size_t>(q)];
  return work;
}

// One RLS step on the window's observation y (N m) with angle-mean θ̈ phi_a (rad/s²); returns the a-priori
// error.
double LoadRls::rls_step(double y, double phi_a) noexcept {
  const double lam = params_.rls_forgetting;
  double err;
  if (params_.rls_estimate_inertia) {
    // EN-15: Q = P ψ (λ + ψᵀPψ)⁻¹, Θ += Q (y − ψᵀΘ), P = (P − Q ψᵀ P)/λ, ψ = [θ̈, 1].
    const double psi0 = phi_a, psi1 = 1.0;
    const double pp0 = p_[0] * psi0 + p_[1] * psi1, pp1 = p_[2] * psi0 + p_[3] * psi1;
    const double den = lam + psi0 * pp0 + psi1 * pp1;
    err = y - (psi0 * theta_[0] + psi1 * theta_[1]);
    last_obs_ = y - theta_[0] * psi0;
    const double q0 = pp0 / den, q1 = pp1 / den;
    theta_[0] += q0 * err;
    theta_[1] += q1 * err;
    const double n00 = (p_[0] - q0 * pp0) / lam, n01 = (p_[1] - q0 * pp1) / lam;
    const double n11 = (p_[3] - q1 * pp1) / lam;
    p_ = {n00, n01, n01, n11};
  } else {
    // Known J_rot: scalar RLS with forgetting on y − J_rot θ̈ = T_load*.
    const double yy = y - engine_.j_rot_kgm2 * phi_a;
    last_obs_ = yy;
    err = yy - theta_[1];
    const double den = lam + p_[3];
    const double q = p_[3] / den;
    theta_[1] += q * err;
    p_[3] = (p_[3] - q * p_[3]) / lam;
  }
  return err;
}

// After a window: residual variance, the tracker RLS (rule 4), the estimates and their uncertainties.
void LoadRls::publish(std::int64_t t_ns, double err, const Window& win) noexcept {
  const double lam = params_.rls_forgetting;
  ++windows_;
  const double a = windows_ < 20 ? 1.0 / static_cast<double>(windows_) : 0.05;
  resid_var_ += a * (err * err - resid_var_);
  // Tracker RLS (rule 4): the same scalar recursion on the same observation, re-seeded at load changes.
  {
    const double yt = last_obs_;
    const double q = trk_p_ / (lam + trk_p_);
    trk_theta_ += q * (yt - trk_theta_);
    trk_p_ = (trk_p_ - q * trk_p_) / lam;
    if (fast_windows_ > 0) {
      // After a load change the load keeps moving (dyno controller settling): hold the memory at one cycle of
      // windows for a few cycles, then let it grow back to the RLS memory.
      --fast_windows_;
      trk_p_ = std::max(trk_p_, 1.0 / std::max(1.0, static_cast<double>(windows_tab_.size())));
    }
  }
  track(last_obs_, win);
  est_.t_ns = t_ns;
  est_.torque_nm = theta_[1];
  // Effective sample count of the forgetting factor: (1 + λ)/(1 − λ).
  const double n_eff = std::min<double>(static_cast<double>(windows_), (1.0 + lam) / (1.0 - lam));
  const double sd_rls = std::sqrt(resid_var_ / n_eff);
  est_.uncertainty = sd_rls;
  est_.health = windows_ >= static_cast<std::uint64_t>(params_.rls_min_windows) ? Health::kValid
                                                                                : Health::kNotConverged;
  trk_ = est_;
  if (z_valid_ && blend_ > 0.0) {
    const double floor_sd = params_.rls_step_min_sd_nm;
    trk_.torque_nm = z_cycle_;
    trk_.uncertainty = std::sqrt(std::max(d_var_, floor_sd * floor_sd));
  } else {
    trk_.torque_nm = trk_theta_;
  }
}

bool LoadRls::update(const ToothSample& s, double map_pa, bool map_valid, double spark_advance_deg,
                     const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid) noexcept {
  if (!s.synced || s.tooth < 0 || s.tooth >= samples_ || !(s.dt_s > 0.0) || !(s.width_rad > 0.0)) {
    restart(s.synced && s.tooth >= 0 && s.tooth < samples_ ? (s.tooth + 1) % samples_ : -1);
    return false;
  }
  return update_checked(s, map_pa, map_valid, spark_advance_deg, cyl_work_j, works_valid);
}

// A hole in the tooth sequence: no window or cycle mean across it.
void LoadRls::restart(int expected_tooth) noexcept {
  std::fill(open_.begin(), open_.end(), 0);
  expected_tooth_ = expected_tooth;
  grp_sum_.fill(0.0);  // no cycle mean across a hole
  grp_n_.fill(0);
  hist_count_ = 0;
  z_valid_ = false;
  blend_ = 0.0;
}

// update() after its sample checks (AnglePipeline::on_tooth makes them, and more, once per tooth).
bool LoadRls::update_checked(const ToothSample& s, double map_pa, bool map_valid, double spark_advance_deg,
                             const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid) noexcept {
  const int next = s.tooth + 1 == samples_ ? 0 : s.tooth + 1;  // (tooth + 1) mod samples_
  if (expected_tooth_ >= 0 && s.tooth != expected_tooth_) {
    restart(next);
    return false;
  }
  expected_tooth_ = next;
  const auto k = static_cast<std::size_t>(s.tooth);
  const double w2 = (s.width_rad / s.dt_s) * (s.width_rad / s.dt_s);
  const int opened = window_first_of_[k];
  if (opened >= 0) {
    const auto oi = static_cast<std::size_t>(opened);
    open_[oi] = 1;
    ke_first_[oi] = 0.5 * (windows_tab_[oi].j_first - engine_.j_rot_kgm2) * w2;
    w2_first_[oi] = w2;
  }
  const int closed = window_last_of_[k];
  if (closed < 0 || !open_[static_cast<std::size_t>(closed)]) return false;
  const auto ci = static_cast<std::size_t>(closed);
  open_[ci] = 0;
  if (!map_valid || !std::isfinite(map_pa)) {
    est_.health = Health::kStaleInput;
    return false;
  }
  const Window& win = windows_tab_[static_cast<std::size_t>(closed)];
  std::array<double, kMaxCylinders> p3{};
  for (int q = 0; q < engine_.cylinders; ++q) {
    const auto qi = static_cast<std::size_t>(q);
    p3[qi] = params_.model_expansion_cylinder && works_valid
                 ? expansion_p3(cyl_work_j[qi], map_pa, spark_advance_deg)
                 : motored_p3(map_pa);
    if (!params_.model_expansion_cylinder)
      p3[qi] = 0.0;  // paper's simplification: no other cylinder's gas torque
  }
  // Paper's simplification keeps only the compressing cylinder: drop every cylinder's expansion/exhaust
  // terms.
  double gas = window_gas_work(closed, map_pa, p3);
  if (!params_.model_expansion_cylinder) gas -= win.k_exh * params_.exhaust_pressure_pa;
  const double ke_rel = 0.5 * (win.j_last - engine_.j_rot_kgm2) * w2 - ke_first_[ci];
  const double y = (gas - ke_rel) / win.span;                  // energy form of EN-11
  const double phi_a = 0.5 * (w2 - w2_first_[ci]) / win.span;  // angle-mean θ̈ (rad/s²)
  if (!std::isfinite(y) || !std::isfinite(phi_a)) {
    est_.health = Health::kInvalidInput;
    return false;
  }
  last_y_ = y;
  const double err = rls_step(y, phi_a);
  if (!std::isfinite(theta_[0]) || !std::isfinite(theta_[1])) {
    reset();
    est_.health = Health::kNumerical;
    return false;
  }
  publish(s.t_ns, err, win);
  return true;
}

}  // namespace torqued
