#include "angle_chain.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

AngleChain::AngleChain(const StageSettings& s, const DbcDatabase* dbc, AngleChainSink& out, ToothSink* time)
    : s_(s), out_(out), time_(time), decoder_(s.wheel, s.decoder) {
  if (!decoder_.valid()) {
    error_ = "crank decoder: " + decoder_.error();
    return;
  }
  decoder_.set_event_log(&transitions_);
  if (dbc) {
    store_ = std::make_unique<SignalStore>(*dbc);
    error_ = bind_signals(*store_, s_.signals);
    if (!error_.empty()) return;
  }
  if (s_.angle_enabled) {
    AnglePipelineConfig ac = s_.angle;
    ac.engine = s_.engine;
    ac.wheel = s_.wheel;
    ac.spark_on_can =
        store_ && !s_.signals[static_cast<std::size_t>(Quantity::kSparkAdvance)].message.empty();
    pipeline_ = std::make_unique<AnglePipeline>(ac);
    const KalmanParams& kp = s_.angle.kalman;
    if (s_.angle.run_kalman && kp.gas_model && kp.burn_phase.learn)
      burn_ = std::make_unique<BurnPhaseLearner>(s_.engine, s_.wheel, kp.burn_phase);
  }
  if (s_.tooth_learn_enabled) {
    learner_ = std::make_unique<ToothErrorLearner>(s_.engine, s_.wheel, s_.tooth_learn);
    if (pipeline_) pipeline_->set_wheel_learned(false);  // until the learner is ready or a table is imported
  }
}

AngleChain::~AngleChain() = default;

ChainStatus AngleChain::status() const noexcept {
  return {decoder_.state() == SyncState::kSynced && decoder_.phase_known(), stale_mask_};
}

void AngleChain::on_edge(const EdgeEvent& e) noexcept {
  last_t_ns_ = e.t_ns;
  ToothEvent te{};
  if (decoder_.on_edge(e, te)) on_tooth(te);
}

void AngleChain::on_frame(const CanFrame& f) noexcept {
  if (store_) (void)store_->on_frame(f);
}

void AngleChain::poll(std::int64_t now_ns) noexcept {
  if (decoder_.poll(now_ns)) {
    prev_tooth_t_ns_ = -1;
    prev_tooth_ = -1;
  }
}

void AngleChain::set_time_estimate(const TorqueEstimate& e, bool uses_can) noexcept {
  if (!pipeline_ || !s_.angle.fusion.time_estimate) return;
  FusionSource src;
  src.brake_nm = e.torque_nm;
  src.sd_nm = e.uncertainty > 0.0 ? e.uncertainty : 1.0;
  src.health = e.health;
  src.uses_can = uses_can;
  src.newest_input_ns = e.t_ns;
  pipeline_->set_external(src);
}

void AngleChain::set_signal_timeouts(const std::array<std::int64_t, kSignalCount>& timeout_ns) noexcept {
  if (!store_) return;
  for (std::size_t i = 0; i < timeout_ns.size(); ++i)
    store_->set_timeout(static_cast<Quantity>(i), timeout_ns[i]);
}

void AngleChain::on_tooth(const ToothEvent& te) noexcept {
  const bool synced = te.sync == SyncState::kSynced && te.phase_known;
  ChainTooth ct;
  ct.event = te;
  ToothSample& ts = ct.sample;
  ts.t_ns = te.t_ns;
  ts.tooth = te.tooth;
  ts.angle_rad = te.angle_rad;
  ts.width_rad = te.width_rad;
  ts.dt_s = prev_tooth_t_ns_ >= 0 ? static_cast<double>(te.t_ns - prev_tooth_t_ns_) * 1e-9 : 0.0;
  ts.synced = synced && prev_tooth_t_ns_ >= 0;

  // EngineSignals at this tooth; remember which bound quantities are stale.
  // The store's cached snapshot and its stale mask (no copy, no per-quantity loop per tooth).
  static constexpr EngineSignals kNoSignals{};
  std::uint32_t stale = 0;
  const EngineSignals& sig = store_ ? store_->snapshot_at(te.t_ns, stale) : kNoSignals;
  stale_mask_ = stale;

  if (time_) time_->tooth(ts);  // time chain hand-off: mean speed
  if (learner_) {
    learner_->set_fuel_cutoff(sig.fuel_cutoff_valid && sig.fuel_cutoff);  // feedback (2)
    learner_->set_map(sig.map_pa, sig.map_valid);  // the speed law compares cycles at the same load
    learner_->set_spark(sig.spark_advance_deg, sig.spark_valid);  // the firing law's spark column
    learner_->update(ts);
  }
  const std::uint8_t ready = pipeline_ ? pipeline_->on_tooth(ts, sig) : 0;
  if (burn_ && synced) feed_burn_phase(sig);  // feedback (6): the Kalman's estimate against its gas model
  const bool est_valid = pipeline_ && pipeline_->tooth_output().valid;
  if (est_valid) {
    ct.accel_rad_s2 = pipeline_->tooth_output().accel_rad_s2;
    ct.estimates = &pipeline_->tooth_output();
  } else if (ts.dt_s > 0.0) {
    ct.accel_rad_s2 = (te.speed_rad_s - prev_speed_rad_s_) / ts.dt_s;
  }
  ct.status = status();
  out_.on_tooth(ct);

  if (ready & AnglePipeline::kSegmentReady) emit_segment(te);
  if (synced && prev_tooth_ >= 0 && te.tooth < prev_tooth_) on_cycle_end();  // tooth index wrapped
  prev_tooth_ = synced ? te.tooth : -1;
  prev_tooth_t_ns_ = te.t_ns;
  prev_speed_rad_s_ = te.speed_rad_s;
}

void AngleChain::emit_segment(const ToothEvent& te) noexcept {
  const CycleOutput& o = pipeline_->cycle_output();
  const int n = s_.engine.cylinders;
  const int pos = ((o.boundary - 1) % n + n) % n;  // firing position whose segment just ended
  const std::int64_t window_ns =
      o.speed_mean_rad_s > 0.0 ? static_cast<std::int64_t>(4.0 * std::numbers::pi / o.speed_mean_rad_s * 1e9)
                               : 0;
  ChainSegment cs;
  cs.source_t_ns = te.source_t_ns;
  cs.window_start_t_ns = te.source_t_ns - window_ns;
  cs.cylinder = s_.engine.firing_order[static_cast<std::size_t>(pos)];
  cs.cycle = cycles_;
  cs.out = &o;
  cs.status = status();
  out_.on_segment(cs);
}

// Feedback (6), per tooth: the Kalman's estimate and the gas model inside it, with the signals the model
// rests on (a stale or absent MAP or spark advance, or a cut-off, keeps the cycle out of the learner).
void AngleChain::feed_burn_phase(const EngineSignals& sig) noexcept {
  const ChauvinKalman& kf = pipeline_->kalman();
  const TorqueEstimate& e = kf.estimate();
  burn_->set_signals(sig.map_valid && std::isfinite(sig.map_pa),
                     sig.spark_valid && std::isfinite(sig.spark_advance_deg),
                     sig.fuel_cutoff_valid && sig.fuel_cutoff);
  const bool valid = pipeline_->tooth_output().kalman_ind.health == Health::kValid && kf.model_active();
  burn_->update(kf.estimate_tooth(), e.torque_nm, kf.output_model_nm(), valid);
}

// Feedback (1): the learned tooth table goes to the decoder at each cycle boundary; (6) the burn-phasing
// learner's offset goes to the gas model.
void AngleChain::on_cycle_end() noexcept {
  ++cycles_;
  if (burn_ && burn_->end_cycle()) pipeline_->set_burn_offset_deg(burn_->offset_deg());
  if (learner_ && learner_->import_distrusted() && !import_distrust_applied_) {
    // The engine contradicted the imported table: the decoder drops it, the angle-domain observers say
    // "not converged" until the fresh table is ready (below, at a later cycle end), the state no longer holds
    // it.
    import_distrust_applied_ = true;
    const auto n = static_cast<std::size_t>(learner_->teeth());
    std::fill(corr_.begin(), corr_.begin() + static_cast<std::ptrdiff_t>(n), 0.0);
    (void)decoder_.set_tooth_corrections(std::span<const double>(corr_.data(), n));
    corr_n_ = 0;
    if (pipeline_) pipeline_->set_wheel_learned(false);
    if (pipeline_) pipeline_->set_wheel_table_var(0.0);
  }
  if (learner_ && learner_->ready()) {
    const int n = learner_->teeth();
    learner_->edge_corrections(std::span<double>(corr_.data(), static_cast<std::size_t>(n)));
    const bool applied =
        decoder_.set_tooth_corrections(std::span<const double>(corr_.data(), static_cast<std::size_t>(n)));
    corr_n_ = applied ? n : 0;
    if (applied && pipeline_) pipeline_->set_wheel_learned(true);
    // The table's own standard error in the in-cycle observers' published 1σ (docs/angle_estimators.md (11)).
    if (applied && pipeline_ && s_.tooth_learn.incycle_sd)
      pipeline_->set_wheel_table_var(wheel_table_accel_var(learner_->order_ids()));
  }
  state_changed_ = true;
}

bool AngleChain::friction_learned() const noexcept {
  if (!pipeline_) return false;
  const FrictionLearner& f = pipeline_->friction();
  if (f.health() != Health::kValid && !f.speed_law_learned()) return false;
  return friction_imported_ || f.motoring_observations() + f.idle_observations() > 0;
}

bool AngleChain::snapshot(LearnedState& st) const noexcept {
  st = LearnedState{};
  if (friction_learned()) {
    const FrictionLearner& f = pipeline_->friction();
    st.friction = f.coefficients();
    if (f.idle_speed_rpm() > 0.0)
      st.friction_idle = std::array<double, 2>{f.idle_correction_nm(), f.idle_speed_rpm()};
    const CoverageScale& r = f.motoring_residual_scale();
    if (r.sd > 0.0) st.friction_residual = std::array<double, 2>{r.sd, static_cast<double>(r.n)};
    if (f.reference_sd_nm() > 0.0) st.friction_reference_sd = f.reference_sd_nm();
    if (f.health() != Health::kValid)
      st.friction_observations = static_cast<double>(f.motoring_observations());
  }
  st.tooth_corrections_rad.assign(corr_.begin(), corr_.begin() + corr_n_);
  if (pipeline_) {
    const FuelTorqueState& f = pipeline_->fuel_model().state();
    if (fuel_imported_ || f.references > 0) st.fuel = f;
    const double crank_var = pipeline_->crank_error_var();
    if (crank_var_imported_ || crank_var > 0.0) st.crank_error_var = crank_var;
    const InertiaLearner& in = pipeline_->inertia();
    if (inertia_imported_ || !in.is_prior())
      st.inertia = std::array<double, 3>{in.scale(), in.information(), s_.engine.j_rot_kgm2};
  }
  if (burn_ && (burn_imported_ || burn_->cycles_behind() > 0))
    st.burn_phase = std::array<double, 2>{burn_->offset_deg(), static_cast<double>(burn_->cycles_behind())};
  return st.friction || !st.tooth_corrections_rad.empty() || st.fuel || st.crank_error_var || st.inertia ||
         st.burn_phase;
}

std::string AngleChain::import_state(const LearnedState& st) {
  std::string what;
  if (st.friction && pipeline_ && pipeline_->friction().import_coefficients(*st.friction)) {
    friction_imported_ = true;
    what = "friction law";
    if (st.friction_idle &&
        pipeline_->friction().import_idle_correction((*st.friction_idle)[0], (*st.friction_idle)[1]))
      what += " with idle correction";
    if (st.friction_residual &&
        pipeline_->friction().import_motoring_residual_scale(
            (*st.friction_residual)[0], static_cast<std::uint32_t>((*st.friction_residual)[1])))
      what += " and motoring residual scale " + std::to_string((*st.friction_residual)[0]) + " N m";
    if (st.friction_reference_sd && pipeline_->friction().import_reference_sd(*st.friction_reference_sd))
      what += " (references 1 sigma " + std::to_string(*st.friction_reference_sd) + " N m)";
    if (st.friction_observations &&
        pipeline_->friction().import_partial(static_cast<std::uint64_t>(*st.friction_observations)))
      what += " (not converged: " + std::to_string(static_cast<std::uint64_t>(*st.friction_observations)) +
              " motoring observations)";
  }
  const std::size_t n = st.tooth_corrections_rad.size();
  if (n > 0 && n <= corr_.size()) {
    const std::span<const double> tab(st.tooth_corrections_rad.data(), n);
    if (learner_) (void)learner_->import_table(tab, s_.tooth_learn.min_cycles);
    if (decoder_.set_tooth_corrections(tab)) {
      std::copy(st.tooth_corrections_rad.begin(), st.tooth_corrections_rad.end(), corr_.begin());
      corr_n_ = static_cast<int>(n);
      if (pipeline_) pipeline_->set_wheel_learned(true);
      what += (what.empty() ? "" : ", ") + std::to_string(n) + " tooth corrections";
    } else {
      what += std::string(what.empty() ? "" : ", ") + "tooth corrections REJECTED (" + std::to_string(n) +
              " values for a wheel of " + std::to_string(s_.wheel.teeth()) + " teeth)";
    }
  }
  if (st.fuel && pipeline_ && pipeline_->fuel_model().import_state(*st.fuel)) {
    fuel_imported_ = true;
    what += (what.empty() ? "" : ", ") + std::string("fuel model (") + std::to_string(st.fuel->references) +
            " reference cycles)";
  }
  if (st.crank_error_var && pipeline_ && std::isfinite(*st.crank_error_var) && *st.crank_error_var >= 0.0) {
    pipeline_->import_crank_error_var(*st.crank_error_var);
    crank_var_imported_ = true;
    what += (what.empty() ? "" : ", ") + std::string("crank-only error variance");
  }
  if (st.inertia && pipeline_) {
    // Learned against another spec J: the same absolute J is k·J_old/J_new of this configuration's.
    const auto& v = *st.inertia;
    const double j_now = s_.engine.j_rot_kgm2;
    const double r = j_now > 0.0 ? v[2] / j_now : 1.0;
    if (pipeline_->inertia().import_state(v[0] * r, v[1] / (r * r))) {
      inertia_imported_ = true;
      what += (what.empty() ? "" : ", ") + std::string("inertia scale ") + std::to_string(v[0] * r);
    } else {
      what += std::string(what.empty() ? "" : ", ") + "inertia scale REJECTED (" + std::to_string(v[0] * r) +
              " x engine.j_rot_kgm2, not within its configured limits)";
    }
  }
  if (st.burn_phase && burn_) {
    const auto& b = *st.burn_phase;
    if (burn_->import_state(b[0], b[1])) {
      pipeline_->set_burn_offset_deg(burn_->offset_deg());
      burn_imported_ = true;
      what += (what.empty() ? "" : ", ") + std::string("burn phase offset ") + std::to_string(b[0]) + " deg";
    } else {
      what += std::string(what.empty() ? "" : ", ") + "burn phase offset REJECTED (" + std::to_string(b[0]) +
              " deg, not within kalman.burn_phase_min/max_offset_deg)";
    }
  }
  state_changed_ = !what.empty();
  return what;
}

}  // namespace torqued
