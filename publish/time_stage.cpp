#include "time_stage.hpp"

#include <array>

#include "methods.hpp"
#include "sample_builder.hpp"

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
    : s_(s), out_(out), chain_(s, dbc) {}

TimeStage::~TimeStage() = default;

void TimeStage::emit(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns,
                     std::int64_t ingest_ns) noexcept {
  dds::AnySample a;
  if (!estimator_sample(method, seq_method_[method] + 1, e, t_ns, ingest_ns, a)) return;
  ++seq_method_[method];
  out_.emit(a);
}

void TimeStage::step(std::int64_t t_ns, std::int64_t ingest_ns) noexcept {
  ++steps_;
  const TimePipelineOutput& o = chain_.step(t_ns);
  if (++decim_count_ < s_.time_decimation) return;
  decim_count_ = 0;
  for (const TimeMethodOutput& b : kTimeEmitted) emit(b.method, o.*b.estimate, t_ns, ingest_ns);
}

void TimeStage::apply(const RuntimeTunables& t) noexcept {
  apply_tunables(s_, t);
  chain_.set_timeouts(t);
}

}  // namespace torqued
