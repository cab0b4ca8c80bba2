#pragma once
// Angle stage: the DDS mapping of the angle chain (angle_chain.hpp, where edges and frames become estimates).
// Emits the decimated CrankState per tooth, the in-cycle EstimatorTorque (Kalman, Fourier) every n-th tooth,
// EngineTorque + EstimatorTorque per combustion segment (rolling 720° window) and per cycle, CylinderTorque
// per cycle, and keeps a lock-free snapshot of the learned state for the supervisor. Runs on the angle thread
// (paced/live) or inline in fast replay; on_edge/on_frame/poll are real-time safe.
#include <array>
#include <atomic>
#include <cstdint>
#include <string>

#include "angle_chain.hpp"
#include "sample_sink.hpp"
#include "stage_settings.hpp"
#include "state_store.hpp"

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
  /// From any thread: the newest learned state snapshot taken at a cycle end (seqlock). False when nothing
  /// was learned or imported yet.
  bool export_state(LearnedState& st) const;

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
  std::array<std::uint64_t, 16> seq_method_{};
  LearnedSnapshot scratch_;  ///< filled on the stage's thread, then copied into the seqlock below

  // Learned-state snapshot for the supervisor (seqlock: odd = being written).
  mutable std::atomic<std::uint32_t> snap_seq_{0};
  std::array<std::atomic<double>, 4> snap_friction_{};
  std::array<std::atomic<double>, 2 * kMaxTeeth> snap_teeth_{};
  std::atomic<int> snap_n_teeth_{0};
  std::atomic<bool> snap_friction_valid_{false};
  std::array<std::atomic<double>, 2> snap_idle_{};  ///< friction idle correction (N m), idle speed (rpm)
  std::atomic<bool> snap_idle_valid_{false};
  std::array<std::atomic<double>, 2> snap_fric_res_{};  ///< motoring residual scale (N m), its count
  std::atomic<bool> snap_fric_res_valid_{false};
  std::array<std::atomic<double>, kFuelStateDoubles> snap_fuel_{};  ///< FuelTorqueState, pack()ed
  std::atomic<bool> snap_fuel_valid_{false};
  std::atomic<double> snap_crank_var_{0.0};
  std::atomic<bool> snap_crank_var_valid_{false};
  std::array<std::atomic<double>, 3> snap_inertia_{};  ///< InertiaLearner k, information, J_spec
  std::atomic<bool> snap_inertia_valid_{false};
};

}  // namespace torqued
