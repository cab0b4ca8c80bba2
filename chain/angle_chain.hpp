#pragma once
// The angle chain: the ONE place where crank/cam edges and CAN frames become per-tooth, per-segment and
// per-cycle estimates. No DDS, no threads; the daemon (fast replay, paced replay, live), torque-accuracy and
// the tests all drive this class, so a figure measured on it is a figure of the daemon.
//
//   edges  ──► CrankDecoder ──ToothEvent──► ToothSample ──► AnglePipeline ──► AngleChainSink (records)
//                  ▲                             │  │            ▲
//                  │ (1) tooth corrections        │  └──► ToothSink: time chain hand-off (mean speed)
//                  │     at each cycle end        ▼               │ (3) time-chain estimate (fusion slot)
//                  └──────────────────── ToothErrorLearner        │     set_time_estimate()
//   frames ──► SignalStore ──EngineSignals──► pipeline, learner (2) fuel cut-off flag gates the learner
//
// Feedback loops, all in angle_chain.cpp: (1) learned tooth table → decoder edge corrections, applied at the
// cycle boundary, and "wheel learned" → in-cycle observers and per-cylinder record (their health says when
// not); (2) CAN fuel cut-off → tooth learner; (3) time pipeline's UIO brake estimate → fusion's external
// source (fusion.time_estimate); (4) learned state import/export (friction law, tooth table); (5) hybrid
// input: the electric machine's CAN torque (can.signals.em_torque × can.e_machine.ratio × sign) folded into
// the net load of every balance (fold_e_machine, estimators/core/e_machine.hpp; the time stage folds the
// same), and motoring by the machine → friction learner; a stale machine signal holds what rests on it with
// STALE_CAN, as the load signal; (6) the in-cycle Kalman's estimate and the gas model inside it →
// burn-phasing learner (kalman.burn_phase_learn) → the gas model's burn centroid offset, applied at the cycle
// boundary. on_edge/on_frame/poll/set_time_estimate are real-time safe: no allocation, no lock, no blocking.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "angle_pipeline.hpp"
#include "burn_phase_learner.hpp"
#include "crank_decoder.hpp"
#include "dbc.hpp"
#include "decoder_events.hpp"
#include "learned_state.hpp"
#include "sample_sink.hpp"
#include "signal_store.hpp"
#include "stage_settings.hpp"
#include "tooth_error_learner.hpp"

namespace torqued {

/// What every record rests on at the moment it was made.
struct ChainStatus {
  bool synced = false;           ///< decoder synced and cam phase known
  std::uint32_t stale_mask = 0;  ///< bit i: EngineSignals quantity i bound but stale at the last tooth
};

/// One decoded tooth.
struct ChainTooth {
  ToothEvent event;           ///< decoder output
  ToothSample sample;         ///< what the estimators were given
  double accel_rad_s2 = 0.0;  ///< pipeline's θ̈, or the speed difference when the pipeline has none yet
  const ToothOutput* estimates = nullptr;  ///< in-cycle estimates of this tooth (null: none valid)
  ChainStatus status;
};

/// One combustion segment (rolling 720° window ending at the segment boundary); cycle_end: a full cycle
/// ended.
struct ChainSegment {
  std::int64_t source_t_ns = 0;  ///< source time of the tooth that closed the segment
  std::int64_t window_start_t_ns = 0;
  int cylinder = 0;                  ///< cylinder (1-based) whose firing segment just ended
  std::uint64_t cycle = 0;           ///< cycles completed by the chain
  const CycleOutput* out = nullptr;  ///< energies chain, friction, fusion, per-cylinder (when cycle_end)
  ChainStatus status;
};

/// Receives the chain's records, on the chain's thread, in order. Implementations must be real-time safe.
class AngleChainSink {
 public:
  virtual ~AngleChainSink() = default;
  virtual void on_tooth(const ChainTooth& t) noexcept = 0;
  virtual void on_segment(const ChainSegment& s) noexcept = 0;
};

class AngleChain {
 public:
  /// dbc may be null (no CAN): estimators then see every signal invalid. time: the time chain's tooth input
  /// (may be null).
  AngleChain(const StageSettings& s, const DbcDatabase* dbc, AngleChainSink& out, ToothSink* time);
  ~AngleChain();
  AngleChain(const AngleChain&) = delete;
  AngleChain& operator=(const AngleChain&) = delete;

  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  void on_edge(const EdgeEvent& e) noexcept;
  void on_frame(const CanFrame& f) noexcept;
  /// Stall detection on the edge clock (live: call when no edge arrived for a while).
  void poll(std::int64_t now_ns) noexcept;
  /// Feedback (3): the time chain's newest brake estimate, used by the fusion at the next segment when
  /// fusion.time_estimate is set (ignored otherwise).
  void set_time_estimate(const TorqueEstimate& e, bool uses_can) noexcept;
  /// SIGHUP: new sensor time-outs.
  void set_signal_timeouts(const std::array<std::int64_t, kSignalCount>& timeout_ns) noexcept;

  [[nodiscard]] const CrankDecoder& decoder() const noexcept { return decoder_; }
  /// The decoder's sync-state transitions (lock-free SPSC ring: this chain's thread pushes, one other thread
  /// or the same one later pops them for the debug log).
  [[nodiscard]] DecoderEventLog& transitions() noexcept { return transitions_; }
  [[nodiscard]] std::uint64_t cycles() const noexcept { return cycles_; }
  [[nodiscard]] std::int64_t last_t_ns() const noexcept { return last_t_ns_; }
  [[nodiscard]] ChainStatus status() const noexcept;
  [[nodiscard]] const AnglePipeline* pipeline() const noexcept { return pipeline_.get(); }
  [[nodiscard]] const ToothErrorLearner* learner() const noexcept { return learner_.get(); }
  /// The burn-phasing learner (null: kalman.burn_phase_learn off, or no Kalman with a gas model).
  [[nodiscard]] const BurnPhaseLearner* burn_phase() const noexcept { return burn_.get(); }
  /// Imported tooth tables the running engine contradicted (discarded and relearned; 0 or 1 per run).
  [[nodiscard]] std::uint64_t tooth_tables_distrusted() const noexcept {
    return learner_ ? learner_->stats().tables_distrusted : 0;
  }
  /// CAN frames too short for a bound signal, one line per signal naming the first such frame (empty: none).
  /// Not real-time: call after the chain stopped.
  [[nodiscard]] std::vector<std::string> describe_bad_frames() const {
    return store_ ? store_->describe_bad_frames() : std::vector<std::string>{};
  }

  /// Feedback (4), before the first edge: restore persisted friction coefficients, tooth corrections, the
  /// fuel model and the measured crank-only error variance. Returns what was applied ("" when nothing).
  std::string import_state(const LearnedState& st);
  /// The state learned so far into `st` (friction when learned or imported, tooth table once applied;
  /// identity and saved_at_t_ns left empty). False when nothing was learned or imported. Real-time safe (no
  /// allocation).
  bool snapshot(LearnedState& st) const noexcept;
  /// True once per cycle end at which snapshot() may have changed (the daemon snapshots it then).
  [[nodiscard]] bool take_state_changed() noexcept {
    const bool c = state_changed_;
    state_changed_ = false;
    return c;
  }

 private:
  void on_tooth(const ToothEvent& te) noexcept;
  void on_cycle_end() noexcept;
  void feed_burn_phase(const EngineSignals& sig) noexcept;
  void emit_segment(const ToothEvent& te) noexcept;
  [[nodiscard]] bool friction_learned() const noexcept;

  StageSettings s_;
  AngleChainSink& out_;
  ToothSink* time_;
  DecoderEventLog transitions_;
  CrankDecoder decoder_;
  std::unique_ptr<SignalStore> store_;
  std::unique_ptr<AnglePipeline> pipeline_;
  std::unique_ptr<ToothErrorLearner> learner_;
  std::unique_ptr<BurnPhaseLearner> burn_;
  std::string error_;

  bool import_distrust_applied_ = false;
  std::uint64_t cycles_ = 0;
  std::int64_t last_t_ns_ = 0;
  std::int64_t prev_tooth_t_ns_ = -1;
  double prev_speed_rad_s_ = 0.0;
  int prev_tooth_ = -1;
  std::uint32_t stale_mask_ = 0;
  std::array<double, 2 * kMaxTeeth> corr_{};  ///< the tooth table last given to the decoder
  int corr_n_ = 0;                            ///< its length (0: none applied)
  bool friction_imported_ = false;
  bool fuel_imported_ = false;
  bool crank_var_imported_ = false;
  bool inertia_imported_ = false;
  bool burn_imported_ = false;
  bool state_changed_ = false;
};

}  // namespace torqued
