#include "angle_stage.hpp"

#include <cmath>

#include "validity.hpp"

namespace torqued {
namespace {

std::uint32_t validity_of(const ChainStatus& st) noexcept {
  std::uint32_t v = 0;
  if (!st.synced) v |= torque_VALIDITY_NO_SYNC;
  if (st.stale_mask != 0) v |= torque_VALIDITY_STALE_CAN;
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

AngleStage::AngleStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out, ToothSink* time,
                       AngleChainSink* tap)
    : s_(s), out_(out), tap_(tap), chain_(s, dbc, *this, time) {}

void AngleStage::on_edge(const EdgeEvent& e, std::int64_t ingest_ns) noexcept {
  ingest_ns_ = ingest_ns;
  chain_.on_edge(e);
  if (chain_.take_state_changed()) publish_snapshot();
}

void AngleStage::on_tooth(const ChainTooth& t) noexcept {
  const ToothEvent& te = t.event;
  if (++crank_count_ >= s_.crank_decimation) {
    crank_count_ = 0;
    dds::AnySample a;
    a.topic = dds::Topic::kCrankState;
    auto& c = a.u.crank;
    c.seq = ++seq_crank_;
    c.source_t_ns = te.source_t_ns;
    c.ingest_t_ns = ingest_ns_;
    c.validity = validity_of(t.status);
    c.tooth = static_cast<std::int16_t>(te.sync == SyncState::kSynced && te.phase_known ? te.tooth : -1);
    c.sync = static_cast<std::uint8_t>(te.sync);
    c.phase_known = te.phase_known;
    c.angle_rad = te.angle_rad;
    c.speed_rad_s = te.speed_rad_s;
    c.accel_rad_s2 = t.accel_rad_s2;
    c.events = te.events;
    out_.emit(a);
  }
  // In-cycle indicated torque (Chauvin Kalman / Fourier), every n-th tooth. The Kalman estimate is a
  // fixed-lag smoother: its t_ns is the edge it refers to (k-4), so each method is stamped with its own t_ns.
  if (t.estimates && s_.tooth_estimator_decimation > 0 &&
      ++tooth_est_count_ >= s_.tooth_estimator_decimation) {
    tooth_est_count_ = 0;
    emit_method(torque_METHOD_KALMAN, t.estimates->kalman_ind, t.estimates->kalman_ind.t_ns);
    emit_method(torque_METHOD_FOURIER, t.estimates->fourier_ind, t.estimates->fourier_ind.t_ns);
  }
  if (tap_) tap_->on_tooth(t);
}

void AngleStage::emit_method(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns) noexcept {
  if (e.health == Health::kDisabled) return;
  dds::AnySample a;
  a.topic = dds::Topic::kEstimatorTorque;
  auto& m = a.u.estimator;
  m.method = method;
  m.seq = ++seq_method_[method];
  m.source_t_ns = t_ns;
  m.ingest_t_ns = ingest_ns_;
  m.value_nm = e.torque_nm;
  m.uncertainty = e.uncertainty;
  m.health = static_cast<std::uint8_t>(e.health);
  m.validity = validity_of(e);
  out_.emit(a);
}

void AngleStage::on_segment(const ChainSegment& s) noexcept {
  const CycleOutput& o = *s.out;
  emit_engine(s);
  emit_method(torque_METHOD_CYCLE_ENERGY, o.brake_energy, s.source_t_ns);
  emit_method(torque_METHOD_LOAD_RLS, o.load_rls, s.source_t_ns);
  emit_method(torque_METHOD_INDICATED_ESO, o.indicated_eso, s.source_t_ns);
  emit_method(torque_METHOD_FRICTION, o.friction, s.source_t_ns);
  emit_method(torque_METHOD_FUSED,
              TorqueEstimate{o.fused.t_ns, o.fused.brake_nm, o.fused.sd_nm, o.fused.health}, s.source_t_ns);
  if (o.cycle_end) emit_cylinders(s);
  if (tap_) tap_->on_segment(s);
}

void AngleStage::emit_engine(const ChainSegment& s) noexcept {
  const CycleOutput& o = *s.out;
  dds::AnySample a;
  a.topic = dds::Topic::kEngineTorque;
  auto& m = a.u.engine;
  m.source_t_ns = s.source_t_ns;
  m.ingest_t_ns = ingest_ns_;
  m.kind = torque_KIND_SEGMENT;
  m.cylinder = static_cast<std::uint8_t>(s.cylinder);
  m.cycle = static_cast<std::uint32_t>(s.cycle);
  m.window_start_t_ns = s.window_start_t_ns;
  m.speed_rad_s = o.speed_mean_rad_s;
  m.brake_nm = o.brake.torque_nm;
  m.indicated_nm = o.indicated.torque_nm;
  m.friction_nm = o.friction.torque_nm;
  m.load_nm = o.load.torque_nm;
  m.fused_nm = o.fused.brake_nm;
  m.quality = static_cast<std::uint8_t>(o.fused.health);
  m.fused_source = method_of(o.fused.primary);
  m.input_age_ns = o.fused.age_ns;
  m.validity = validity_of(s.status) | validity_of(o.brake) | validity_of(o.fused.health, o.fused.brake_nm);
  if (o.fused.can_lost) m.validity |= torque_VALIDITY_STALE_CAN;
  if (o.fused.quality == FusionQuality::kPriorOnly) m.validity |= torque_VALIDITY_PRIOR_ONLY;
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
}

void AngleStage::emit_cylinders(const ChainSegment& s) noexcept {
  const CylinderCycle& cc = s.out->cylinders;
  dds::AnySample b;
  b.topic = dds::Topic::kCylinderTorque;
  auto& c = b.u.cylinder;
  c.seq = ++seq_cyl_;
  c.source_t_ns = s.source_t_ns;
  c.ingest_t_ns = ingest_ns_;
  c.cycle = static_cast<std::uint32_t>(s.cycle);
  c.cylinders = static_cast<std::uint8_t>(cc.cylinders);
  for (int i = 0; i < 8; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    const bool used = i < cc.cylinders;
    c.indicated_nm[i] = used ? cc.torque_nm[ii] : 0.0;
    c.imbalance_pct[i] = used ? cc.imbalance_pct[ii] : 0.0;
    c.imbalance_filtered_pct[i] = used ? cc.imbalance_filtered_pct[ii] : 0.0;
    if (used && cc.misfire[ii]) c.misfire_mask = static_cast<std::uint8_t>(c.misfire_mask | (1u << i));
  }
  c.imbalance_sd_pct = cc.imbalance_sd_pct;
  c.health = static_cast<std::uint8_t>(cc.health);
  c.validity = validity_of(s.status) | validity_of(cc.health, cc.mean_nm);
  out_.emit(b);
}

void AngleStage::publish_snapshot() noexcept {
  if (!chain_.snapshot(scratch_)) return;
  snap_seq_.fetch_add(1, std::memory_order_acq_rel);  // odd: writing
  if (scratch_.friction_valid)
    for (std::size_t i = 0; i < 4; ++i)
      snap_friction_[i].store(scratch_.friction[i], std::memory_order_relaxed);
  snap_friction_valid_.store(scratch_.friction_valid, std::memory_order_relaxed);
  if (scratch_.idle_valid)
    for (std::size_t i = 0; i < 2; ++i) snap_idle_[i].store(scratch_.idle[i], std::memory_order_relaxed);
  snap_idle_valid_.store(scratch_.idle_valid, std::memory_order_relaxed);
  if (scratch_.fric_res_valid)
    for (std::size_t i = 0; i < 2; ++i)
      snap_fric_res_[i].store(scratch_.fric_res[i], std::memory_order_relaxed);
  snap_fric_res_valid_.store(scratch_.fric_res_valid, std::memory_order_relaxed);
  for (int i = 0; i < scratch_.n_teeth; ++i)
    snap_teeth_[static_cast<std::size_t>(i)].store(scratch_.teeth[static_cast<std::size_t>(i)],
                                                   std::memory_order_relaxed);
  snap_n_teeth_.store(scratch_.n_teeth, std::memory_order_relaxed);
  if (scratch_.fuel_valid) {
    std::array<double, kFuelStateDoubles> v{};
    pack(scratch_.fuel, v);
    for (std::size_t i = 0; i < v.size(); ++i) snap_fuel_[i].store(v[i], std::memory_order_relaxed);
  }
  snap_fuel_valid_.store(scratch_.fuel_valid, std::memory_order_relaxed);
  snap_crank_var_.store(scratch_.crank_var, std::memory_order_relaxed);
  snap_crank_var_valid_.store(scratch_.crank_var_valid, std::memory_order_relaxed);
  for (std::size_t i = 0; i < 3; ++i) snap_inertia_[i].store(scratch_.inertia[i], std::memory_order_relaxed);
  snap_inertia_valid_.store(scratch_.inertia_valid, std::memory_order_relaxed);
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
      for (std::size_t i = 0; i < 4; ++i) c[i] = snap_friction_[i].load(std::memory_order_relaxed);
      tmp.friction = c;
    }
    if (snap_idle_valid_.load(std::memory_order_relaxed))
      tmp.friction_idle = std::array<double, 2>{snap_idle_[0].load(std::memory_order_relaxed),
                                                snap_idle_[1].load(std::memory_order_relaxed)};
    if (snap_fric_res_valid_.load(std::memory_order_relaxed))
      tmp.friction_residual = std::array<double, 2>{snap_fric_res_[0].load(std::memory_order_relaxed),
                                                    snap_fric_res_[1].load(std::memory_order_relaxed)};
    const int n = snap_n_teeth_.load(std::memory_order_relaxed);
    tmp.tooth_corrections_rad.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i)
      tmp.tooth_corrections_rad[static_cast<std::size_t>(i)] =
          snap_teeth_[static_cast<std::size_t>(i)].load(std::memory_order_relaxed);
    if (snap_fuel_valid_.load(std::memory_order_relaxed)) {
      std::array<double, kFuelStateDoubles> v{};
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = snap_fuel_[i].load(std::memory_order_relaxed);
      tmp.fuel = unpack(v);
    }
    if (snap_crank_var_valid_.load(std::memory_order_relaxed))
      tmp.crank_error_var = snap_crank_var_.load(std::memory_order_relaxed);
    if (snap_inertia_valid_.load(std::memory_order_relaxed))
      tmp.inertia = std::array<double, 3>{snap_inertia_[0].load(std::memory_order_relaxed),
                                          snap_inertia_[1].load(std::memory_order_relaxed),
                                          snap_inertia_[2].load(std::memory_order_relaxed)};
    std::atomic_thread_fence(std::memory_order_acquire);
    if (snap_seq_.load(std::memory_order_relaxed) == s0) {
      st = std::move(tmp);
      return true;
    }
  }
  return false;
}

std::string AngleStage::import_state(const LearnedState& st) {
  std::string what = chain_.import_state(st);
  if (chain_.take_state_changed()) publish_snapshot();
  return what;
}

void AngleStage::apply(const RuntimeTunables& t) noexcept {
  apply_tunables(s_, t);
  chain_.set_signal_timeouts(t.signal_timeout_ns);
}

}  // namespace torqued
