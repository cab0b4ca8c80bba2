#pragma once
// Angle stage: the DDS mapping of the angle chain (angle_chain.hpp, where edges and frames become estimates).
// Emits the decimated CrankState per tooth, the in-cycle EstimatorTorque (Kalman, Fourier) every n-th tooth,
// EngineTorque + EstimatorTorque per combustion segment (rolling 720° window) and per cycle, CylinderTorque
// per cycle, and publishes the learned state at cycle ends through a LatestValue<LearnedState> for the
// supervisor. Runs on the angle thread (paced/live) or inline in fast replay; on_edge/on_frame/poll are
// real-time safe.
#include <array>
#include <cstdint>
#include <string>

#include "angle_chain.hpp"
#include "latest_value.hpp"
#include "learned_state.hpp"
#include "methods.hpp"
#include "sample_sink.hpp"
#include "stage_settings.hpp"

namespace torqued {

class AngleStage final : public AngleChainSink {
 public:
  /// dbc may be null (no CAN). time: the time chain's tooth input (may be null). tap (may be null): also
  /// receives every chain record, after this stage mapped it (torque-accuracy, tests).
  AngleStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out, ToothSink* time,
             AngleChainSink* tap = nullptr);
  [[nodiscard]] bool ok() const noexcept { return chain_.ok(); }
  [[nodiscard]] const std::string& error() const noexcept { return chain_.error(); }

  /// ingest_ns: CLOCK_REALTIME at which the edge became available (0 in fast replay).
  void on_edge(const EdgeEvent& e, std::int64_t ingest_ns) noexcept;
  void on_frame(const CanFrame& f) noexcept { chain_.on_frame(f); }
  void poll(std::int64_t now_ns) noexcept { chain_.poll(now_ns); }
  /// SIGHUP: new decimations / sensor time-outs, applied between two events on this stage's thread.
  void apply(const RuntimeTunables& t) noexcept;

  [[nodiscard]] AngleChain& chain() noexcept { return chain_; }
  [[nodiscard]] const AngleChain& chain() const noexcept { return chain_; }

  /// Before start (no concurrent on_edge): restore persisted state; returns what was applied ("": nothing).
  std::string import_state(const LearnedState& st);
  /// The learned state, published at each cycle end that may have changed it and after import_state (nothing
  /// before anything was learned or imported). One reader (the supervisor): load_new() gives each newest
  /// snapshot once, complete (never torn).
  [[nodiscard]] LatestValue<LearnedState>& learned() noexcept { return learned_; }

  void on_tooth(const ChainTooth& t) noexcept override;
  void on_segment(const ChainSegment& s) noexcept override;

 private:
  void emit_method(std::uint8_t method, const TorqueEstimate& e, std::int64_t t_ns) noexcept;
  void emit_engine(const ChainSegment& s) noexcept;
  void emit_cylinders(const ChainSegment& s) noexcept;
  void publish_snapshot() noexcept;

  StageSettings s_;
  SampleSink& out_;
  AngleChainSink* tap_;
  AngleChain chain_;
  std::int64_t ingest_ns_ = 0;  ///< of the edge being processed
  int crank_count_ = 0;
  int tooth_est_count_ = 0;
  std::uint64_t seq_engine_ = 0, seq_cyl_ = 0, seq_crank_ = 0;
  std::array<std::uint64_t, dds::kMethodCount> seq_method_{};  ///< per method id (idl/methods.hpp)
  LearnedState scratch_;  ///< filled on the stage's thread, then stored into learned_
  LatestValue<LearnedState> learned_;
};

}  // namespace torqued
