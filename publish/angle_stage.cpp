#include "angle_stage.hpp"

#include <array>
#include <cmath>

#include "sample_builder.hpp"
#include "validity.hpp"

namespace torqued {
namespace {

constexpr InCycleMethodOutput output_of(std::uint8_t method) {
  for (const auto& b : kInCycleMethodOutputs)
    if (b.method == method) return b;
  return {};
}
/// The registry's in-cycle methods in registry order, each with its ToothOutput member.
constexpr auto kInCycleEmitted = [] {
  std::array<InCycleMethodOutput, dds::method_count(dds::MethodDomain::kAngleInCycle)> a{};
  std::size_t k = 0;
  for (const auto& m : dds::kMethods)
    if (m.domain == dds::MethodDomain::kAngleInCycle) a[k++] = output_of(m.id);
  return a;
}();
constexpr bool every_in_cycle_method_bound() {
  for (const auto& b : kInCycleEmitted)
    if (b.estimate == nullptr) return false;
  return std::size(kInCycleMethodOutputs) == kInCycleEmitted.size();
}
static_assert(
    every_in_cycle_method_bound(),
    "an in-cycle method of idl/methods.hpp has no row in kInCycleMethodOutputs (chain/angle_pipeline.hpp), "
    "or a row names a method that is not in-cycle");

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
  // In-cycle indicated torque (the registry's in-cycle methods: Chauvin Kalman / Fourier), every n-th tooth.
  // The Kalman estimate is a fixed-lag smoother: its t_ns is the edge it refers to (k-4), so each method is
  // stamped with its own t_ns.
  if (t.estimates && s_.tooth_estimator_decimation > 0 &&
      ++tooth_est_count_ >= s_.tooth_estimator_decimation) {
    tooth_est_count_ = 0;
    for (const InCycleMethodOutput& b : kInCycleEmitted) {
      const TorqueEstimate& e = (*t.estimates).*b.estimate;
      emit_method(b.method, e, e.t_ns);
    }
  }
  if (tap_) tap_->on_tooth(t);
}

void AngleStage::emit_method(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns) noexcept {
  dds::AnySample a;
  if (!estimator_sample(method, seq_method_[method] + 1, e, t_ns, ingest_ns_, a)) return;
  ++seq_method_[method];
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
  if (chain_.snapshot(scratch_)) learned_.store(scratch_);
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
