#include "angle_stage.hpp"

#include "estimate.hpp"

#include <cmath>
#include <limits>
#include <numbers>

namespace torqued {
namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

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
}

AngleStage::~AngleStage() = default;

std::uint32_t AngleStage::validity_now() const noexcept {
  std::uint32_t v = 0;
  if (decoder_.state() != SyncState::kSynced || !decoder_.phase_known()) v |= torque_VALIDITY_NO_SYNC;
  if (stale_mask_ != 0) v |= torque_VALIDITY_STALE_CAN;
  return v;
}

void AngleStage::on_edge(const EdgeEvent& e, std::int64_t ingest_ns) noexcept {
  ++edges_;
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
    cycle_start_t_ns_ = -1;
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
  EngineSignals sig{};
  std::uint32_t stale = 0;
  if (store_) {
    sig = store_->signals_at(te.t_ns);
    for (int i = 0; i < kSignalCount; ++i) {
      const auto q = static_cast<Quantity>(i);
      if (store_->bound(q) && !store_->valid_at(q, te.t_ns)) stale |= 1u << i;
    }
  }
  stale_mask_ = stale;
  (void)sig;  // consumed by the angle-domain estimators

  if (teeth_) teeth_->tooth(ts);

  // Crank state, decimated; acceleration from consecutive tooth speeds.
  double accel = 0.0;
  if (ts.dt_s > 0.0) accel = (te.speed_rad_s - prev_speed_rad_s_) / ts.dt_s;
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

  // Cycle boundary: tooth index wrapped to the start of the 720° cycle.
  if (synced) {
    if (prev_tooth_ >= 0 && te.tooth < prev_tooth_) end_of_cycle(te, ingest_ns);
    if (cycle_start_t_ns_ < 0 || te.tooth < prev_tooth_) cycle_start_t_ns_ = te.t_ns;
    prev_tooth_ = te.tooth;
  } else {
    prev_tooth_ = -1;
    cycle_start_t_ns_ = -1;
  }
  prev_tooth_t_ns_ = te.t_ns;
  prev_speed_rad_s_ = te.speed_rad_s;
}

void AngleStage::end_of_cycle(const ToothEvent& te, std::int64_t ingest_ns) noexcept {
  if (cycle_start_t_ns_ < 0 || te.t_ns <= cycle_start_t_ns_) return;
  ++cycles_;
  const double period_s = static_cast<double>(te.t_ns - cycle_start_t_ns_) * 1e-9;
  dds::AnySample a;
  a.topic = dds::Topic::kEngineTorque;
  auto& m = a.u.engine;
  m.seq = ++seq_engine_;
  m.source_t_ns = te.source_t_ns;
  m.ingest_t_ns = ingest_ns;
  m.kind = torque_KIND_CYCLE;
  m.cycle = static_cast<std::uint32_t>(cycles_);
  m.speed_rad_s = 4.0 * std::numbers::pi / period_s;
  // Torques come from the angle-domain estimators; until they run here the values are NaN and flagged.
  m.brake_nm = m.indicated_nm = m.friction_nm = m.fused_nm = kNaN;
  m.load_nm = kNaN;
  if (store_ && store_->valid_at(Quantity::kLoadTorque, te.t_ns)) m.load_nm = store_->value(Quantity::kLoadTorque).value;
  m.quality = static_cast<std::uint8_t>(Health::kDisabled);
  m.validity = validity_now() | torque_VALIDITY_ESTIMATOR_FAULT;
  m.fused_source = torque_METHOD_FUSED;
  m.input_age_ns = 0;
  out_.emit(a);
}

}  // namespace torqued
