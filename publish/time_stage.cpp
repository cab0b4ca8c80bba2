#include "time_stage.hpp"

#include <array>

#include "methods.hpp"
#include "validity.hpp"

namespace torqued {
namespace {

using dds::MethodDomain;

constexpr TimeMethodOutput output_of(std::uint8_t method) {
  for (const auto& b : kTimeMethodOutputs)
    if (b.method == method) return b;
  return {};
}
/// The registry's time-domain methods in registry order, each with its TimePipelineOutput member.
constexpr auto kTimeEmitted = [] {
  std::array<TimeMethodOutput, dds::method_count(MethodDomain::kTime)> a{};
  std::size_t k = 0;
  for (const auto& m : dds::kMethods)
    if (m.domain == MethodDomain::kTime) a[k++] = output_of(m.id);
  return a;
}();
constexpr bool every_time_method_bound() {
  for (const auto& b : kTimeEmitted)
    if (b.estimate == nullptr) return false;
  return std::size(kTimeMethodOutputs) == kTimeEmitted.size();
}
static_assert(
    every_time_method_bound(),
    "a time-domain method of idl/methods.hpp has no row in kTimeMethodOutputs (chain/time_pipeline.hpp), "
    "or a row names a method that is not of the time domain");

}  // namespace

TimeStage::TimeStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out)
    : s_(s), out_(out), pipeline_(s.time_pipeline, s.time_estimators, s.engine) {
  pipeline_.set_e_machine(s.angle.e_machine);  // hybrid input: the same net load as the angle chain
  pipeline_.set_load_reference(s.angle.load_ref);
  step_ns_ = static_cast<std::int64_t>(std::llround(s.time_pipeline.step_s * 1e9));
  if (step_ns_ <= 0) error_ = "time pipeline step must be > 0";
  if (dbc) {
    store_ = std::make_unique<SignalStore>(*dbc);
    if (error_.empty()) error_ = bind_signals(*store_, s_.signals);
  }
}

TimeStage::~TimeStage() = default;

void TimeStage::on_tooth(const ToothSample& t) noexcept { pipeline_.on_tooth(t); }

void TimeStage::on_frame(const CanFrame& f) noexcept {
  if (store_) (void)store_->on_frame(f);
}

void TimeStage::emit(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns,
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

void TimeStage::step(std::int64_t t_ns, std::int64_t ingest_ns) noexcept {
  ++steps_;
  const EngineSignals sig = store_ ? store_->signals_at(t_ns) : EngineSignals{};
  const TimePipelineOutput& o = pipeline_.step(t_ns, sig);
  if (++decim_count_ < s_.time_decimation) return;
  decim_count_ = 0;
  for (const TimeMethodOutput& b : kTimeEmitted) emit(b.method, o.*b.estimate, t_ns, ingest_ns);
}

void TimeStage::apply(const RuntimeTunables& t) noexcept {
  apply_tunables(s_, t);
  if (store_)
    for (std::size_t i = 0; i < t.signal_timeout_ns.size(); ++i)
      store_->set_timeout(static_cast<Quantity>(i), t.signal_timeout_ns[i]);
}

}  // namespace torqued
