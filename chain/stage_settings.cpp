#include "stage_settings.hpp"

#include <cmath>

namespace torqued {

RuntimeTunables tunables_of(const StageSettings& s) noexcept {
  RuntimeTunables t;
  t.crank_decimation = s.crank_decimation;
  t.time_decimation = s.time_decimation;
  t.tooth_estimator_decimation = s.tooth_estimator_decimation;
  t.edge_timeout_ns = s.edge_timeout_ns;
  for (std::size_t i = 0; i < t.signal_timeout_ns.size(); ++i)
    t.signal_timeout_ns[i] = s.signals[i].timeout_ns;
  return t;
}

void apply_tunables(StageSettings& s, const RuntimeTunables& t) noexcept {
  s.crank_decimation = t.crank_decimation;
  s.time_decimation = t.time_decimation;
  s.tooth_estimator_decimation = t.tooth_estimator_decimation;
  s.edge_timeout_ns = t.edge_timeout_ns;
  for (std::size_t i = 0; i < t.signal_timeout_ns.size(); ++i)
    s.signals[i].timeout_ns = t.signal_timeout_ns[i];
}

std::string bind_signals(SignalStore& store, const std::array<SignalSpec, kSignalCount>& signals) {
  for (int i = 0; i < kSignalCount; ++i) {
    const SignalSpec& spec = signals[static_cast<std::size_t>(i)];
    if (spec.message.empty()) continue;
    std::string err;
    if (!store.bind(static_cast<Quantity>(i), spec.message, spec.signal, spec.timeout_ns, &err))
      return std::string("signal '") + quantity_name(static_cast<Quantity>(i)) + "': " + err;
  }
  return {};
}

}  // namespace torqued
