#pragma once
// Time-triggered pipeline (docs/architecture.md data flow: "time_pipeline (timer, 1 kHz)"): mean crank speed
// from the decoder's teeth (MeanSpeedTracker), load torque and air mass flow from the CAN signal store, and
// the four Na et al. estimators (UIO, sliding mode, dirty differentiation, adaptive), each selectable.
// Everything is sized at construction; on_tooth() and step() are real-time safe (no allocation, noexcept).
#include <cstdint>
#include <optional>

#include "adaptive_tv.hpp"
#include "dirty_diff.hpp"
#include "e_machine.hpp"
#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "load_reference.hpp"
#include "mean_speed_tracker.hpp"
#include "methods.hpp"
#include "params.hpp"
#include "samples.hpp"
#include "sliding_mode.hpp"
#include "time_sample.hpp"
#include "uio.hpp"

namespace torqued {

/// The time-domain estimators' parameters, one field per estimator (StageSettings carries one; a new
/// estimator adds its field here, not a constructor argument).
struct TimeEstimatorParams {
  UioParams uio;
  SlidingModeParams sliding_mode;
  DirtyDiffParams dirty_diff;
  AdaptiveParams adaptive;
};

/// Result of one pipeline step. Estimators that are switched off report Health::kDisabled.
struct TimePipelineOutput {
  TimeSample input{};                                  ///< what the estimators saw
  TorqueEstimate uio{};                                ///< Na-14
  TorqueEstimate sliding_mode{};                       ///< Na-21
  TorqueEstimate dirty_diff{};                         ///< Na-24
  TorqueEstimate adaptive{};                           ///< Na-50 or Na-54; uncertainty = λ_min(P)
  AdaptiveTv::Vec theta_si = AdaptiveTv::Vec::Zero();  ///< θ̂ in SI [N m s/rad, N m s/kg]
  double lambda_min_p = 0.0;                           ///< excitation level (Na Remark 9)
};

/// Which output member carries which EstimatorTorque method: the time stage emits the registry's time-domain
/// methods (idl/methods.hpp, in its order) through this table; a time-domain entry without a row here fails
/// the build (publish/time_stage.cpp). A new time estimator: its member above and its row here.
struct TimeMethodOutput {
  std::uint8_t method = 0;
  TorqueEstimate TimePipelineOutput::*estimate = nullptr;
};
inline constexpr TimeMethodOutput kTimeMethodOutputs[] = {
    {torque_METHOD_UIO, &TimePipelineOutput::uio},
    {torque_METHOD_SLIDING_MODE, &TimePipelineOutput::sliding_mode},
    {torque_METHOD_DIRTY_DIFF, &TimePipelineOutput::dirty_diff},
    {torque_METHOD_ADAPTIVE, &TimePipelineOutput::adaptive},
};

class TimePipeline {
 public:
  TimePipeline(const TimePipelineParams& params, const TimeEstimatorParams& estimators,
               const EngineGeometry& geometry) noexcept;

  /// J used by the estimators (kg m^2): params.inertia_kgm2, or J_rot + cycle mean of the oscillating
  /// inertia.
  [[nodiscard]] double inertia_kgm2() const noexcept { return inertia_kgm2_; }

  void reset() noexcept;
  /// Hybrid input: how the machine's CAN torque folds into the load step() hands the estimators (before the
  /// first step; default: not bound, the load signal alone).
  void set_e_machine(const EMachineParams& p) noexcept { e_machine_ = p; }
  /// Clutch / neutral flags (load_reference.hpp): which instants have a known load on a vehicle.
  void set_load_reference(const LoadReferenceParams& p) noexcept { load_ref_ = p; }
  /// Feeds one decoded tooth to the mean-speed tracker. Real-time safe.
  void on_tooth(const ToothSample& tooth) noexcept;
  /// One timer tick at t_ns with the current signal-store snapshot. Real-time safe.
  const TimePipelineOutput& step(std::int64_t t_ns, const EngineSignals& signals) noexcept;
  /// One tick with inputs already assembled (replay of mean-value data, tests). Real-time safe.
  const TimePipelineOutput& step(const TimeSample& sample) noexcept;

  [[nodiscard]] const TimePipelineOutput& output() const noexcept { return out_; }
  [[nodiscard]] const MeanSpeedTracker& speed_tracker() const noexcept { return tracker_; }

 private:
  TimePipelineParams params_;
  EMachineParams e_machine_{};
  LoadReferenceParams load_ref_{};
  double inertia_kgm2_;
  MeanSpeedTracker tracker_;
  Uio uio_;
  SlidingMode sliding_;
  DirtyDiff dirty_;
  AdaptiveTv adaptive_;
  std::int64_t last_t_ns_ = 0;
  bool has_last_ = false;
  TimePipelineOutput out_{};
};

/// J_rot + (1/4π)∮ m_osc R² Σ_j f_j² dθ: the inertia the mean-value model (Na-8) sees (CK-1 averaged).
[[nodiscard]] double mean_inertia_kgm2(const EngineGeometry& geometry) noexcept;

}  // namespace torqued
