#include "stage_settings.hpp"

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
  s.decoder.use_cam = !cfg.wheel.cam_channel.empty();
  s.decoder.cam_rising = cfg.wheel.cam_rising_edge;
  s.decoder.crank_channel = 0;  // EdgeCsvSource/backends map the configured crank column to channel 0
  s.decoder.cam_channel = 1;
  static_assert(kSignalCount == static_cast<int>(kCanQuantityCount));
  for (std::size_t i = 0; i < kCanQuantityCount; ++i) {
    const SignalMapping& m = cfg.can.signals[i];
    s.signals[i].message = m.message;
    s.signals[i].signal = m.signal;
    s.signals[i].timeout_ns = static_cast<std::int64_t>(m.timeout_ms) * 1'000'000;
  }
  s.dbc_path = cfg.can.dbc;
  s.time_pipeline = cfg.estimators.time_pipeline;
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
