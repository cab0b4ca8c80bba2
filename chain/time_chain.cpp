#include "time_chain.hpp"

#include <cmath>

namespace torqued {

TimeChain::TimeChain(const StageSettings& s, const DbcDatabase* dbc)
    : pipeline_(s.time_pipeline, s.time_estimators, s.engine) {
  pipeline_.set_e_machine(s.angle.e_machine);  // hybrid input: the same net load as the angle chain
  pipeline_.set_load_reference(s.angle.load_ref);
  step_ns_ = static_cast<std::int64_t>(std::llround(s.time_pipeline.step_s * 1e9));
  if (step_ns_ <= 0) error_ = "time pipeline step must be > 0";
  if (dbc) {
    store_ = std::make_unique<SignalStore>(*dbc);
    if (error_.empty()) error_ = bind_signals(*store_, s.signals);
  }
}

TimeChain::~TimeChain() = default;

void TimeChain::on_frame(const CanFrame& f) noexcept {
  if (store_) (void)store_->on_frame(f);
}

const TimePipelineOutput& TimeChain::step(std::int64_t t_ns) noexcept {
  static constexpr EngineSignals kNoSignals{};
  std::uint32_t stale = 0;  // the store's cached snapshot, not a copy per step
  return pipeline_.step(t_ns, store_ ? store_->snapshot_at(t_ns, stale) : kNoSignals);
}

void TimeChain::set_timeouts(const RuntimeTunables& t) noexcept {
  if (!store_) return;
  for (std::size_t i = 0; i < t.signal_timeout_ns.size(); ++i)
    store_->set_timeout(static_cast<Quantity>(i), t.signal_timeout_ns[i]);
}

}  // namespace torqued
