#pragma once
// Time stage: the time-triggered estimators of Na et al. (chain/time_pipeline.hpp) stepped at a fixed
// rate (default 1 kHz) on the edge clock. Inputs: tooth samples from the angle stage (mean speed), load
// torque and MAF from its own SignalStore copy. Outputs: EstimatorTorque per time method, decimated
// (StageSettings::time_decimation). Runs on the time pipeline thread (timerfd) or inline in fast replay.
// on_tooth/on_frame/step are real-time safe (no allocation, no lock, no blocking).
#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "dbc.hpp"
#include "methods.hpp"
#include "sample_sink.hpp"
#include "signal_store.hpp"
#include "stage_settings.hpp"
#include "time_pipeline.hpp"

namespace torqued {

class TimeStage {
 public:
  TimeStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out);
  ~TimeStage();
  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  void on_tooth(const ToothSample& t) noexcept;
  void on_frame(const CanFrame& f) noexcept;
  /// SIGHUP: new decimations / sensor time-outs, applied between two events on this stage's thread.
  void apply(const RuntimeTunables& t) noexcept;
  /// One step at edge-clock time t_ns; ingest_ns: CLOCK_REALTIME of the tick (0 in fast replay).
  void step(std::int64_t t_ns, std::int64_t ingest_ns) noexcept;

  [[nodiscard]] std::int64_t step_ns() const noexcept { return step_ns_; }
  [[nodiscard]] std::uint64_t steps() const noexcept { return steps_; }
  [[nodiscard]] const TimePipeline& pipeline() const noexcept { return pipeline_; }

 private:
  void emit(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns, std::int64_t ingest_ns) noexcept;

  StageSettings s_;
  SampleSink& out_;
  std::unique_ptr<SignalStore> store_;
  TimePipeline pipeline_;
  std::string error_;
  std::int64_t step_ns_ = 1'000'000;
  std::uint64_t steps_ = 0;
  int decim_count_ = 0;
  std::array<std::uint64_t, dds::kMethodCount> seq_method_{};  ///< per method id (idl/methods.hpp)
};

}  // namespace torqued
