#pragma once
// DDS QoS of every torque topic, in ONE place (docs/conventions.md habit 8). The daemon fills DdsSettings
// from the validated Config (dds.*); subscribers (torque-echo, torque-latency, tests) use the same defaults
// so that reader and writer QoS always match (a reliable reader never matches a best-effort writer; a reader
// deadline shorter than the writer's does not match either).
#include <array>
#include <cstdint>
#include <string>

#include "dds/dds.h"
#include "topics.hpp"

namespace torqued::dds {

struct TopicQos {
  bool reliable = true;          ///< reliable (true) or best-effort
  std::int32_t depth = 16;       ///< keep-last history depth (samples per instance)
  std::int64_t deadline_ms = 0;  ///< offered deadline period (ms); 0 = infinite
  std::int64_t lease_ms = 0;     ///< automatic liveliness lease (ms); 0 = infinite
};

struct DdsSettings {
  std::uint32_t domain_id = 0;
  std::string topic_prefix =
      "torque";  ///< full topic name = prefix + "/" + type name (config dds.topic_prefix)
  std::uint16_t engine_id = 1;
  std::array<TopicQos, kTopicCount> qos = default_qos();

  /// Defaults: reliable keep-last for per-cycle torque, per-cylinder and status; best-effort keep-last 1 for
  /// the decimated crank state; deadlines a few times the slowest expected period (idle 600 rpm: 200 ms per
  /// cycle); liveliness lease 1 s so a subscriber notices a dead daemon within a second.
  /// EstimatorTorque keeps 1024 per key (per method): the in-cycle Kalman/Fourier publish 1450 Hz each at
  /// 3000 rpm, so 64 unacknowledged samples were 44 ms of a descheduled subscriber, and a starved one lost
  /// samples; 1024 are 0.7 s (at most 11 methods x 1024 x ~100 B held by the writer, while a reader lags).
  static constexpr std::int32_t kEstimatorTorqueDepth = 1024;
  static constexpr std::array<TopicQos, kTopicCount> default_qos() {
    return {TopicQos{true, 64, 1000, 1000},                     // EngineTorque (segments + cycles)
            TopicQos{true, kEstimatorTorqueDepth, 1000, 1000},  // EstimatorTorque
            TopicQos{true, 16, 1000, 1000},                     // CylinderTorque
            TopicQos{false, 1, 1000, 1000},                     // CrankState
            TopicQos{true, 4, 3000, 1000}};                     // DaemonStatus (1 Hz)
  }
  [[nodiscard]] std::string topic_name(Topic t) const {
    return topic_prefix.empty() ? std::string(kTopicNames[static_cast<int>(t)])
                                : topic_prefix + "/" + std::string(kTopicNames[static_cast<int>(t)]);
  }
};

/// New dds_qos_t for a writer or reader of a topic (caller owns it: dds_delete_qos). Readers get the same
/// reliability/history; their deadline/lease requests are the writer's offer (compatible by construction).
dds_qos_t* make_qos(const TopicQos& q);

/// Creates the participant's topic for T with the settings' name; returns the entity or a negative error.
dds_entity_t create_topic(dds_entity_t participant, const DdsSettings& s, Topic t);

}  // namespace torqued::dds
