#include "angle_pipeline.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>

namespace torqued {

namespace {
/// The fuel model's shared-bias 1σ is the accessories' prior's (one source of truth: can.load_reference).
FuelTorqueParams with_shared_bias(FuelTorqueParams f, const LoadReferenceParams& p) noexcept {
  f.shared_bias_sd_nm = p.accessory_sd_nm;
  return f;
}
constexpr double kFourPi = 4.0 * std::numbers::pi;
constexpr double kRadSToRpm = 30.0 / std::numbers::pi;
/// Misfire decisions only after this many firing cycles (the CAN fuel flag leads the injections that resume).
constexpr int kMisfireArmCycles = 2;

TorqueEstimate make(std::int64_t t, double v, double sd, Health h) noexcept {
  TorqueEstimate e;
  e.t_ns = t;
  e.torque_nm = std::isfinite(v) ? v : 0.0;
  e.uncertainty = sd;
  e.health = std::isfinite(v) ? h : Health::kNumerical;
  return e;
}
Health worst(Health a, Health b) noexcept {
  return static_cast<std::uint8_t>(a) > static_cast<std::uint8_t>(b) ? a : b;
}
}  // namespace

namespace {
/// The configuration with the friction prior resolved (generic correlation from the displacement unless
/// told).
AnglePipelineConfig resolve_prior(AnglePipelineConfig c) noexcept {
  if (c.friction.prior_from_geometry) {
    const double r = c.engine.crank_radius_m();
    const double vd =
        std::numbers::pi * 0.25 * c.engine.bore_m * c.engine.bore_m * 2.0 * r * c.engine.cylinders;
    c.friction.c = generic_friction_prior(vd, c.friction.sign);
  }
  c.load_ref.load_sd_nm = c.fusion.can_load_sd_nm;
  return c;
}
/// Firing TDC of each firing position relative to cylinder 1's (rad): 4π·m/n (docs/equations.md §0).
std::array<double, kMaxCylinders> firing_tdcs(const EngineGeometry& e) noexcept {
  std::array<double, kMaxCylinders> t{};
  for (int m = 0; m < e.cylinders && m < kMaxCylinders; ++m)
    t[static_cast<std::size_t>(m)] = kFourPi * m / e.cylinders;
  return t;
}
}  // namespace

AnglePipeline::AnglePipeline(const AnglePipelineConfig& config)
    : cfg_(resolve_prior(config)),
      energy_(config.engine, config.wheel, config.energies),
      wide_(energy_, config.energies.cycle_ke_window_deg, 0.5 * config.energies.energy_window_deg),
      cyl_energy_(config.engine, config.wheel, config.energies,
                  config.energies.cylinder_window_deg > 0.0 ? config.energies.cylinder_window_deg
                                                            : config.energies.energy_window_deg,
                  0.5 * config.energies.energy_window_deg, config.energies.cylinder_window_taper),
      rls_(config.engine, config.wheel, config.energies, config.spark_on_can),
      friction_(cfg_.friction),
      inertia_(config.energies.inertia),
      eso_(config.engine, config.energies),
      fuel_(config.engine, with_shared_bias(config.fuel, config.load_ref)),
      fuel_win_(config.engine.cylinders, firing_tdcs(config.engine), config.fuel.intake_btdc_deg,
                config.fuel.work_centroid_atdc_deg, config.fuel.report_window_s),
      cyl_(config.engine, config.cylinder),
      fusion_(config.fusion),
      pre_(config.engine, config.wheel, config.preprocess),
      kalman_(config.engine, config.wheel, config.kalman),
      fourier_(config.engine, config.wheel, config.fourier),
      j_mean_kgm2_(mean_inertia_kgm2(config.engine)) {
  // CF-14: refuse unstable Fourier gains (the config loader reports the reason; here the method is just off).
  fourier_ok_ =
      config.run_fourier && !FourierObserver::check_stability(config.fourier, config.engine, config.wheel);
  // The per-cylinder segments' end boundary hands part of a cylinder's expansion to the next segment where
  // it lies before EVO (I6: 120° segments): the published imbalance takes it out (cylinder_torque.hpp).
  const EnergiesParams& en = config.energies;
  cyl_.set_spill(expansion_spill(
      config.engine, en.segment_offset_deg + 720.0 / std::max(config.engine.cylinders, 1),
      en.cylinder_window_deg > 0.0 ? en.cylinder_window_deg : en.energy_window_deg,
      0.5 * en.energy_window_deg, en.cylinder_window_taper, en.burn_centroid_atdc_deg, en.evo_atdc_deg));
  reset();
}

void AnglePipeline::reset() noexcept {
  energy_.reset();
  wide_.reset();
  cyl_energy_.reset();
  rls_.reset();
  eso_.reset();
  fuel_ind_ = TorqueEstimate{};
  fuel_win_.reset();
  cyl_.reset();
  fusion_.reset();
  pre_.reset();
  kalman_.reset();
  fourier_.reset();
  load_star_nm_ = 0.0;
  cut_flag_ = false;
  works_since_fuel_change_ = ~0u;
  have_fired_p3_ = false;
  fired_t_ = ripple_t_ = LoadRls::kRippleBase;
  // The friction and inertia learners keep what they learned (persisted state); call their reset() to forget.
  prev_inertia_ = InertiaPoint{};
  tooth_ = ToothOutput{};
  cycle_ = CycleOutput{};
  stats_ = AnglePipelineStats{};
  cyl_work_j_.fill(0.0);
  ripple_p3_ok_ = false;
  ripple_pair_ok_ = false;
  cyl_work_ok_.fill(false);
  works_all_ok_ = all_works_ok();
  oil_c_ = cfg_.default_oil_temp_c;
  have_prev_ = false;
  cut_segments_ = fired_segments_ = 0;
  since_cut_segments_ = 1 << 30;  // no fuel cut-off seen yet
  coast_fired_ = CoastFired{};
  free_coast_ = coast_idle_ = coast_confirmed_ = false;
  coast_resume_rpm_ = coast_resume_map_pa_ = 0.0;
  idle_steady_cycles_ = 0;
  prev_cycle_rpm_ = 0.0;
  brake_var_ = cfg_.fusion.can_load_sd_nm * cfg_.fusion.can_load_sd_nm;
  fired_ = true;
  have_prev_brake_ = false;
  have_prev_load_ = false;
  held_map_pa_ = 0.0;
  have_map_ = false;
  held_spark_deg_ = std::nan("");
}

// A tooth the estimators cannot use (not synced, or invalid): it breaks the sequence in every estimator.
std::uint8_t AnglePipeline::break_sequence(ToothSample s) noexcept {
  s.synced = false;
  have_prev_ = false;
  pre_.update(s);
  if (cfg_.run_kalman) kalman_.update(s);
  if (fourier_ok_) fourier_.update(s);
  energy_.update(s, 0.0, false);
  cyl_energy_.update(s, 0.0, false);
  wide_.update(s);
  rls_.update(s, 0.0, false, 0.0, cyl_work_j_, false);
  fuel_win_.break_sequence();
  tooth_.valid = false;
  return 0;
}

// The cylinder-pressure model's gas torque ripple over the step after tooth k (known input of the in-cycle
// observers): the MAP held from CAN and the last measured works per firing position (motored until every
// position has one). 0 without a MAP.
bool AnglePipeline::all_works_ok() const noexcept {
  bool ok = true;
  for (int m = 0; m < cfg_.engine.cylinders; ++m) ok = ok && cyl_work_ok_[static_cast<std::size_t>(m)];
  return ok;
}

double AnglePipeline::gas_ripple_nm(int k, bool works_ok) const noexcept {
  if (!have_map_) return 0.0;
  const bool phased = cfg_.energies.incycle_spark_phasing;
  int t = LoadRls::kRippleBase;
  double f = 0.0;
  if (phased) {
    const auto spark = std::bit_cast<std::uint64_t>(held_spark_deg_);  // NaN (none yet) included
    if (!ripple_pair_ok_ || spark != ripple_pair_spark_) {
      rls_.ripple_table(ripple_centroid_deg(), ripple_pair_t_, ripple_pair_f_);
      ripple_pair_spark_ = spark;
      ripple_pair_ok_ = true;
    }
    t = ripple_pair_t_;
    f = ripple_pair_f_;
  }
  // p3 per position follows the held MAP, the works' validity, the centroid's table and a new segment work
  // only: kept between them, not recomputed (four divisions) per tooth.
  if (!ripple_p3_ok_ || held_map_pa_ != ripple_p3_map_ || works_ok != ripple_p3_works_ || t != ripple_t_) {
    rls_.ripple_p3(held_map_pa_, cyl_work_j_, works_ok, ripple_p3_, t);
    if (phased) rls_.ripple_p3(held_map_pa_, cyl_work_j_, works_ok, ripple_p3b_, t + 1);
    ripple_p3_map_ = held_map_pa_;
    ripple_p3_works_ = works_ok;
    ripple_t_ = t;
    ripple_p3_ok_ = true;
  }
  const double a = rls_.gas_ripple_nm(k, held_map_pa_, ripple_p3_, t);
  if (!phased) return a;
  if (f == 0.0) return a;
  // Linear in the centroid between the two tables around it.
  const double b = rls_.gas_ripple_nm(k, held_map_pa_, ripple_p3b_, t + 1);
  return a + f * (b - a);
}

// The in-cycle model's burn centroid (docs/angle_estimators.md, "What limits the I6"): the spark advance's,
// centroid = burn_delay_deg − advance as in the RLS closure (energies.incycle_spark_phasing), else, or while
// no spark advance has arrived, energies.burn_centroid_atdc_deg; plus the burn-phasing learner's offset
// (set_burn_offset_deg, 0 without it).
double AnglePipeline::ripple_centroid_deg() const noexcept {
  if (!cfg_.energies.incycle_spark_phasing) return cfg_.energies.burn_centroid_atdc_deg;
  return rls_.centroid_deg(held_spark_deg_) + burn_offset_deg_;
}

std::uint8_t AnglePipeline::on_tooth(const ToothSample& s, const EngineSignals& sig) noexcept {
  ++stats_.teeth;
  if (!s.synced) {
    ++stats_.not_synced;
    return break_sequence(s);
  }
  const double speed = s.width_rad / s.dt_s;
  if (!(s.dt_s > 0.0) || !(s.width_rad > 0.0) || !std::isfinite(s.dt_s) || !std::isfinite(s.width_rad) ||
      !std::isfinite(speed) || s.tooth < 0 || s.tooth >= energy_.samples()) {
    ++stats_.invalid;
    return break_sequence(s);
  }
  std::uint8_t ready = kToothReady;
  tooth_.t_ns = s.t_ns;
  tooth_.tooth = s.tooth;
  tooth_.angle_rad = s.angle_rad;
  tooth_.speed_rad_s = speed;
  // The sample passed the checks every stage makes (all size the cycle as 2 × teeth of the same wheel):
  // they take it without repeating them.
  pre_.update_checked(s);
  const ToothKinematics& kin = pre_.state();
  tooth_.accel_rad_s2 =
      kin.valid ? kin.accel_rad_s2 : (have_prev_ ? (speed - prev_speed_) / (0.5 * (s.dt_s + prev_dt_)) : 0.0);
  tooth_.speed_lp_rad_s = kin.valid ? kin.speed_lp_rad_s : speed;
  tooth_.valid = have_prev_;
  // In-cycle observers (Chauvin): feed_incycle_observers. Every firing position has a measured work (the gas
  // ripple and the RLS window model use them).
  const bool works_ok = works_all_ok_;  // kept where a work changes, not looped over per tooth
  const bool can_fresh = static_cast<double>(s.t_ns - sig.t_ns) * 1e-9 <= cfg_.fusion.max_can_age_s;
  LoadReference lref;
  const bool load_ok = feed_incycle_observers(s, sig, works_ok, can_fresh, lref);
  const NetLoad& net = lref.net;
  prev_speed_ = speed;
  prev_dt_ = s.dt_s;
  have_prev_ = true;

  if (sig.oil_temp_valid && std::isfinite(sig.oil_temp_c)) oil_c_ = sig.oil_temp_c;
  track_reference(lref, load_ok);
  machine_motoring_ =
      can_fresh && net.em_valid && net.em_crank_nm > 0.0 && sig.fuel_mass_valid && !(sig.fuel_mass_kg > 0.0);

  // CAN lost: the RLS keeps running on the last MAP / spark advance it saw (they move slowly at a steady
  // operating point); the fusion marks the result crank-only with can_lost set.
  if (can_fresh && sig.map_valid && std::isfinite(sig.map_pa)) {
    held_map_pa_ = sig.map_pa;
    have_map_ = true;
  }
  if (can_fresh && sig.spark_valid && std::isfinite(sig.spark_advance_deg))
    held_spark_deg_ = sig.spark_advance_deg;
  rls_.update_checked(s, held_map_pa_, have_map_, held_spark_deg_, cyl_work_j_, works_ok);
  FuelIntakeInput intake;
  intake.fuel_kg = sig.fuel_mass_kg;
  intake.map_pa = held_map_pa_;
  intake.fuel_cut = can_fresh && sig.fuel_cutoff_valid && sig.fuel_cutoff;
  intake.valid = can_fresh && sig.fuel_mass_valid && std::isfinite(sig.fuel_mass_kg) && have_map_;
  fuel_win_.on_tooth(s.t_ns, s.angle_rad - cfg_.engine.tdc_offset_rad, intake);

  wide_done_ = wide_.update_checked(s);  // completes on the same tooth as boundary 0's per-cylinder window
  const std::uint64_t breaks_before = energy_.breaks();
  // The per-cylinder work with the friction law and RLS load as they are before this segment's learning;
  // handed to CylinderTorque after on_segment, which decides the segment's fuel state (count_fuel_state).
  // Both windows end on the same tooth: a cycle record completed here goes out with boundary 0's segment.
  const bool cyl_done = cyl_energy_.update_checked(s, net.torque_nm, load_ok);
  double cyl_work_j = 0.0;
  const bool cyl_ok = cyl_done && cylinder_work(cyl_energy_.segment(), cyl_work_j);
  if (energy_.update_checked(s, net.torque_nm, load_ok)) {
    on_segment(energy_.segment(), sig, can_fresh);
    ready = static_cast<std::uint8_t>(ready | kSegmentReady);
    if (cycle_.cycle_end) ready = static_cast<std::uint8_t>(ready | kCycleReady);
  }
  if (cyl_done) cylinder_segment(cyl_energy_.segment(), cyl_work_j, cyl_ok);
  stats_.sequence_breaks += energy_.breaks() - breaks_before;
  return ready;
}

// The in-cycle observers' step of on_tooth (Chauvin's Kalman filter and the Fourier observer, see
// docs/angle_estimators.md): they estimate the net torque, which the extended load turns into T_ind. First
// this tooth's load reference: on a hybrid the machine's torque is a known part of the load (e_machine.hpp;
// not bound, this is the load signal alone, and a stale machine value makes the net load unknown as a stale
// load signal does); on a vehicle the clutch / neutral flags decide whether anything fixes the load
// (classify_load, load_reference.hpp), and a recognised free coast-down supplies its own reference. Then each
// enabled observer gets its extended load and gas-model torque and takes the tooth. `lref` receives the
// reference (the learners track it); returns whether the net load is known on fresh CAN. Real-time safe: no
// allocation, the same work per tooth as when this was inline in on_tooth.
bool AnglePipeline::feed_incycle_observers(const ToothSample& s, const EngineSignals& sig, bool works_ok,
                                           bool can_fresh, LoadReference& lref) noexcept {
  const double ripple =
      cfg_.kalman.gas_model || cfg_.fourier.gas_model ? observer_ripple_nm(s, sig, works_ok, can_fresh) : 0.0;
  last_ripple_nm_ = ripple;
  lref = classify_load(cfg_.e_machine, cfg_.load_ref, sig);
  if (free_coast_) {
    const double map_pa = can_fresh && sig.map_valid ? sig.map_pa : held_map_pa_;
    // The low-passed speed: the idle tests compare a mean speed, not one tooth's (firing ripple, tooth
    // errors).
    free_coast_reference(can_fresh && sig.fuel_cutoff_valid && sig.fuel_cutoff,
                         tooth_.speed_lp_rad_s * kRadSToRpm, map_pa, lref);
  }
  const NetLoad& net = lref.net;
  const bool load_ok = can_fresh && net.known;
  if (cfg_.run_kalman) {
    kalman_.set_extended_load(observer_load_star_nm(net.torque_nm, load_ok));
    kalman_.set_model_torque(cfg_.kalman.gas_model ? ripple : 0.0, have_map_);
    kalman_.update_checked(s);
    copy_estimate(tooth_.kalman_ind, kalman_.estimate());
    add_table_sd(tooth_.kalman_ind);  // the tooth table's own uncertainty (docs/angle_estimators.md (11))
  } else {
    tooth_.kalman_ind.health = Health::kDisabled;
  }
  if (fourier_ok_) {
    fourier_.set_extended_load(load_star_nm_);
    fourier_.set_model_torque(cfg_.fourier.gas_model ? ripple : 0.0, have_map_);
    fourier_.update_checked(s);
    copy_estimate(tooth_.fourier_ind, fourier_.estimate());
  } else {
    tooth_.fourier_ind.health = Health::kDisabled;
  }
  return load_ok;
}

// The Kalman's extended load T*_load (docs/angle_estimators.md, "Through transients and a fuel cut-off"):
// with a known net load on fresh CAN (a load signal, or a vehicle's reference: neutral, the machine alone, a
// free coast's accessories), this tooth's net load plus the friction law at this tooth's speed, T_load(t) +
// T_fric(ω̄), instead of the last segment's cycle mean (up to a cycle behind through speed and load steps);
// without one, the segment's estimate (load_star_nm_).
double AnglePipeline::observer_load_star_nm(double net_load_nm, bool load_ok) const noexcept {
  if (!load_ok || !std::isfinite(net_load_nm)) return load_star_nm_;
  return net_load_nm + friction_.friction_nm(tooth_.speed_lp_rad_s * kRadSToRpm, oil_c_);
}

// Fuel-state change rule (docs/angle_estimators.md, "Through transients and a fuel cut-off"): the gas model's
// p3 per firing position comes from that position's last measured work, so for up to a cycle after the ECU's
// cut-off flag changes it describes the other fuel state. Until every position has a work measured since the
// change: in cut-off the motored p3 (no combustion, known from MAP alone); after the exit the p3 each
// position had when the cut-off began (its combustion before it), instead of the motored works of the cut-off
// cycles.
double AnglePipeline::observer_ripple_nm(const ToothSample& s, const EngineSignals& sig, bool works_ok,
                                         bool fresh) noexcept {
  if (fresh && sig.fuel_cutoff_valid && sig.fuel_cutoff != cut_flag_) {
    cut_flag_ = sig.fuel_cutoff;
    works_since_fuel_change_ = 0;
    if (cut_flag_) {  // entering: the firing positions' p3 as last measured, the prior for when fuel returns
      have_fired_p3_ = works_ok && have_map_;
      fired_t_ = ripple_t_;
      if (have_fired_p3_) rls_.ripple_p3(held_map_pa_, cyl_work_j_, works_ok, fired_p3_, fired_t_);
    }
  }
  if (!have_map_) return 0.0;
  const std::uint32_t all = (1u << static_cast<unsigned>(cfg_.engine.cylinders)) - 1u;
  if ((works_since_fuel_change_ & all) == all) return gas_ripple_nm(s.tooth, works_ok);
  if (cut_flag_) return gas_ripple_nm(s.tooth, false);  // motored p3 at every position
  return have_fired_p3_ ? rls_.gas_ripple_nm(s.tooth, held_map_pa_, fired_p3_, fired_t_)
                        : gas_ripple_nm(s.tooth, works_ok);
}

// ---------------------------------------------------------------------------------------------------------------------
// Per segment (named steps and named gates, docs/conventions.md habit 13).

void AnglePipeline::count_fuel_state(const EngineSignals& sig, bool can_fresh) noexcept {
  const bool cut_known = can_fresh && sig.fuel_cutoff_valid;
  // Motoring by the electric machine (no fuel, the machine drives the crank) is a cut-off segment too,
  // whatever the ECU's cut-off flag says (a bench motoring the engine may not send one): a friction reference
  // (learn()).
  fired_ = !(cut_known && sig.fuel_cutoff) && !machine_motoring_;
  if (fired_) {
    ++fired_segments_;
    ++since_cut_segments_;
    cut_segments_ = 0;
  } else {
    ++cut_segments_;
    fired_segments_ = 0;
    since_cut_segments_ = 0;
  }
}

FuelWindow AnglePipeline::fuel_window(const SegmentEnergy& seg) const noexcept {
  // The 720° window ends at this segment's boundary (the balance's window, relative to cylinder 1's TDC).
  return fuel_win_.window(energy_.boundary_rad(seg.boundary));
}

bool AnglePipeline::segment_load_star(const SegmentEnergy& seg, const TorqueEstimate& rls,
                                      double& load_star_nm) const noexcept {
  const double fric_seg = friction_.friction_nm(seg.speed_rad_s * kRadSToRpm, oil_c_);
  if (seg.load_valid) {
    load_star_nm = seg.load_mean_nm + fric_seg;
    return true;
  }
  load_star_nm = rls.health == Health::kValid ? rls.torque_nm : 0.0;
  return rls.health == Health::kValid;
}

void AnglePipeline::segment_work(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh,
                                 CycleOutput& o) noexcept {
  const TorqueEstimate& rls = o.load_rls;
  const bool rls_ok = rls.health == Health::kValid;
  const double fric_seg = friction_.friction_nm(seg.speed_rad_s * kRadSToRpm, oil_c_);
  double seg_load_star = 0.0;
  const bool seg_ok = segment_load_star(seg, rls, seg_load_star) && seg.segment_valid;
  const double work = seg.d_ke_segment_j + seg_load_star * seg.segment_rad;
  const auto pos = static_cast<std::size_t>(seg.ended_position);
  cyl_work_j_[pos] =
      seg_ok ? work : cyl_work_j_[pos];  // the segment holds this cylinder's whole-cycle net work (RLS input)
  ripple_p3_ok_ = false;                 // gas_ripple_nm's p3 follow the works
  cyl_work_ok_[pos] = seg_ok;
  works_all_ok_ = all_works_ok();
  if (seg_ok) works_since_fuel_change_ |= 1u << pos;
  EsoInput ein;
  ein.t_ns = seg.t_ns;
  ein.ke_j = seg.ke_j;
  ein.segment_rad = seg.segment_rad;
  ein.segment_dt_s = seg.segment_dt_s;
  ein.fuel_kg = fired_ ? sig.fuel_mass_kg : 0.0;
  ein.lambda = sig.lambda_valid ? sig.lambda : 1.0;
  ein.friction_nm = fric_seg;
  ein.load_nm = seg.load_valid ? seg.load_mean_nm : rls.torque_nm - fric_seg;
  ein.valid = seg.segment_valid && can_fresh && sig.fuel_mass_valid && (seg.load_valid || rls_ok);
  eso_.update(ein);
  o.indicated_eso = eso_.estimate();
}

// Per-cylinder work W_m = ΔKE_segment + (T_load + T_fric)·segment angle (CylinderTorque, docs/equations.md
// §4) from the wider KE window: the edge jitter and the tooth-table residual at the two outer edges enter ΔKE
// divided by the window (CycleEnergy), while the 720° balance, the ESO and the RLS keep energy_'s window.
bool AnglePipeline::cylinder_work(const SegmentEnergy& seg, double& work_j) const noexcept {
  double load_star = 0.0;
  const bool ok = segment_load_star(seg, rls_.estimate(), load_star) && seg.segment_valid;
  work_j = seg.d_ke_segment_j + load_star * seg.segment_rad;
  return ok;
}

void AnglePipeline::cylinder_segment(const SegmentEnergy& seg, double work, bool ok) noexcept {
  const int n = cfg_.engine.cylinders;
  // Misfire decisions only after kMisfireArmCycles firing cycles: the CAN flag leads the injections that
  // resume.
  if (cyl_.on_segment(seg.t_ns, seg.ended_position, work, ok,
                      fired_ && fired_segments_ > kMisfireArmCycles * n)) {
    cycle_.cylinders = cyl_.cycle();
    stats_.misfires = cyl_.misfires();
    ++stats_.cycles;
  }
}

double AnglePipeline::friction_sd_nm(double fric) const noexcept {
  // Until learned over speed (motoring) the law is the generic correlation, whose spread across engines is
  // ≈ ±27 % (an idle correction fixes it near idle only). Learned: never below the 1σ its load references
  // shared (FrictionLearner::reference_sd_nm).
  if (!friction_.speed_law_learned()) return friction_.prior_level_sd() * std::fabs(fric);
  return std::max(cfg_.friction.learned_sd_nm, friction_.reference_sd_nm());
}

void AnglePipeline::cycle_balance(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh,
                                  double dke_nm, const FuelWindow& fw, CycleOutput& o) noexcept {
  const double rpm = o.speed_mean_rad_s * kRadSToRpm;
  const double fric = friction_.friction_nm(rpm, oil_c_);
  const Health fric_h = friction_.health();
  const double fric_sd = friction_sd_nm(fric);
  o.friction = make(seg.t_ns, fric, fric_sd, fric_h);
  // Energy balance with the measured load: the brake torque needs no friction model.
  if (seg.cycle_load_valid) {
    const double brake = dke_nm + seg.cycle_load_mean_nm;
    if (have_prev_brake_) {
      const double d = brake - prev_brake_;
      brake_var_ += cfg_.fusion.brake_sd_ema * (0.5 * d * d - brake_var_);  // ½: a difference of two cycles
    }
    prev_brake_ = brake;
    have_prev_brake_ = true;
    o.brake_energy = make(seg.t_ns, brake, std::sqrt(brake_var_) + load_sd_nm(), Health::kValid);
  } else {
    o.brake_energy = make(seg.t_ns, 0.0, 0.0, Health::kStaleInput);
  }
  // Crank only: indicated from the extended load tracked through load changes (LoadRls rule 4). Its claimed
  // 1σ is at least the RMS error measured against the energy balance while a load signal was present.
  const TorqueEstimate trk = rls_.tracked();
  o.indicated_crank = make(seg.t_ns, dke_nm + trk.torque_nm,
                           std::max(trk.uncertainty, std::sqrt(crank_err_var_)), trk.health);
  // Fuel model (ECU fuel mass on CAN at each intake event, efficiency learned against the energy balance).
  // The window's events in fuel cut-off hold the motored (pumping) torque, the model the friction law was
  // learned against in cut-off (learn(): T_fric = T_motored − ΔKE − T_load): in a window wholly in cut-off
  // brake = T_motored − friction is as good as the learned law fits its motoring balances (claimed 1σ: their
  // residuals' 68th percentile); a window straddling a cut-off edge is split.
  const TorqueEstimate motored =
      make(seg.t_ns, rls_.motored_torque_nm(fw.map_cut_pa), friction_.motoring_sd_nm(),
           have_map_ && !friction_.is_prior() ? Health::kValid : Health::kNotConverged);
  fuel_ind_ = fuel_.estimate_window(seg.t_ns, fw, fuel_point(sig, can_fresh, rpm), motored);
  if (seg.cycle_load_valid) {
    o.load = make(seg.t_ns, seg.cycle_load_mean_nm, load_sd_nm(), Health::kValid);
    o.brake = o.brake_energy;
    o.indicated = make(seg.t_ns, o.brake_energy.torque_nm + fric,
                       std::hypot(o.brake_energy.uncertainty, fric_sd), fric_h);
  } else {
    // No load signal: the more certain of the fuel model and the compression-window chain (claimed 1σ, both
    // measured).
    const bool use_fuel =
        fuel_ind_.health == Health::kValid && (trk.health != Health::kValid || !crank_agrees_with_fuel(o) ||
                                               fuel_ind_.uncertainty < o.indicated_crank.uncertainty);
    // Both chains were scored against T_ind,ref = balance + learned friction: their brake (value − friction)
    // carries the measured σ alone, their indicated also the friction's.
    const TorqueEstimate& src = use_fuel ? fuel_ind_ : o.indicated_crank;
    o.indicated =
        make(seg.t_ns, src.torque_nm, std::hypot(src.uncertainty, fric_sd), worst(src.health, fric_h));
    o.brake = make(seg.t_ns, src.torque_nm - fric, src.uncertainty, worst(src.health, fric_h));
    if (use_fuel && !fuel_.valid()) o.brake = fuel_prior_brake(seg.t_ns, fric, fric_sd);
    o.load = make(seg.t_ns, o.brake.torque_nm - dke_nm, o.brake.uncertainty, o.brake.health);
  }
  // Extended load for the in-cycle observers: measured load + friction, or the crank-only estimate without
  // it.
  load_star_nm_ = seg.cycle_load_valid ? seg.cycle_load_mean_nm + fric : o.load.torque_nm + fric;
}

// The fuel model's operating point for a window: cycle speed, and the spark advance and λ on CAN (they move
// slowly; the window's fuel and MAP come from its intake events).
FuelPoint AnglePipeline::fuel_point(const EngineSignals& sig, bool can_fresh, double rpm) const noexcept {
  FuelPoint x;
  x.rpm = rpm;
  x.spark_valid = can_fresh && sig.spark_valid && std::isfinite(sig.spark_advance_deg);
  x.spark_deg = x.spark_valid ? sig.spark_advance_deg : 0.0;
  x.lambda_valid = can_fresh && sig.lambda_valid && std::isfinite(sig.lambda) && sig.lambda > 0.0;
  x.lambda = x.lambda_valid ? sig.lambda : 1.0;
  return x;
}

// Brake from a fuel model that has not measured its residuals yet (prior or few references): indicated from
// fuel minus friction, nothing else; its 1σ is the model's (parameter + model-form) with the friction's.
TorqueEstimate AnglePipeline::fuel_prior_brake(std::int64_t t_ns, double fric,
                                               double fric_sd) const noexcept {
  return make(t_ns, fuel_ind_.torque_nm - fric, std::hypot(fuel_ind_.uncertainty, fric_sd), fuel_ind_.health);
}

void AnglePipeline::track_reference(const LoadReference& ref, bool load_ok) noexcept {
  const ReferenceKind k = load_ok ? ref.kind : ReferenceKind::kNone;
  if (k != ref_kind_) {
    ref_kind_ = k;
    ref_teeth_ = 0;
    ref_sd_nm_ = 0.0;
  }
  if (ref_teeth_ < (1 << 30)) ++ref_teeth_;
  ref_sd_nm_ = std::max(ref_sd_nm_, ref.sd_nm);
}

// The one decision of whether a 720° window is a reference for the learners (friction, inertia, fuel model,
// crank-chain error): its load was known at every tooth (a measured load, the machine alone with the clutch
// open, neutral with the accessory prior) and one kind fixed it throughout (a window that saw the clutch /
// neutral flag change is not a reference; a quarter cycle of margin for the wide KE window's outer edges). A
// fuel cut-off with the clutch closed and no load signal has kind kNone: nothing is learned from it.
CycleReference AnglePipeline::cycle_reference(const SegmentEnergy& seg) const noexcept {
  CycleReference r;
  const int teeth_cycle = 2 * cfg_.wheel.teeth();
  r.kind = ref_kind_;
  r.sd_nm = ref_sd_nm_;
  r.ok =
      seg.cycle_load_valid && ref_kind_ != ReferenceKind::kNone && ref_teeth_ > teeth_cycle + teeth_cycle / 4;
  return r;
}

bool AnglePipeline::free_coast_allowed() const noexcept {
  const LoadReferenceParams& p = cfg_.load_ref;
  // A mapped load signal measures the load whenever it is fresh; when it times out the load is unknown, and a
  // dynamometer's cut-off can pass the entry tests: no free coast is taken on a bench.
  return p.free_coast && !p.sole_flag_bound && !p.neutral_bound && !p.load_signal_bound &&
         !cfg_.e_machine.bound;
}

// Per tooth while a free coast-down holds: the load is the accessories' (prior and 1σ) while the fuel stays
// cut and nothing else fixes the load. When the fuel comes back the coast goes on as idle (the engine settles
// to idle speed with the throttle closed: a driver who coasted out of gear and stops): it ends at the first
// sign of a driveline closing or a driver driving off, the speed rising above both idle and the speed the
// fuel resumed at, or MAP rising free_coast_idle_map_rise_pa above its value then.
void AnglePipeline::free_coast_reference(bool cut_now, double rpm, double map_pa,
                                         LoadReference& lref) noexcept {
  if (lref.kind != ReferenceKind::kNone) {
    free_coast_ = coast_idle_ = false;
    return;
  }
  if (cut_now) {
    coast_idle_ = false;
  } else if (!coast_idle_) {
    coast_idle_ = true;
    coast_resume_rpm_ = rpm;
    coast_resume_map_pa_ = map_pa;
  } else if ((rpm > coast_resume_rpm_ && rpm > cfg_.energies.idle_max_rpm) ||
             map_pa > coast_resume_map_pa_ + cfg_.load_ref.free_coast_idle_map_rise_pa) {
    free_coast_ = coast_idle_ = false;
    return;
  }
  if (!coast_confirmed_) return;  // the load is known once one more cut-off cycle passed the tests
  lref.kind = ReferenceKind::kFreeCoast;
  lref.net.torque_nm = cfg_.load_ref.accessory_nm;
  lref.net.known = true;
  lref.sd_nm = cfg_.load_ref.accessory_sd_nm;
}

// A free coast-down recognised from the crank and the fuel alone, with no clutch / neutral flag
// (docs/angle_pipeline.md "Free coast-down without a flag"). In a fuel cut-off the balance J θ̈ = T_mot −
// T_fric − T_net teaches friction only where T_net is known; with the clutch open it is the accessories'.
// Coupled in gear, the vehicle's inertia referred to the crank (J_v ≥ 2 J in any gear: m r_w² / i² against
// 0.1-0.3 kg m²) takes its share of every torque change: the step of J θ̈ at cut-off entry is ≤ J / (J + J_v)
// ≤ 0.33 of the indicated torque lost, and the coast's deceleration far below the free engine's (T_mot −
// T_fric − T_acc). Hard braking in a low gear can match that deceleration, but not the step at the same
// instant as well. Both ratios are checked at the first cycle wholly in cut-off, the deceleration at every
// cut-off cycle after it. Returns true when this window ends a free coast: its load is not known (the caller
// publishes no energy balance for it).
bool AnglePipeline::detect_free_coast(const FuelWindow& fw, double dke_nm, const CycleOutput& o) noexcept {
  if (!o.cycle_end) return false;
  const int n = cfg_.engine.cylinders;
  const LoadReferenceParams& p = cfg_.load_ref;
  const double rpm = o.speed_mean_rad_s * kRadSToRpm;
  if (coast_fired_.age < (1 << 20)) ++coast_fired_.age;
  if (!free_coast_allowed() || !fw.valid || !have_map_) {
    const bool ended = free_coast_;
    free_coast_ = false;
    return ended;
  }
  if (fw.fired == n && fw.cut == 0) {  // a fully fired cycle: the level before a cut-off
    coast_fired_.dke_nm = dke_nm;
    coast_fired_.t_ind_nm = fuel_.estimate(o.t_ns, fw.fuel_kg, fw.map_fired_pa, rpm).torque_nm;
    coast_fired_.age = 0;
    free_coast_ = free_coast_ && coast_idle_;  // a coast's idle ends on the per-tooth tests
    return false;
  }
  if (fw.fired != 0 || fw.cut != n) return false;  // the entry window: wait for a cycle wholly in cut-off
  const double t_mot = rls_.motored_torque_nm(fw.map_cut_pa);
  const double free_nm = t_mot - friction_.friction_nm(rpm, oil_c_) - p.accessory_nm;
  const double q = free_nm < -kCoastMinTorqueNm ? dke_nm / free_nm : 0.0;
  const bool decel_ok = q >= p.free_coast_decel_min && q <= p.free_coast_decel_max;
  if (free_coast_) {
    // A free coast's deceleration torque (friction and pumping) moves a few per cent from one cycle to the
    // next; a speed-held dynamometer or a driveline taking up its share after the cut-off changes it far
    // more. Ended here, the window is no reference either (the kind's count restarts).
    const bool smooth = std::fabs(dke_nm - coast_fired_.coast_dke_nm) <=
                        p.free_coast_decel_change * std::fabs(coast_fired_.coast_dke_nm);
    coast_fired_.coast_dke_nm = dke_nm;
    free_coast_ = decel_ok && smooth;
    coast_confirmed_ = free_coast_;
    if (!free_coast_ && ref_kind_ == ReferenceKind::kFreeCoast) ref_teeth_ = 0;
    return !free_coast_;
  }
  if (coast_fired_.age > kCoastEntryCycles) return false;  // only at cut-off entry
  coast_fired_.age = 1 << 20;                              // one decision per entry
  const double drop = coast_fired_.t_ind_nm - t_mot;
  const double step = drop > kCoastMinTorqueNm ? (coast_fired_.dke_nm - dke_nm) / drop : 0.0;
  if (decel_ok && step >= p.free_coast_step_min && step <= p.free_coast_step_max) {
    free_coast_ = true;
    coast_confirmed_ = false;
    coast_fired_.coast_dke_nm = dke_nm;
    ++stats_.free_coasts;
  }
  return false;
}

bool AnglePipeline::motoring_observation_allowed(const CycleReference& ref, const EngineSignals& sig,
                                                 bool load_steady) const noexcept {
  // Fuel cut-off for the whole 720° window plus one segment for the CAN flag's delay.
  return cut_segments_ > cfg_.engine.cylinders + 1 && ref.ok && load_steady && sig.map_valid;
}

bool AnglePipeline::idle_observation_allowed(const SegmentEnergy& seg, const CycleReference& ref,
                                             const TorqueEstimate& rls, double rpm,
                                             bool cycle_end) const noexcept {
  const int n = cfg_.engine.cylinders;
  const FrictionParams& f = cfg_.friction;
  // "No load" beyond the accessories: on a vehicle (a clutch or neutral flag mapped) the driveline-open load
  // is the accessory prior, which the observation subtracts like any known load.
  const bool vehicle = cfg_.load_ref.sole_flag_bound || cfg_.load_ref.neutral_bound;
  const bool acc_acts = vehicle || ref.kind == ReferenceKind::kFreeCoast;
  const double acc = acc_acts && ref.kind != ReferenceKind::kLoadSignal ? cfg_.load_ref.accessory_nm : 0.0;
  return cycle_end && fired_segments_ > n && since_cut_segments_ > f.idle_after_cut_cycles * n && ref.ok &&
         rls.health == Health::kValid && rls.uncertainty < f.idle_max_rls_sd_nm &&
         idle_steady_cycles_ >= f.idle_steady_cycles && rpm < cfg_.energies.idle_max_rpm &&
         std::fabs(seg.cycle_load_mean_nm - acc) < cfg_.energies.idle_max_load_nm;
}

bool AnglePipeline::fuel_reference_allowed(const CycleReference& ref, const EngineSignals& sig,
                                           bool can_fresh, bool load_steady, bool cycle_end) const noexcept {
  // A reference cycle: known load (energy balance) no less certain than fuel_max_sd_nm (FuelTorque::learn has
  // no per-reference weight), learned friction, firing for a whole window, fuel on CAN.
  return cycle_end && ref.ok && ref.sd_nm <= cfg_.load_ref.fuel_max_sd_nm && load_steady &&
         friction_.speed_law_learned() && fired_segments_ > cfg_.engine.cylinders && can_fresh &&
         sig.fuel_mass_valid && have_map_;
}

bool AnglePipeline::fuel_learning_allowed(const CycleReference& ref, const EngineSignals& sig, bool can_fresh,
                                          bool cycle_end, const FuelWindow& fw) const noexcept {
  // A fuel-model reference: as fuel_reference_allowed() but transients too (the friction law learned over
  // speed, not only corrected at idle: T_ind,ref = balance + friction carries the friction's error) (the
  // window's fuel and MAP are the intake events' whose work it holds; FuelAngleWindow), every event fired.
  return cycle_end && ref.ok && ref.sd_nm <= cfg_.load_ref.fuel_max_sd_nm && friction_.speed_law_learned() &&
         fired_segments_ > cfg_.engine.cylinders && can_fresh && sig.fuel_mass_valid && have_map_ &&
         fw.valid && fw.cut == 0 && fw.fired > 0;
}

bool AnglePipeline::rests_on_accessory_prior(const CycleReference& ref) const noexcept {
  // The references whose load is the accessories' prior (classify_load, free_coast_reference): its error is
  // one bias shared by all of them (FuelTorque::learn).
  const LoadReferenceParams& p = cfg_.load_ref;
  const bool flagged = p.sole_flag_bound || p.neutral_bound;
  return ref.kind == ReferenceKind::kNeutral || ref.kind == ReferenceKind::kFreeCoast ||
         (ref.kind == ReferenceKind::kEMachineSole && flagged);
}

void AnglePipeline::learn_fuel(const CycleReference& ref, const EngineSignals& sig, bool can_fresh,
                               const FuelWindow& fw, const CycleOutput& o) noexcept {
  if (!fuel_learning_allowed(ref, sig, can_fresh, o.cycle_end, fw)) return;
  FuelPoint x = fuel_point(sig, can_fresh, o.speed_mean_rad_s * kRadSToRpm);
  x.fuel_kg = fw.fuel_kg;
  x.map_pa = fw.map_fired_pa;
  const double t_ind_ref = o.brake_energy.torque_nm + o.friction.torque_nm;
  (void)fuel_.learn(x, t_ind_ref, fuel_.transient_sd_nm(fw, x), rests_on_accessory_prior(ref));
}

void AnglePipeline::learn(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh, double dke_nm,
                          const FuelWindow& fw, const CycleOutput& o) noexcept {
  const double rpm = o.speed_mean_rad_s * kRadSToRpm;
  const CycleReference ref = cycle_reference(seg);
  const bool load_steady =
      have_prev_load_ && std::fabs(seg.cycle_load_mean_nm - prev_load_) <= cfg_.friction.max_load_change_nm;
  prev_load_ = seg.cycle_load_mean_nm;
  have_prev_load_ = seg.cycle_load_valid;
  // EN-24..36 in fuel cut-off: T_ind = motored (pumping) torque, so T_fric = T_motored − Δ(½Jθ̇²)/4π − T_load.
  // The reference's 1σ weighs the observation (a measured load ≈ the learner's unit variance, neutral's
  // accessory prior less).
  if (motoring_observation_allowed(ref, sig, load_steady)) {
    const double obs = rls_.motored_torque_nm(sig.map_pa) - dke_nm - seg.cycle_load_mean_nm;
    if (friction_.observe_motoring(rpm, oil_c_, obs, ref.sd_nm * ref.sd_nm)) ++stats_.friction_observations;
  }
  // Steady idle (speed within idle_speed_tolerance for idle_steady_cycles; the RLS remembers ≈ 10 cycles).
  if (o.cycle_end) {
    const bool steady = rpm < cfg_.energies.idle_max_rpm && ref.ok && load_steady &&
                        std::fabs(rpm - prev_cycle_rpm_) < cfg_.friction.idle_speed_tolerance * rpm;
    idle_steady_cycles_ = steady ? idle_steady_cycles_ + 1 : 0;
    prev_cycle_rpm_ = rpm;
  }
  // Idle: no load, firing, RLS settled -> its extended load is the friction (EN-30..33; local idle
  // correction). The learner rejects observations far from the established idle level (no collapse on one bad
  // input).
  if (idle_observation_allowed(seg, ref, o.load_rls, rpm, o.cycle_end)) {
    friction_.observe_idle(rpm, oil_c_, o.load_rls.torque_nm - seg.cycle_load_mean_nm,
                           ref.kind != ReferenceKind::kLoadSignal,
                           std::hypot(ref.sd_nm, o.load_rls.uncertainty));
  }
  // Crank-only references: the energy balance with the measured load is the truth the crank-only chains are
  // scored against (fuel-model efficiency; measured 1σ of the compression-window chain).
  if (fuel_reference_allowed(ref, sig, can_fresh, load_steady, o.cycle_end)) {
    const double t_ind_ref = o.brake_energy.torque_nm + o.friction.torque_nm;
    if (o.indicated_crank.health == Health::kValid) {
      const double e = o.indicated_crank.torque_nm - t_ind_ref;
      crank_err_var_ += cfg_.fusion.brake_sd_ema * (e * e - crank_err_var_);
    }
  }
  learn_fuel(ref, sig, can_fresh, fw, o);
}

void AnglePipeline::learn_inertia(const SegmentEnergy& seg, bool can_fresh, double dke_spec_nm,
                                  const FuelWindow& fw, const CycleOutput& o) noexcept {
  if (!o.cycle_end) return;  // consecutive, non-overlapping 720° windows
  const int n = cfg_.engine.cylinders;
  InertiaPoint p;
  p.ok = cycle_reference(seg).ok && can_fresh && fw.valid && have_map_;
  p.fired = fw.fired == n && fw.cut == 0;
  p.cut = fw.fired == 0 && fw.cut == n;
  p.dke_spec_nm = dke_spec_nm;
  p.load_nm = seg.cycle_load_mean_nm;
  p.rpm = o.speed_mean_rad_s * kRadSToRpm;
  p.fuel_kg = fw.fuel_kg;
  p.map_pa = p.fired ? fw.map_fired_pa : fw.map_cut_pa;
  const InertiaPoint& q = prev_inertia_;
  const InertiaParams& ip = cfg_.energies.inertia;
  const bool same_firing =
      p.fired && q.fired &&
      std::fabs(p.fuel_kg - q.fuel_kg) <= ip.max_fuel_change * std::max(p.fuel_kg, q.fuel_kg) &&
      std::fabs(p.map_pa - q.map_pa) <= ip.max_map_change_pa;
  const bool both_cut = p.cut && q.cut;
  if (p.ok && q.ok && (same_firing || both_cut)) {
    // k·Δ(ΔKE_spec/4π) = −ΔT_load − ΔT_fric + ΔT_ind (inertia_learner.hpp): ΔT_ind is the modelled motored
    // torque's change in cut-off, the fuel model's (Willans line, learned or its prior) between two cycles of
    // nearly the same fuelling.
    const double d_ind = both_cut ? rls_.motored_torque_nm(p.map_pa) - rls_.motored_torque_nm(q.map_pa)
                                  : fuel_.estimate(seg.t_ns, p.fuel_kg, p.map_pa, p.rpm).torque_nm -
                                        fuel_.estimate(seg.t_ns, q.fuel_kg, q.map_pa, q.rpm).torque_nm;
    const double y = -(p.load_nm - q.load_nm) -
                     (friction_.friction_nm(p.rpm, oil_c_) - friction_.friction_nm(q.rpm, oil_c_)) + d_ind;
    if (inertia_.observe(p.dke_spec_nm - q.dke_spec_nm, y)) ++stats_.inertia_observations;
  }
  prev_inertia_ = p;
}

void AnglePipeline::fuse(const SegmentEnergy& seg, const EngineSignals& sig, CycleOutput& o) noexcept {
  const double fric = o.friction.torque_nm;
  const double fric_sd = o.friction.uncertainty;
  const Health fric_h = o.friction.health;
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
  c.sd_nm = o.indicated_crank.uncertainty;  // measured against balance + learned friction (see cycle_balance)
  c.health = worst(o.load_rls.health, fric_h);
  c.uses_can = false;
  c.newest_input_ns = seg.t_ns;
  // Without the load signal the compression-window chain is offered only where its claimed 1σ was measured:
  // in an operating cell the references reached (they teach the fuel model's cells too), and agreeing with
  // the fuel model (crank_agrees_with_fuel). Elsewhere its gas model can be far off while the 1σ measured at
  // a few references (idle after a coast-down, say) claims a fraction of a newton-metre.
  const bool cell_measured =
      (fuel_.learned_cells() >> FuelTorque::cell_of(o.speed_mean_rad_s * kRadSToRpm, held_map_pa_)) & 1u;
  if (o.brake_energy.health != Health::kValid && (!cell_measured || !crank_agrees_with_fuel(o)))
    c.health = Health::kNotConverged;
  // Model-based slot: the learned fuel model when valid, else the ESO; without a load signal the fuel model
  // before it measured its residuals (fuel_model_slot).
  FusionSource& z = fin.src[static_cast<std::size_t>(FusionSourceId::kEso)];
  if (!fuel_model_slot(o, z)) {
    const bool fuel_ok = fuel_.valid() && fuel_ind_.health == Health::kValid;
    const TorqueEstimate& m = fuel_ok ? fuel_ind_ : o.indicated_eso;
    // A learned fuel model with a friction law short of friction.min_observations (a vehicle's few coast-down
    // cycles, restored so): published with the friction's 1σ added, not withheld until more coasts come.
    const bool fric_partial = fuel_ok && fric_h == Health::kNotConverged;
    z.brake_nm = m.torque_nm - fric;
    z.sd_nm = fuel_ok && !fric_partial ? m.uncertainty : std::hypot(m.uncertainty, fric_sd);
    z.health = fric_partial ? m.health : worst(m.health, fric_h);
  }
  z.uses_can = true;
  z.newest_input_ns = sig.t_ns;
  fin.src[static_cast<std::size_t>(FusionSourceId::kExternal)] = external_;
  o.fused = fusion_.update(fin);
}

bool AnglePipeline::crank_agrees_with_fuel(const CycleOutput& o) const noexcept {
  // The compression-window chain's claimed 1σ is measured against the references, at their operating points;
  // elsewhere its gas model can be wrong by far more (100-400 N m seen on the bed's I6). The fuel model's 1σ
  // is backed by its priors everywhere: a chain farther from it than fusion.gate_sigma combined σ is not
  // used.
  if (o.indicated_crank.health != Health::kValid || fuel_ind_.health != Health::kValid) return true;
  const double gate =
      cfg_.fusion.gate_sigma * std::hypot(o.indicated_crank.uncertainty, fuel_ind_.uncertainty);
  return std::fabs(o.indicated_crank.torque_nm - fuel_ind_.torque_nm) <= gate;
}

bool AnglePipeline::fuel_model_slot(const CycleOutput& o, FusionSource& z) const noexcept {
  // No load signal and a fuel model that has not measured its residual scale (prior, or a few references):
  // brake = fuel model − friction with both 1σ (the prior's are wide); "prior only" while nothing was
  // learned. With a load signal the balance leads and this slot stays as it was (learned fuel model or ESO).
  if (fuel_.valid() || o.brake_energy.health == Health::kValid || fuel_ind_.health != Health::kValid)
    return false;
  const TorqueEstimate b = fuel_prior_brake(o.t_ns, o.friction.torque_nm, o.friction.uncertainty);
  z.brake_nm = b.torque_nm;
  z.sd_nm = b.uncertainty;
  z.health = b.health;
  z.prior_only = fuel_.prior_only() && friction_.is_prior();
  return true;
}

void AnglePipeline::on_segment(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh) noexcept {
  ++stats_.segments;
  count_fuel_state(sig, can_fresh);
  CycleOutput o;
  o.t_ns = seg.t_ns;
  o.seq = cycle_.seq + 1;
  o.boundary = seg.boundary;
  o.cycle_end = seg.boundary == 0;
  o.cylinders = cycle_.cylinders;
  o.load_rls = rls_.estimate();
  segment_work(seg, sig, can_fresh, o);
  if (!seg.cycle_valid) {
    o.brake = o.indicated = o.friction = o.load = o.brake_energy = o.indicated_crank =
        make(seg.t_ns, 0.0, 0.0, Health::kNotConverged);
    o.fused = fusion_.estimate();
    cycle_ = o;
    prev_inertia_.ok = false;
    return;
  }
  o.speed_mean_rad_s = kFourPi / seg.cycle_dt_s;
  // Δ(½Jθ̇²)/4π; at boundary 0 from the wide window when it completed here (jitter noise / ≈ 4,
  // CycleKeWindow). Computed with the spec sheet's J, scaled by the learned k (J = k·J_spec, InertiaLearner).
  const bool wide = o.cycle_end && wide_done_ && wide_.cycle_valid();
  const double dke_spec_nm = (wide ? wide_.d_ke_cycle_j() : seg.d_ke_cycle_j) / kFourPi;
  const double dke_nm = inertia_.applied_scale() * dke_spec_nm;
  // The fuel window of this segment's 720° (FuelAngleWindow), read once for the balance and the learners.
  const FuelWindow fw = fuel_window(seg);
  // Before the balance and learning: its tests use the friction law the window began with, and a window that
  // ends a free coast (its deceleration changed: a driveline closing, a dynamometer) has no known load.
  SegmentEnergy s = seg;
  if (detect_free_coast(fw, dke_nm, o)) s.cycle_load_valid = false;
  const CycleReference ref = cycle_reference(s);
  o.reference = ref.ok ? ref.kind : ReferenceKind::kNone;
  cycle_balance(s, sig, can_fresh, dke_nm, fw, o);
  learn(s, sig, can_fresh, dke_nm, fw, o);
  learn_inertia(s, can_fresh, dke_spec_nm, fw, o);
  fuse(s, sig, o);
  cycle_ = o;
}

}  // namespace torqued
