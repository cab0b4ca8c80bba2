#pragma once
// Time stage: the time-triggered estimators (Na et al.) stepped at a fixed rate (default 1 kHz) on the edge
// clock. Inputs: mean crank speed from the tooth samples of the angle stage, load torque and MAF from its own
// SignalStore copy. Outputs: EstimatorTorque per time method, decimated (StageSettings::time_decimation).
// Runs on the time pipeline thread (timerfd) or inline in fast replay. Real-time safe after construction.
#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "dbc.hpp"
#include "sample_sink.hpp"
#include "signal_store.hpp"
#include "stage_settings.hpp"

namespace torqued {

class TimePipelineAdapter;  // wraps estimators/time_pipeline.hpp when built with it

class TimeStage {
 public:
  TimeStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out);
  ~TimeStage();
  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  void on_tooth(const ToothSample& t) noexcept;
  void on_frame(const CanFrame& f) noexcept;
  /// One step at edge-clock time t_ns; ingest_ns: CLOCK_REALTIME of the tick (0 in fast replay).
  void step(std::int64_t t_ns, std::int64_t ingest_ns) noexcept;

  [[nodiscard]] std::int64_t step_ns() const noexcept { return step_ns_; }
  [[nodiscard]] std::uint64_t steps() const noexcept { return steps_; }
  [[nodiscard]] std::uint64_t progress() const noexcept { return steps_; }
  /// Mean speed over the last 720° (rad/s), 0 when unknown.
  [[nodiscard]] double mean_speed_rad_s() const noexcept { return mean_speed_rad_s_; }

 private:
  StageSettings s_;
  SampleSink& out_;
  std::unique_ptr<SignalStore> store_;
  std::unique_ptr<TimePipelineAdapter> pipeline_;
  std::string error_;
  std::int64_t step_ns_ = 1'000'000;
  std::uint64_t steps_ = 0;
  int decim_count_ = 0;
  // Mean speed over the last 720°: ring of tooth periods (sized at construction from the wheel).
  std::array<double, 2 * kMaxTeeth> dt_ring_{};
  std::array<double, 2 * kMaxTeeth> w_ring_{};
  int ring_n_ = 0, ring_i_ = 0, ring_len_ = 0;
  double sum_dt_ = 0.0, sum_w_ = 0.0;
  double mean_speed_rad_s_ = 0.0;
  std::int64_t last_tooth_t_ns_ = -1;
  std::array<std::uint64_t, 16> seq_method_{};
};

}  // namespace torqued
