#pragma once
// Angle stage: crank/cam edges -> crank decoder -> ToothSample -> AnglePipeline (energies chain, friction,
// per-cylinder, fusion) and ToothErrorLearner (corrections fed back to the decoder). Emits the decimated
// CrankState per tooth, EngineTorque + EstimatorTorque per combustion segment (rolling 720° window) and per
// cycle, CylinderTorque per cycle. CAN frames feed its own SignalStore copy (EngineSignals at each tooth).
// Runs on the angle pipeline thread (paced/live) or inline in fast replay. on_edge/on_frame/poll are
// real-time safe: no allocation, no lock, no blocking; everything is sized in the constructor.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "angle_pipeline.hpp"
#include "crank_decoder.hpp"
#include "dbc.hpp"
#include "sample_sink.hpp"
#include "signal_store.hpp"
#include "stage_settings.hpp"
#include "state_store.hpp"
#include "tooth_error_learner.hpp"

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
  /// SIGHUP: new decimations / sensor time-outs, applied between two events on this stage's thread.
  void apply(const RuntimeTunables& t) noexcept;
  /// Stall detection on the edge clock (live: call when no edge arrived for a while).
  void poll(std::int64_t now_ns) noexcept;

  [[nodiscard]] const CrankDecoder& decoder() const noexcept { return decoder_; }
  [[nodiscard]] std::uint64_t cycles() const noexcept { return cycles_; }
  [[nodiscard]] std::int64_t last_t_ns() const noexcept { return last_t_ns_; }
  /// Bit i set = EngineSignals quantity i bound but stale at the last tooth.
  [[nodiscard]] std::uint32_t stale_mask() const noexcept { return stale_mask_; }

  /// Before start (no concurrent on_edge): restore persisted friction coefficients and tooth corrections.
  void import_state(const LearnedState& st);
  /// From any thread: the newest learned state published by the stage at a cycle end (seqlock snapshot).
  /// Returns false when nothing was learned or imported yet.
  bool export_state(LearnedState& st) const;

 private:
  void on_tooth(const ToothEvent& te, std::int64_t ingest_ns) noexcept;
  void on_segment(const ToothEvent& te, std::int64_t ingest_ns) noexcept;
  void emit_method(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns,
                   std::int64_t ingest_ns) noexcept;
  void publish_snapshot() noexcept;
  std::uint32_t validity_now() const noexcept;

  StageSettings s_;
  SampleSink& out_;
  ToothSink* teeth_;
  CrankDecoder decoder_;
  std::unique_ptr<SignalStore> store_;
  std::unique_ptr<AnglePipeline> pipeline_;
  std::unique_ptr<ToothErrorLearner> learner_;
  std::string error_;

  std::uint64_t cycles_ = 0;
  std::int64_t last_t_ns_ = 0;
  std::int64_t prev_tooth_t_ns_ = -1;
  double prev_speed_rad_s_ = 0.0;
  int prev_tooth_ = -1;
  int crank_count_ = 0;
  int tooth_est_count_ = 0;
  std::uint32_t stale_mask_ = 0;
  std::uint64_t seq_engine_ = 0, seq_cyl_ = 0, seq_crank_ = 0;
  std::array<std::uint64_t, 16> seq_method_{};
  std::array<double, 2 * kMaxTeeth> corr_{};  ///< scratch for the learner's table
  bool corrections_applied_ = false;
  bool friction_imported_ = false;

  // Learned-state snapshot for the supervisor (seqlock: odd = being written).
  mutable std::atomic<std::uint32_t> snap_seq_{0};
  std::array<std::atomic<double>, 4> snap_friction_{};
  std::array<std::atomic<double>, kMaxTeeth> snap_teeth_{};
  std::atomic<int> snap_n_teeth_{0};
  std::atomic<bool> snap_friction_valid_{false};
  std::array<std::atomic<double>, 2> snap_idle_{};  ///< friction idle correction (N m), idle speed (rpm)
  std::atomic<bool> snap_idle_valid_{false};
};

}  // namespace torqued
