#include "angle_stage.hpp"

#include <cmath>
#include <limits>
#include <numbers>

#include "estimate.hpp"

namespace torqued {
namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::uint32_t validity_of(const TorqueEstimate& e) noexcept {
  std::uint32_t v = 0;
  switch (e.health) {
    case Health::kValid:
      break;
    case Health::kNotConverged:
    case Health::kNotExcited:
      v |= torque_VALIDITY_NOT_CONVERGED;
      break;
    case Health::kStaleInput:
      v |= torque_VALIDITY_STALE_CAN;
      break;
    case Health::kNoSync:
      v |= torque_VALIDITY_NO_SYNC;
      break;
    default:
      v |= torque_VALIDITY_ESTIMATOR_FAULT;
      break;
  }
  if (!std::isfinite(e.torque_nm)) v |= torque_VALIDITY_ESTIMATOR_FAULT;  // NaN never leaves silently
  return v;
}

std::uint8_t method_of(FusionSourceId id) noexcept {
  switch (id) {
    case FusionSourceId::kEnergyCan:
      return torque_METHOD_CYCLE_ENERGY;
    case FusionSourceId::kCrankOnly:
      return torque_METHOD_LOAD_RLS;
    case FusionSourceId::kEso:
      return torque_METHOD_INDICATED_ESO;
    case FusionSourceId::kExternal:
      return torque_METHOD_UIO;
  }
  return torque_METHOD_FUSED;
}
}  // namespace

AngleStage::AngleStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out, ToothSink* teeth)
    : s_(s), out_(out), teeth_(teeth), decoder_(s.wheel, s.decoder) {
  if (!decoder_.valid()) {
    error_ = "crank decoder: " + decoder_.error();
    return;
  }
  if (dbc) {
    store_ = std::make_unique<SignalStore>(*dbc);
    for (int i = 0; i < kSignalCount; ++i) {
      const SignalSpec& spec = s_.signals[static_cast<std::size_t>(i)];
      if (spec.message.empty()) continue;
      std::string err;
      if (!store_->bind(static_cast<Quantity>(i), spec.message, spec.signal, spec.timeout_ns, &err)) {
        error_ = std::string("signal '") + quantity_name(static_cast<Quantity>(i)) + "': " + err;
        return;
      }
    }
  }
  if (s_.angle_enabled) {
    AnglePipelineConfig ac = s_.angle;
    ac.engine = s_.engine;
    ac.wheel = s_.wheel;
    pipeline_ = std::make_unique<AnglePipeline>(ac);
  }
  if (s_.tooth_learn_enabled)
    learner_ = std::make_unique<ToothErrorLearner>(s_.engine, s_.wheel, s_.tooth_learn);
}

AngleStage::~AngleStage() = default;

std::uint32_t AngleStage::validity_now() const noexcept {
  std::uint32_t v = 0;
  if (decoder_.state() != SyncState::kSynced || !decoder_.phase_known()) v |= torque_VALIDITY_NO_SYNC;
  if (stale_mask_ != 0) v |= torque_VALIDITY_STALE_CAN;
  return v;
}

void AngleStage::on_edge(const EdgeEvent& e, std::int64_t ingest_ns) noexcept {
  last_t_ns_ = e.t_ns;
  ToothEvent te{};
  if (decoder_.on_edge(e, te)) on_tooth(te, ingest_ns);
}

void AngleStage::on_frame(const CanFrame& f) noexcept {
  if (store_) (void)store_->on_frame(f);
}

void AngleStage::poll(std::int64_t now_ns) noexcept {
  if (decoder_.poll(now_ns)) {
    prev_tooth_t_ns_ = -1;
    prev_tooth_ = -1;
  }
}

void AngleStage::on_tooth(const ToothEvent& te, std::int64_t ingest_ns) noexcept {
  const bool synced = te.sync == SyncState::kSynced && te.phase_known;
  ToothSample ts{};
  ts.t_ns = te.t_ns;
  ts.tooth = te.tooth;
  ts.angle_rad = te.angle_rad;
  ts.width_rad = te.width_rad;
  ts.dt_s = prev_tooth_t_ns_ >= 0 ? static_cast<double>(te.t_ns - prev_tooth_t_ns_) * 1e-9 : 0.0;
  ts.synced = synced && prev_tooth_t_ns_ >= 0;

  // EngineSignals at this tooth; remember which bound quantities are stale (published in status).
  const EngineSignals sig = store_ ? store_->signals_at(te.t_ns) : EngineSignals{};
  std::uint32_t stale = 0;
  if (store_) {
    for (int i = 0; i < kSignalCount; ++i) {
      const auto q = static_cast<Quantity>(i);
      if (store_->bound(q) && !store_->valid_at(q, te.t_ns)) stale |= 1u << i;
    }
  }
  stale_mask_ = stale;

  if (teeth_) teeth_->tooth(ts);
  if (learner_) {
    learner_->set_fuel_cutoff(sig.fuel_cutoff_valid && sig.fuel_cutoff);
    learner_->update(ts);
  }
  const std::uint8_t ready = pipeline_ ? pipeline_->on_tooth(ts, sig) : 0;

  // Crank state, decimated.
  double accel = 0.0;
  if (pipeline_ && pipeline_->tooth_output().valid)
    accel = pipeline_->tooth_output().accel_rad_s2;
  else if (ts.dt_s > 0.0)
    accel = (te.speed_rad_s - prev_speed_rad_s_) / ts.dt_s;
  if (++crank_count_ >= s_.crank_decimation) {
    crank_count_ = 0;
    dds::AnySample a;
    a.topic = dds::Topic::kCrankState;
    auto& c = a.u.crank;
    c.seq = ++seq_crank_;
    c.source_t_ns = te.source_t_ns;
    c.ingest_t_ns = ingest_ns;
    c.validity = validity_now();
    c.tooth = static_cast<std::int16_t>(synced ? te.tooth : -1);
    c.sync = static_cast<std::uint8_t>(te.sync);
    c.phase_known = te.phase_known;
    c.angle_rad = te.angle_rad;
    c.speed_rad_s = te.speed_rad_s;
    c.accel_rad_s2 = accel;
    c.events = te.events;
    out_.emit(a);
  }

  // In-cycle indicated torque (Chauvin Kalman / Fourier observers), every n-th tooth. The Kalman estimate is
  // a fixed-lag smoother: its t_ns is the edge it refers to (k-4), so each method is stamped with its own
  // t_ns.
  if (pipeline_ && pipeline_->tooth_output().valid && s_.tooth_estimator_decimation > 0 &&
      ++tooth_est_count_ >= s_.tooth_estimator_decimation) {
    tooth_est_count_ = 0;
    const ToothOutput& to = pipeline_->tooth_output();
    emit_method(torque_METHOD_KALMAN, to.kalman_ind, to.kalman_ind.t_ns, ingest_ns);
    emit_method(torque_METHOD_FOURIER, to.fourier_ind, to.fourier_ind.t_ns, ingest_ns);
  }

  if (ready & AnglePipeline::kSegmentReady) on_segment(te, ingest_ns);

  // Cycle boundary (tooth index wrapped): apply the learned tooth table, publish the learned state.
  if (synced && prev_tooth_ >= 0 && te.tooth < prev_tooth_) {
    ++cycles_;
    if (learner_ && learner_->ready()) {
      const int n = learner_->teeth();
      learner_->edge_corrections(std::span<double>(corr_.data(), static_cast<std::size_t>(n)));
      corrections_applied_ =
          decoder_.set_tooth_corrections(std::span<const double>(corr_.data(), static_cast<std::size_t>(n)));
    }
    publish_snapshot();
  }
  prev_tooth_ = synced ? te.tooth : -1;
  prev_tooth_t_ns_ = te.t_ns;
  prev_speed_rad_s_ = te.speed_rad_s;
}

void AngleStage::emit_method(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns,
                             std::int64_t ingest_ns) noexcept {
  if (e.health == Health::kDisabled) return;
  dds::AnySample a;
  a.topic = dds::Topic::kEstimatorTorque;
  auto& m = a.u.estimator;
  m.method = method;
  m.seq = ++seq_method_[method];
  m.source_t_ns = t_ns;
  m.ingest_t_ns = ingest_ns;
  m.value_nm = e.torque_nm;
  m.uncertainty = e.uncertainty;
  m.health = static_cast<std::uint8_t>(e.health);
  m.validity = validity_of(e);
  out_.emit(a);
}

void AngleStage::on_segment(const ToothEvent& te, std::int64_t ingest_ns) noexcept {
  const CycleOutput& o = pipeline_->cycle_output();
  const int n = s_.engine.cylinders;
  const int pos = ((o.boundary - 1) % n + n) % n;  // firing position whose segment just ended
  const std::int64_t window_ns =
      o.speed_mean_rad_s > 0.0 ? static_cast<std::int64_t>(4.0 * std::numbers::pi / o.speed_mean_rad_s * 1e9)
                               : 0;

  dds::AnySample a;
  a.topic = dds::Topic::kEngineTorque;
  auto& m = a.u.engine;
  m.source_t_ns = te.source_t_ns;
  m.ingest_t_ns = ingest_ns;
  m.kind = torque_KIND_SEGMENT;
  m.cylinder = static_cast<std::uint8_t>(s_.engine.firing_order[static_cast<std::size_t>(pos)]);
  m.cycle = static_cast<std::uint32_t>(cycles_);
  m.window_start_t_ns = te.source_t_ns - window_ns;
  m.speed_rad_s = o.speed_mean_rad_s;
  m.brake_nm = o.brake.torque_nm;
  m.indicated_nm = o.indicated.torque_nm;
  m.friction_nm = o.friction.torque_nm;
  m.load_nm = o.load.torque_nm;
  m.fused_nm = o.fused.brake_nm;
  m.quality = static_cast<std::uint8_t>(o.fused.health);
  m.fused_source = method_of(o.fused.primary);
  m.input_age_ns = o.fused.age_ns;
  m.validity = validity_now() | validity_of(o.brake) |
               validity_of(TorqueEstimate{0, o.fused.brake_nm, 0, o.fused.health});
  if (o.fused.can_lost) m.validity |= torque_VALIDITY_STALE_CAN;
  if (!std::isfinite(m.indicated_nm) || !std::isfinite(m.friction_nm) || !std::isfinite(m.load_nm))
    m.validity |= torque_VALIDITY_ESTIMATOR_FAULT;
  m.seq = ++seq_engine_;
  out_.emit(a);
  if (o.cycle_end) {
    m.kind = torque_KIND_CYCLE;
    m.cylinder = 0;
    m.seq = ++seq_engine_;
    out_.emit(a);
  }

  emit_method(torque_METHOD_CYCLE_ENERGY, o.brake_energy, te.source_t_ns, ingest_ns);
  emit_method(torque_METHOD_LOAD_RLS, o.load_rls, te.source_t_ns, ingest_ns);
  emit_method(torque_METHOD_INDICATED_ESO, o.indicated_eso, te.source_t_ns, ingest_ns);
  emit_method(torque_METHOD_FRICTION, o.friction, te.source_t_ns, ingest_ns);
  emit_method(torque_METHOD_FUSED,
              TorqueEstimate{o.fused.t_ns, o.fused.brake_nm, o.fused.sd_nm, o.fused.health}, te.source_t_ns,
              ingest_ns);

  if (o.cycle_end) {
    const CylinderCycle& cc = o.cylinders;
    dds::AnySample b;
    b.topic = dds::Topic::kCylinderTorque;
    auto& c = b.u.cylinder;
    c.seq = ++seq_cyl_;
    c.source_t_ns = te.source_t_ns;
    c.ingest_t_ns = ingest_ns;
    c.cycle = static_cast<std::uint32_t>(cycles_);
    c.cylinders = static_cast<std::uint8_t>(cc.cylinders);
    for (int i = 0; i < 8; ++i) {
      const bool used = i < cc.cylinders;
      c.indicated_nm[i] = used ? cc.torque_nm[static_cast<std::size_t>(i)] : 0.0;
      c.imbalance_pct[i] = used ? cc.imbalance_pct[static_cast<std::size_t>(i)] : 0.0;
      if (used && cc.misfire[static_cast<std::size_t>(i)])
        c.misfire_mask = static_cast<std::uint8_t>(c.misfire_mask | (1u << i));
    }
    c.health = static_cast<std::uint8_t>(cc.health);
    c.validity = validity_now() | validity_of(TorqueEstimate{0, cc.mean_nm, 0, cc.health});
    out_.emit(b);
  }
}

void AngleStage::publish_snapshot() noexcept {
  const bool fric =
      pipeline_ && pipeline_->friction().health() == Health::kValid &&
      (friction_imported_ ||
       pipeline_->friction().motoring_observations() + pipeline_->friction().idle_observations() > 0);
  const int n = corrections_applied_ && learner_ ? learner_->teeth() : 0;
  if (!fric && n == 0) return;
  snap_seq_.fetch_add(1, std::memory_order_acq_rel);  // odd: writing
  if (fric) {
    const auto c = pipeline_->friction().coefficients();
    for (int i = 0; i < 4; ++i)
      snap_friction_[static_cast<std::size_t>(i)].store(c[static_cast<std::size_t>(i)],
                                                        std::memory_order_relaxed);
  }
  snap_friction_valid_.store(fric, std::memory_order_relaxed);
  const bool idle = fric && pipeline_->friction().idle_speed_rpm() > 0.0;
  if (idle) {
    snap_idle_[0].store(pipeline_->friction().idle_correction_nm(), std::memory_order_relaxed);
    snap_idle_[1].store(pipeline_->friction().idle_speed_rpm(), std::memory_order_relaxed);
  }
  snap_idle_valid_.store(idle, std::memory_order_relaxed);
  for (int i = 0; i < n; ++i)
    snap_teeth_[static_cast<std::size_t>(i)].store(corr_[static_cast<std::size_t>(i)],
                                                   std::memory_order_relaxed);
  snap_n_teeth_.store(n, std::memory_order_relaxed);
  snap_seq_.fetch_add(1, std::memory_order_release);  // even: consistent
}

bool AngleStage::export_state(LearnedState& st) const {
  for (int attempt = 0; attempt < 100; ++attempt) {
    const std::uint32_t s0 = snap_seq_.load(std::memory_order_acquire);
    if (s0 == 0) return false;
    if (s0 & 1u) continue;
    LearnedState tmp;
    if (snap_friction_valid_.load(std::memory_order_relaxed)) {
      std::array<double, 4> c{};
      for (int i = 0; i < 4; ++i)
        c[static_cast<std::size_t>(i)] =
            snap_friction_[static_cast<std::size_t>(i)].load(std::memory_order_relaxed);
      tmp.friction = c;
    }
    if (snap_idle_valid_.load(std::memory_order_relaxed))
      tmp.friction_idle = std::array<double, 2>{snap_idle_[0].load(std::memory_order_relaxed),
                                                snap_idle_[1].load(std::memory_order_relaxed)};
    const int n = snap_n_teeth_.load(std::memory_order_relaxed);
    tmp.tooth_corrections_rad.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i)
      tmp.tooth_corrections_rad[static_cast<std::size_t>(i)] =
          snap_teeth_[static_cast<std::size_t>(i)].load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (snap_seq_.load(std::memory_order_relaxed) == s0) {
      st = std::move(tmp);
      return true;
    }
  }
  return false;
}

void AngleStage::import_state(const LearnedState& st) {
  bool any = false;
  if (st.friction && pipeline_ && pipeline_->friction().import_coefficients(*st.friction)) {
    any = friction_imported_ = true;
    if (st.friction_idle) (void)pipeline_->friction().import_idle_correction((*st.friction_idle)[0], (*st.friction_idle)[1]);
  }
  const auto n = st.tooth_corrections_rad.size();
  if (n > 0 && n <= corr_.size()) {
    const std::span<const double> tab(st.tooth_corrections_rad.data(), n);
    if (learner_) (void)learner_->import_table(tab, s_.tooth_learn.min_cycles);
    if (decoder_.set_tooth_corrections(tab)) {
      std::copy(st.tooth_corrections_rad.begin(), st.tooth_corrections_rad.end(), corr_.begin());
      corrections_applied_ = true;
      any = true;
    }
  }
  if (any) publish_snapshot();
}

void AngleStage::apply(const RuntimeTunables& t) noexcept {
  apply_tunables(s_, t);
  if (store_)
    for (std::size_t i = 0; i < t.signal_timeout_ns.size(); ++i)
      store_->set_timeout(static_cast<Quantity>(i), t.signal_timeout_ns[i]);
}

}  // namespace torqued
