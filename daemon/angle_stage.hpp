#pragma once
// Angle stage: crank/cam edges -> crank decoder -> ToothSample -> angle-domain estimators; per tooth the
// decimated CrankState, per combustion segment and per 720° cycle EngineTorque / CylinderTorque /
// EstimatorTorque samples. CAN frames feed its own SignalStore copy (EngineSignals at each tooth).
// Runs on the angle pipeline thread (paced/live) or inline in fast replay. on_edge/on_frame/poll are
// real-time safe: no allocation, no lock, no blocking; everything is sized in the constructor.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "crank_decoder.hpp"
#include "dbc.hpp"
#include "sample_sink.hpp"
#include "signal_store.hpp"
#include "stage_settings.hpp"

namespace torqued {

class AngleStage {
 public:
  /// dbc may be null (no CAN): estimators then see every signal invalid.
  AngleStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out, ToothSink* teeth);
  ~AngleStage();
  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  /// ingest_ns: CLOCK_REALTIME at which the edge became available (0 in fast replay).
  void on_edge(const EdgeEvent& e, std::int64_t ingest_ns) noexcept;
  void on_frame(const CanFrame& f) noexcept;
  /// Stall detection on the edge clock (live: call when no edge arrived for a while).
  void poll(std::int64_t now_ns) noexcept;

  [[nodiscard]] const CrankDecoder& decoder() const noexcept { return decoder_; }
  [[nodiscard]] const SignalStore* signals() const noexcept { return store_.get(); }
  [[nodiscard]] std::uint64_t cycles() const noexcept { return cycles_; }
  [[nodiscard]] std::int64_t last_t_ns() const noexcept { return last_t_ns_; }
  /// Bit i set = EngineSignals quantity i bound but stale at the last tooth.
  [[nodiscard]] std::uint32_t stale_mask() const noexcept { return stale_mask_; }
  /// Monotonic progress counter (edges processed), read by the supervisor for the watchdog.
  [[nodiscard]] std::uint64_t progress() const noexcept { return edges_; }

  /// Learned tooth corrections (rad per tooth of 720° or per revolution); not real-time.
  bool set_tooth_corrections(std::span<const double> rad) noexcept { return decoder_.set_tooth_corrections(rad); }

 private:
  void on_tooth(const ToothEvent& te, std::int64_t ingest_ns) noexcept;
  void end_of_cycle(const ToothEvent& te, std::int64_t ingest_ns) noexcept;
  std::uint32_t validity_now() const noexcept;

  StageSettings s_;
  SampleSink& out_;
  ToothSink* teeth_;
  CrankDecoder decoder_;
  std::unique_ptr<SignalStore> store_;
  std::string error_;

  std::uint64_t edges_ = 0;
  std::uint64_t cycles_ = 0;
  std::int64_t last_t_ns_ = 0;
  std::int64_t prev_tooth_t_ns_ = -1;
  double prev_speed_rad_s_ = 0.0;
  std::int64_t cycle_start_t_ns_ = -1;
  int prev_tooth_ = -1;
  int crank_count_ = 0;
  std::uint32_t stale_mask_ = 0;
  std::uint64_t seq_engine_ = 0, seq_cyl_ = 0, seq_crank_ = 0;
  std::array<std::uint64_t, 16> seq_method_{};
};

}  // namespace torqued
