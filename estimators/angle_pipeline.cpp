#include "angle_pipeline.hpp"

#include <cmath>
#include <numbers>

namespace torqued {

namespace {
constexpr double kFourPi = 4.0 * std::numbers::pi;
constexpr double kRadSToRpm = 30.0 / std::numbers::pi;

TorqueEstimate make(std::int64_t t, double v, double sd, Health h) noexcept {
  TorqueEstimate e;
  e.t_ns = t;
  e.torque_nm = std::isfinite(v) ? v : 0.0;
  e.uncertainty = sd;
  e.health = std::isfinite(v) ? h : Health::kNumerical;
  return e;
}
Health worst(Health a, Health b) noexcept { return static_cast<std::uint8_t>(a) > static_cast<std::uint8_t>(b) ? a : b; }
}  // namespace

namespace {
/// The configuration with the friction prior resolved (generic correlation from the displacement unless told).
AnglePipelineConfig resolve_prior(AnglePipelineConfig c) noexcept {
  if (c.friction.prior_from_geometry) {
    const double r = c.engine.crank_radius_m();
    const double vd = std::numbers::pi * 0.25 * c.engine.bore_m * c.engine.bore_m * 2.0 * r * c.engine.cylinders;
    c.friction.c = generic_friction_prior(vd, c.friction.sign);
  }
  return c;
}
}  // namespace

AnglePipeline::AnglePipeline(const AnglePipelineConfig& config)
    : cfg_(resolve_prior(config)),
      energy_(config.engine, config.wheel, config.energies),
      wide_(energy_, config.energies.cycle_ke_window_deg, 0.5 * config.energies.energy_window_deg),
      rls_(config.engine, config.wheel, config.energies),
      friction_(cfg_.friction),
      eso_(config.engine, config.energies),
      cyl_(config.engine, config.cylinder),
      fusion_(config.fusion),
      pre_(config.engine, config.wheel, config.preprocess),
      kalman_(config.engine, config.wheel, config.kalman),
      fourier_(config.engine, config.wheel, config.fourier) {
  // CF-14: refuse unstable Fourier gains (the config loader reports the reason; here the method is just off).
  fourier_ok_ = config.run_fourier && !FourierObserver::check_stability(config.fourier, config.engine, config.wheel);
  reset();
}

void AnglePipeline::reset() noexcept {
  energy_.reset();
  wide_.reset();
  rls_.reset();
  eso_.reset();
  cyl_.reset();
  fusion_.reset();
  pre_.reset();
  kalman_.reset();
  fourier_.reset();
  load_star_nm_ = 0.0;
  // The friction learner keeps what it learned (persisted state); call friction().reset() to forget.
  tooth_ = ToothOutput{};
  cycle_ = CycleOutput{};
  stats_ = AnglePipelineStats{};
  cyl_work_j_.fill(0.0);
  cyl_work_ok_.fill(false);
  oil_c_ = cfg_.default_oil_temp_c;
  have_prev_ = false;
  cut_segments_ = fired_segments_ = 0;
  since_cut_segments_ = 1 << 30;  // no fuel cut-off seen yet
  idle_steady_cycles_ = 0;
  prev_cycle_rpm_ = 0.0;
  brake_var_ = 4.0;
  have_prev_brake_ = false;
  have_prev_load_ = false;
  held_map_pa_ = 0.0;
  have_map_ = false;
  held_spark_deg_ = std::nan("");
}

std::uint8_t AnglePipeline::on_tooth(const ToothSample& s, const EngineSignals& sig) noexcept {
  ++stats_.teeth;
  if (!s.synced) {
    ++stats_.not_synced;
    have_prev_ = false;
    pre_.update(s);
    if (cfg_.run_kalman) kalman_.update(s);
    if (fourier_ok_) fourier_.update(s);
    energy_.update(s, 0.0, false);
    wide_.update(s);
    rls_.update(s, 0.0, false, 0.0, cyl_work_j_, false);
    tooth_.valid = false;
    return 0;
  }
  if (!(s.dt_s > 0.0) || !(s.width_rad > 0.0) || !std::isfinite(s.dt_s) || !std::isfinite(s.width_rad) ||
      s.tooth < 0 || s.tooth >= energy_.samples()) {
    ++stats_.invalid;
    have_prev_ = false;
    ToothSample bad = s;
    bad.synced = false;  // breaks the sequence in the estimators
    pre_.update(bad);
    if (cfg_.run_kalman) kalman_.update(bad);
    if (fourier_ok_) fourier_.update(bad);
    energy_.update(bad, 0.0, false);
    wide_.update(bad);
    rls_.update(bad, 0.0, false, 0.0, cyl_work_j_, false);
    tooth_.valid = false;
    return 0;
  }
  std::uint8_t ready = kToothReady;
  const double speed = s.width_rad / s.dt_s;
  tooth_.t_ns = s.t_ns;
  tooth_.tooth = s.tooth;
  tooth_.angle_rad = s.angle_rad;
  tooth_.speed_rad_s = speed;
  pre_.update(s);
  const ToothKinematics& kin = pre_.state();
  tooth_.accel_rad_s2 = kin.valid ? kin.accel_rad_s2
                                  : (have_prev_ ? (speed - prev_speed_) / (0.5 * (s.dt_s + prev_dt_)) : 0.0);
  tooth_.speed_lp_rad_s = kin.valid ? kin.speed_lp_rad_s : speed;
  tooth_.valid = have_prev_;
  // In-cycle observers (Chauvin): they estimate the net torque; the extended load turns it into T_ind.
  if (cfg_.run_kalman) {
    kalman_.set_extended_load(load_star_nm_);
    kalman_.update(s);
    copy_estimate(tooth_.kalman_ind, kalman_.estimate());
  } else {
    tooth_.kalman_ind.health = Health::kDisabled;
  }
  if (fourier_ok_) {
    fourier_.set_extended_load(load_star_nm_);
    fourier_.update(s);
    copy_estimate(tooth_.fourier_ind, fourier_.estimate());
  } else {
    tooth_.fourier_ind.health = Health::kDisabled;
  }
  prev_speed_ = speed;
  prev_dt_ = s.dt_s;
  have_prev_ = true;

  if (sig.oil_temp_valid && std::isfinite(sig.oil_temp_c)) oil_c_ = sig.oil_temp_c;
  const bool can_fresh = static_cast<double>(s.t_ns - sig.t_ns) * 1e-9 <= cfg_.fusion.max_can_age_s;
  const bool load_ok = can_fresh && sig.load_torque_valid && std::isfinite(sig.load_torque_nm);

  bool works_ok = true;
  for (int m = 0; m < cfg_.engine.cylinders; ++m) works_ok = works_ok && cyl_work_ok_[static_cast<std::size_t>(m)];
  // CAN lost: the RLS keeps running on the last MAP / spark advance it saw (they move slowly at a steady
  // operating point); the fusion marks the result crank-only with can_lost set.
  if (can_fresh && sig.map_valid && std::isfinite(sig.map_pa)) {
    held_map_pa_ = sig.map_pa;
    have_map_ = true;
  }
  if (can_fresh && sig.spark_valid && std::isfinite(sig.spark_advance_deg)) held_spark_deg_ = sig.spark_advance_deg;
  rls_.update(s, held_map_pa_, have_map_, held_spark_deg_, cyl_work_j_, works_ok);

  wide_done_ = wide_.update(s);  // completes on the same tooth as boundary 0's per-cylinder window
  const std::uint64_t breaks_before = energy_.breaks();
  if (energy_.update(s, sig.load_torque_nm, load_ok)) {
    on_segment(energy_.segment(), sig, can_fresh);
    ready = static_cast<std::uint8_t>(ready | kSegmentReady);
    if (cycle_.cycle_end) ready = static_cast<std::uint8_t>(ready | kCycleReady);
  }
  stats_.sequence_breaks += energy_.breaks() - breaks_before;
  return ready;
}

void AnglePipeline::on_segment(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh) noexcept {
  ++stats_.segments;
  const int n = cfg_.engine.cylinders;
  const bool cut_known = can_fresh && sig.fuel_cutoff_valid;
  const bool fired = !(cut_known && sig.fuel_cutoff);
  if (fired) {
    ++fired_segments_;
    ++since_cut_segments_;
    cut_segments_ = 0;
  } else {
    ++cut_segments_;
    fired_segments_ = 0;
    since_cut_segments_ = 0;
  }
  CycleOutput o;
  o.t_ns = seg.t_ns;
  o.seq = cycle_.seq + 1;
  o.boundary = seg.boundary;
  o.cycle_end = seg.boundary == 0;
  o.cylinders = cycle_.cylinders;

  const TorqueEstimate rls = rls_.estimate();
  o.load_rls = rls;
  const bool rls_ok = rls.health == Health::kValid;

  // --- Segment work (per-cylinder measure) and ESO ---------------------------------------------------------------
  const double seg_rpm = seg.speed_rad_s * kRadSToRpm;
  const double fric_seg = friction_.friction_nm(seg_rpm, oil_c_);
  double seg_load_star = 0.0;
  bool seg_ok = seg.segment_valid;
  if (seg.load_valid) {
    seg_load_star = seg.load_mean_nm + fric_seg;
  } else if (rls_ok) {
    seg_load_star = rls.torque_nm;
  } else {
    seg_ok = false;
  }
  const double work = seg.d_ke_segment_j + seg_load_star * seg.segment_rad;
  const auto pos = static_cast<std::size_t>(seg.ended_position);
  if (seg_ok) {
    cyl_work_j_[pos] = work;  // the segment holds this cylinder's whole-cycle net work (see CylinderTorque)
    cyl_work_ok_[pos] = true;
  } else {
    cyl_work_ok_[pos] = false;
  }
  // Per-cylinder work per cycle = segment work (its share of the cycle); CylinderTorque divides by 4π.
  // Misfire decisions only after two firing cycles: the CAN flag leads the injections that actually resume.
  if (cyl_.on_segment(seg.t_ns, seg.ended_position, work, seg_ok, fired && fired_segments_ > 2 * n)) {
    o.cylinders = cyl_.cycle();
    stats_.misfires = cyl_.misfires();
    ++stats_.cycles;
  }

  EsoInput ein;
  ein.t_ns = seg.t_ns;
  ein.ke_j = seg.ke_j;
  ein.segment_rad = seg.segment_rad;
  ein.segment_dt_s = seg.segment_dt_s;
  ein.fuel_kg = fired ? sig.fuel_mass_kg : 0.0;
  ein.lambda = sig.lambda_valid ? sig.lambda : 1.0;
  ein.friction_nm = fric_seg;
  ein.load_nm = seg.load_valid ? seg.load_mean_nm : rls.torque_nm - fric_seg;
  ein.valid = seg.segment_valid && can_fresh && sig.fuel_mass_valid && (seg.load_valid || rls_ok);
  eso_.update(ein);
  o.indicated_eso = eso_.estimate();

  // --- Rolling 720° balance ---------------------------------------------------------------------------------------
  if (!seg.cycle_valid) {
    o.brake = o.indicated = o.friction = o.load = o.brake_energy = o.indicated_crank = make(seg.t_ns, 0.0, 0.0, Health::kNotConverged);
    o.fused = fusion_.estimate();
    cycle_ = o;
    return;
  }
  o.speed_mean_rad_s = kFourPi / seg.cycle_dt_s;
  const double rpm = o.speed_mean_rad_s * kRadSToRpm;
  // Δ(½Jθ̇²)/4π; at boundary 0 from the wide window when it completed here (jitter noise / ≈ 4, CycleKeWindow)
  const bool wide = o.cycle_end && wide_done_ && wide_.cycle_valid();
  const double dke_nm = (wide ? wide_.d_ke_cycle_j() : seg.d_ke_cycle_j) / kFourPi;
  const double fric = friction_.friction_nm(rpm, oil_c_);
  const Health fric_h = friction_.health();
  o.friction = make(seg.t_ns, fric, 2.0, fric_h);

  // Energy balance with the measured load: the brake torque needs no friction model.
  const bool can_load = seg.cycle_load_valid;
  if (can_load) {
    const double brake = dke_nm + seg.cycle_load_mean_nm;
    if (have_prev_brake_) {
      const double d = brake - prev_brake_;
      brake_var_ += 0.05 * (0.5 * d * d - brake_var_);
    }
    prev_brake_ = brake;
    have_prev_brake_ = true;
    o.brake_energy = make(seg.t_ns, brake, std::sqrt(brake_var_) + 0.5, Health::kValid);
  } else {
    o.brake_energy = make(seg.t_ns, 0.0, 0.0, Health::kStaleInput);
  }
  // Crank only: indicated from the extended load tracked through load changes (LoadRls rule 4; the plain RLS lags).
  const TorqueEstimate trk = rls_.tracked();
  o.indicated_crank = make(seg.t_ns, dke_nm + trk.torque_nm, trk.uncertainty + 1.0, trk.health);

  if (can_load) {
    o.load = make(seg.t_ns, seg.cycle_load_mean_nm, 0.5, Health::kValid);
    o.brake = o.brake_energy;
    o.indicated = make(seg.t_ns, o.brake_energy.torque_nm + fric, o.brake_energy.uncertainty + 2.0, fric_h);
  } else {
    o.load = make(seg.t_ns, trk.torque_nm - fric, trk.uncertainty + 2.0, worst(trk.health, fric_h));
    o.indicated = o.indicated_crank;
    o.brake = make(seg.t_ns, o.indicated_crank.torque_nm - fric, o.indicated_crank.uncertainty + 2.0,
                   worst(rls.health, fric_h));
  }

  // Extended load for the in-cycle observers: measured load + friction, or the RLS estimate without CAN.
  load_star_nm_ = can_load ? seg.cycle_load_mean_nm + fric : rls.torque_nm;

  // --- Friction learning (EN-24..36) -------------------------------------------------------------------------------
  // Fuel cut-off for the whole window (+1 segment margin for the CAN flag's delay): T_ind = motored (pumping)
  // torque, so T_fric = T_motored − Δ(½Jθ̇²)/4π − T_load.
  const bool load_steady = have_prev_load_ && std::fabs(seg.cycle_load_mean_nm - prev_load_) <= cfg_.friction.max_load_change_nm;
  prev_load_ = seg.cycle_load_mean_nm;
  have_prev_load_ = can_load;
  if (cut_segments_ > n + 1 && can_load && load_steady && sig.map_valid) {
    const double obs = rls_.motored_torque_nm(sig.map_pa) - dke_nm - seg.cycle_load_mean_nm;
    if (friction_.observe_motoring(rpm, oil_c_, obs)) ++stats_.friction_observations;
  }
  // Idle: no load, firing, RLS converged -> its extended load is the friction (EN-30..33 learn C4 from it).
  // The same value sets the friction learner's local idle correction (below the fuel cut-off resume speed, which
  // motoring observations never reach). Only with a tight, settled RLS (tooth errors learned, 1σ < 1.5 N m,
  // 25 firing cycles after a fuel cut-off so that its memory holds no coasting windows).
  // Steady idle only: the RLS remembers ≈ 10 cycles, so the speed (±3 %) and load must have held for
  // friction.idle_steady_cycles cycles (idle-controller undershoots and ramps through idle gave ±1.5 N m outliers).
  if (o.cycle_end) {
    const bool steady = rpm < cfg_.energies.idle_max_rpm && can_load && load_steady &&
                        std::fabs(rpm - prev_cycle_rpm_) < 0.03 * rpm;
    idle_steady_cycles_ = steady ? idle_steady_cycles_ + 1 : 0;
    prev_cycle_rpm_ = rpm;
  }
  if (o.cycle_end && fired_segments_ > n && since_cut_segments_ > 25 * n && can_load && rls_ok && rls.uncertainty < 1.5 &&
      idle_steady_cycles_ >= cfg_.friction.idle_steady_cycles &&
      rpm < cfg_.energies.idle_max_rpm &&
      std::fabs(seg.cycle_load_mean_nm) < cfg_.energies.idle_max_load_nm) {
    const double idle_fric = rls.torque_nm - seg.cycle_load_mean_nm;
    friction_.observe_idle(rpm, oil_c_, idle_fric);  // C4 (EN-30..33) and the local idle correction
  }

  // --- Fusion -------------------------------------------------------------------------------------------------------
  FusionInput fin;
  fin.t_ns = seg.t_ns;
  fin.can_t_ns = sig.t_ns;
  fin.can_seen = sig.t_ns != 0 || sig.load_torque_valid || sig.map_valid;
  FusionSource& e = fin.src[static_cast<std::size_t>(FusionSourceId::kEnergyCan)];
  e.brake_nm = o.brake_energy.torque_nm;
  e.sd_nm = o.brake_energy.uncertainty > 0.0 ? o.brake_energy.uncertainty : 1.0;
  e.health = o.brake_energy.health;
  e.uses_can = true;
  e.newest_input_ns = seg.t_ns < sig.t_ns ? seg.t_ns : sig.t_ns;
  FusionSource& c = fin.src[static_cast<std::size_t>(FusionSourceId::kCrankOnly)];
  c.brake_nm = o.indicated_crank.torque_nm - fric;
  c.sd_nm = o.indicated_crank.uncertainty + 2.0;
  c.health = worst(rls.health, fric_h);
  c.uses_can = false;
  c.newest_input_ns = seg.t_ns;
  FusionSource& z = fin.src[static_cast<std::size_t>(FusionSourceId::kEso)];
  z.brake_nm = o.indicated_eso.torque_nm - fric;
  z.sd_nm = o.indicated_eso.uncertainty + 2.0;
  z.health = worst(o.indicated_eso.health, fric_h);
  z.uses_can = true;
  z.newest_input_ns = sig.t_ns;
  fin.src[static_cast<std::size_t>(FusionSourceId::kExternal)] = external_;
  o.fused = fusion_.update(fin);
  cycle_ = o;
}

}  // namespace torqued
