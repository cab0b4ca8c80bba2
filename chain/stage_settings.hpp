#pragma once
// What the daemon's chains and stages need from the Config, as plain data sized before the threads start.
// Built once by stage_settings_from() (service/stage_settings_from.cpp, where the Config meets the chains),
// so the real-time code does not depend on the config schema's churn.
#include <array>
#include <cstdint>
#include <string>

#include "angle_pipeline.hpp"
#include "crank_decoder.hpp"
#include "engine_geometry.hpp"
#include "params.hpp"
#include "qos.hpp"
#include "signal_store.hpp"
#include "time_pipeline.hpp"

namespace torqued {

inline constexpr int kSignalCount = 13;  ///< EngineSignals quantities: map, maf, ..., load_torque, em_torque,
                                         ///< em_sole_load, neutral (this order)

struct SignalSpec {
  std::string message;  ///< DBC message ("" = not mapped)
  std::string signal;   ///< DBC signal
  std::int64_t timeout_ns = 100'000'000;
};

struct StageSettings {
  EngineGeometry engine;
  WheelGeometry wheel;
  DecoderParams decoder;
  std::array<SignalSpec, kSignalCount> signals{};
  std::string dbc_path;
  TimePipelineParams time_pipeline;
  TimeEstimatorParams time_estimators;  ///< one field per time-domain estimator
  AnglePipelineConfig
      angle;  ///< energies chain, friction, cylinders, fusion, e_machine (engine/wheel filled too)
  bool angle_enabled = true;  ///< run the angle pipeline (estimators.energies.enabled)
  ToothLearnParams tooth_learn;
  bool tooth_learn_enabled = true;  ///< learn tooth corrections and feed them to the decoder
  int crank_decimation = 10;        ///< publish CrankState every n-th synced tooth
  int time_decimation = 10;         ///< publish EstimatorTorque of time methods every n-th step
  int tooth_estimator_decimation =
      2;  ///< publish per-tooth Kalman/Fourier T_ind every n-th tooth (0 = never)
  std::int64_t edge_timeout_ns = 500'000'000;  ///< no crank edge for this long: STATUS_EDGE_TIMEOUT
  std::int64_t status_period_ns = 1'000'000'000;
  /// Fast replay: across a silent stretch of the input (a genuine clock jump) only this much recording time
  /// of time-triggered output is written (inputs.max_time_jump_s).
  std::int64_t max_input_gap_ns = 10'000'000'000;
  /// Fast replay's threads (replay.fast_threads): 0 = auto (3 when the process may use 2 CPUs, else 1), 1, 3.
  int fast_threads = 0;
  dds::DdsSettings dds;
};

/// The part of StageSettings that may change while the pipelines run (SIGHUP): plain data, applied by the
/// real-time threads themselves between two events (no allocation, no lock).
struct RuntimeTunables {
  int crank_decimation = 10;
  int time_decimation = 10;
  int tooth_estimator_decimation = 2;
  std::int64_t edge_timeout_ns = 500'000'000;
  std::array<std::int64_t, kSignalCount> signal_timeout_ns{};
  bool operator==(const RuntimeTunables&) const = default;
};

/// The tunables of `s`.
RuntimeTunables tunables_of(const StageSettings& s) noexcept;
/// Copies the tunables into `s` (no allocation).
void apply_tunables(StageSettings& s, const RuntimeTunables& t) noexcept;

/// Binds every mapped EngineSignals quantity of `signals` in `store` (one binding rule for every stage);
/// returns "" or "signal '<quantity>': <why>".
std::string bind_signals(SignalStore& store, const std::array<SignalSpec, kSignalCount>& signals);

}  // namespace torqued
