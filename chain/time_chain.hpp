#pragma once
// The time chain: the ONE place where tooth samples and CAN frames become the time-triggered estimates of
// Na et al. (time_pipeline.hpp), stepped at a fixed rate on the edge clock. It owns its own signal store (the
// CAN frames it is given, decoded with the DBC), the pipeline and its step. No DDS, no threads: the time
// stage (publish/time_stage.hpp) maps its outputs onto topics, on the time thread (paced/live) or inline
// (fast replay); tests drive it directly. on_tooth/on_frame/step are real-time safe (no allocation, no lock).
#include <cstdint>
#include <memory>
#include <string>

#include "dbc.hpp"
#include "signal_store.hpp"
#include "stage_settings.hpp"
#include "time_pipeline.hpp"

namespace torqued {

class TimeChain {
 public:
  /// `dbc` may be null (no CAN: every signal stays invalid). ok() says whether the settings were usable.
  TimeChain(const StageSettings& s, const DbcDatabase* dbc);
  ~TimeChain();
  TimeChain(const TimeChain&) = delete;
  TimeChain& operator=(const TimeChain&) = delete;

  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  /// Mean speed input: the angle chain's tooth samples.
  void on_tooth(const ToothSample& t) noexcept { pipeline_.on_tooth(t); }
  /// CAN input (load torque, MAF, machine torque, flags), decoded into the chain's own signal store.
  void on_frame(const CanFrame& f) noexcept;
  /// One step at edge-clock time t_ns with the signals valid then.
  const TimePipelineOutput& step(std::int64_t t_ns) noexcept;
  /// New sensor time-outs (SIGHUP), between two events on the chain's thread.
  void set_timeouts(const RuntimeTunables& t) noexcept;

  [[nodiscard]] std::int64_t step_ns() const noexcept { return step_ns_; }
  [[nodiscard]] const TimePipeline& pipeline() const noexcept { return pipeline_; }

 private:
  std::unique_ptr<SignalStore> store_;
  TimePipeline pipeline_;
  std::string error_;
  std::int64_t step_ns_ = 1'000'000;
};

}  // namespace torqued
