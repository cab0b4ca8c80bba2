#include "stage_settings_from.hpp"

#include <cmath>

#include "config.hpp"

namespace torqued {
namespace {
dds::TopicQos map_qos(const TopicQos& q) {
  return dds::TopicQos{q.reliability == Reliability::kReliable, q.history_depth, q.deadline_ms, q.lease_ms};
}
}  // namespace

StageSettings stage_settings_from(const Config& cfg) {
  StageSettings s;
  s.engine = cfg.engine;
  s.wheel = cfg.wheel.geometry;
  s.decoder = cfg.wheel.decoder;  // YAML wheel.decoder.* (run_daemon also applies io's decoder_params())
  s.decoder.use_cam = !cfg.wheel.cam_channel.empty();
  s.decoder.cam_rising = cfg.wheel.cam_rising_edge;
  s.decoder.crank_channel = 0;  // EdgeCsvSource/backends map the configured crank column to channel 0
  s.decoder.cam_channel = 1;
  static_assert(kSignalCount == static_cast<int>(kCanQuantityCount));
  static_assert(kCanEmTorque == static_cast<std::size_t>(Quantity::kEmTorque));
  static_assert(kCanEmSoleLoad == static_cast<std::size_t>(Quantity::kEmSoleLoad));
  static_assert(kCanNeutral == static_cast<std::size_t>(Quantity::kNeutral));
  for (std::size_t i = 0; i < kCanQuantityCount; ++i) {
    const SignalMapping& m = cfg.can.signals[i];
    s.signals[i].message = m.message;
    s.signals[i].signal = m.signal;
    s.signals[i].timeout_ns = static_cast<std::int64_t>(m.timeout_ms) * 1'000'000;
  }
  s.dbc_path = cfg.can.dbc;
  s.time_pipeline = cfg.estimators.time_pipeline;
  s.time_pipeline.uio = s.time_pipeline.uio && cfg.estimators.uio.enabled;
  s.time_pipeline.sliding_mode = s.time_pipeline.sliding_mode && cfg.estimators.sliding_mode.enabled;
  s.time_pipeline.dirty_diff = s.time_pipeline.dirty_diff && cfg.estimators.dirty_diff.enabled;
  s.time_pipeline.adaptive = s.time_pipeline.adaptive && cfg.estimators.adaptive.enabled;
  s.time_estimators.uio = cfg.estimators.uio.params;
  s.time_estimators.sliding_mode = cfg.estimators.sliding_mode.params;
  s.time_estimators.dirty_diff = cfg.estimators.dirty_diff.params;
  s.time_estimators.adaptive = cfg.estimators.adaptive.params;
  s.angle.engine = cfg.engine;
  s.angle.wheel = cfg.wheel.geometry;
  s.angle.energies = cfg.estimators.energies.params;
  s.angle.friction = cfg.estimators.friction.params;
  s.angle.cylinder = cfg.estimators.cylinder.params;
  s.angle.fusion = cfg.estimators.fusion;
  s.angle.fuel = cfg.estimators.fuel;
  s.angle.default_oil_temp_c = cfg.estimators.default_oil_temp_c;
  // Hybrid input (both chains fold it: the angle chain here, the time stage from s.angle.e_machine).
  s.angle.e_machine.bound = cfg.can.signals[static_cast<std::size_t>(Quantity::kEmTorque)].mapped();
  s.angle.e_machine.ratio = cfg.can.e_machine.ratio;
  s.angle.e_machine.sign = static_cast<double>(cfg.can.e_machine.sign);
  s.angle.e_machine.sole_load = cfg.can.e_machine.sole_load;
  // Vehicle load references (estimators/core/load_reference.hpp): the clutch / neutral flags, the accessory
  // prior.
  s.angle.load_ref.sole_flag_bound =
      cfg.can.signals[static_cast<std::size_t>(Quantity::kEmSoleLoad)].mapped();
  s.angle.load_ref.neutral_bound = cfg.can.signals[static_cast<std::size_t>(Quantity::kNeutral)].mapped();
  s.angle.load_ref.load_signal_bound =
      cfg.can.signals[static_cast<std::size_t>(Quantity::kLoadTorque)].mapped();
  s.angle.load_ref.accessory_nm = cfg.can.load_reference.accessory_nm;
  s.angle.load_ref.accessory_sd_nm = cfg.can.load_reference.accessory_sd_nm;
  s.angle.load_ref.fuel_max_sd_nm = cfg.can.load_reference.fuel_max_sd_nm;
  s.angle.load_ref.free_coast = cfg.can.load_reference.free_coast;
  s.angle.load_ref.free_coast_step_min = cfg.can.load_reference.free_coast_step_min;
  s.angle.load_ref.free_coast_step_max = cfg.can.load_reference.free_coast_step_max;
  s.angle.load_ref.free_coast_decel_min = cfg.can.load_reference.free_coast_decel_min;
  s.angle.load_ref.free_coast_decel_max = cfg.can.load_reference.free_coast_decel_max;
  s.angle.load_ref.free_coast_decel_change = cfg.can.load_reference.free_coast_decel_change;
  s.angle.load_ref.free_coast_idle_map_rise_pa = 1e3 * cfg.can.load_reference.free_coast_idle_map_rise_kpa;
  s.angle_enabled = cfg.estimators.energies.enabled;
  s.angle.preprocess = cfg.estimators.preprocess;
  s.angle.kalman = cfg.estimators.kalman.params;
  s.angle.fourier = cfg.estimators.fourier.params;
  s.angle.run_kalman = cfg.estimators.kalman.enabled;
  s.angle.run_fourier = cfg.estimators.fourier.enabled;
  s.crank_decimation = cfg.dds.crank_state_decimation;
  s.time_decimation = cfg.dds.time_estimator_decimation;
  s.tooth_estimator_decimation = cfg.dds.tooth_estimator_decimation;
  s.edge_timeout_ns = static_cast<std::int64_t>(std::llround(cfg.inputs.edges.timeout_s * 1e9));
  s.status_period_ns = static_cast<std::int64_t>(std::llround(cfg.dds.status_period_s * 1e9));
  s.max_input_gap_ns = static_cast<std::int64_t>(std::llround(cfg.inputs.max_time_jump_s * 1e9));
  s.fast_threads = cfg.replay.fast_threads == FastThreads::kOne     ? 1
                   : cfg.replay.fast_threads == FastThreads::kThree ? 3
                                                                    : 0;
  s.tooth_learn = cfg.estimators.tooth_learn.params;
  s.tooth_learn_enabled = cfg.estimators.tooth_learn.enabled && cfg.estimators.tooth_learn.params.learn;
  s.dds.domain_id = static_cast<std::uint32_t>(cfg.dds.domain_id);
  s.dds.topic_prefix = cfg.dds.topic_prefix;
  s.dds.engine_id = static_cast<std::uint16_t>(cfg.dds.engine_id);
  s.dds.qos[static_cast<int>(dds::Topic::kEngineTorque)] = map_qos(cfg.dds.engine_torque);
  s.dds.qos[static_cast<int>(dds::Topic::kEstimatorTorque)] = map_qos(cfg.dds.estimator_torque);
  s.dds.qos[static_cast<int>(dds::Topic::kCylinderTorque)] = map_qos(cfg.dds.cylinder_torque);
  s.dds.qos[static_cast<int>(dds::Topic::kCrankState)] = map_qos(cfg.dds.crank_state);
  s.dds.qos[static_cast<int>(dds::Topic::kDaemonStatus)] = map_qos(cfg.dds.status);
  return s;
}

}  // namespace torqued
