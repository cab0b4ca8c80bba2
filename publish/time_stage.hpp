#pragma once
// Time stage: the topic mapping of the time chain (chain/time_chain.hpp, where tooth samples and CAN frames
// become the time-triggered estimates of Na et al.). Outputs: EstimatorTorque per time method of the registry
// (idl/methods.hpp), decimated (StageSettings::time_decimation). Runs on the time pipeline thread (timerfd)
// or inline in fast replay. on_tooth/on_frame/step are real-time safe (no allocation, no lock, no blocking).
#include <array>
#include <cstdint>
#include <string>

#include "dbc.hpp"
#include "methods.hpp"
#include "sample_sink.hpp"
#include "stage_settings.hpp"
#include "time_chain.hpp"

namespace torqued {

class TimeStage {
 public:
  TimeStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out);
  ~TimeStage();
  [[nodiscard]] bool ok() const noexcept { return chain_.ok(); }
  [[nodiscard]] const std::string& error() const noexcept { return chain_.error(); }

  void on_tooth(const ToothSample& t) noexcept { chain_.on_tooth(t); }
  void on_frame(const CanFrame& f) noexcept { chain_.on_frame(f); }
  /// SIGHUP: new decimations / sensor time-outs, applied between two events on this stage's thread.
  void apply(const RuntimeTunables& t) noexcept;
  /// One step at edge-clock time t_ns; ingest_ns: CLOCK_REALTIME of the tick (0 in fast replay).
  void step(std::int64_t t_ns, std::int64_t ingest_ns) noexcept;

  [[nodiscard]] std::int64_t step_ns() const noexcept { return chain_.step_ns(); }
  [[nodiscard]] std::uint64_t steps() const noexcept { return steps_; }
  [[nodiscard]] const TimePipeline& pipeline() const noexcept { return chain_.pipeline(); }

 private:
  void emit(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns, std::int64_t ingest_ns) noexcept;

  StageSettings s_;
  SampleSink& out_;
  TimeChain chain_;
  std::uint64_t steps_ = 0;
  int decim_count_ = 0;
  std::array<std::uint64_t, dds::kMethodCount> seq_method_{};  ///< per method id (idl/methods.hpp)
};

}  // namespace torqued
