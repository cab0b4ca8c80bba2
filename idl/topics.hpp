#pragma once
// Compile-time description of the torque topics: which C type (idlc output), which descriptor, which topic
// name suffix, which CSV file. The one table every DDS participant of torqued uses (daemon, torque-echo,
// torque-latency), so a type or topic name cannot differ between them.
#include <cstdint>
#include <string_view>

#include "torque.h"

namespace torqued::dds {

enum class Topic : std::uint8_t {
  kEngineTorque = 0,
  kEstimatorTorque,
  kCylinderTorque,
  kCrankState,
  kDaemonStatus
};
inline constexpr int kTopicCount = 5;

template <class T>
struct TopicTraits;

template <>
struct TopicTraits<torque_EngineTorque> {
  static constexpr Topic id = Topic::kEngineTorque;
  static constexpr std::string_view name = "EngineTorque";
  static constexpr std::string_view csv = "engine_torque";
  static const dds_topic_descriptor_t* descriptor() noexcept { return &torque_EngineTorque_desc; }
};
template <>
struct TopicTraits<torque_EstimatorTorque> {
  static constexpr Topic id = Topic::kEstimatorTorque;
  static constexpr std::string_view name = "EstimatorTorque";
  static constexpr std::string_view csv = "estimator_torque";
  static const dds_topic_descriptor_t* descriptor() noexcept { return &torque_EstimatorTorque_desc; }
};
template <>
struct TopicTraits<torque_CylinderTorque> {
  static constexpr Topic id = Topic::kCylinderTorque;
  static constexpr std::string_view name = "CylinderTorque";
  static constexpr std::string_view csv = "cylinder_torque";
  static const dds_topic_descriptor_t* descriptor() noexcept { return &torque_CylinderTorque_desc; }
};
template <>
struct TopicTraits<torque_CrankState> {
  static constexpr Topic id = Topic::kCrankState;
  static constexpr std::string_view name = "CrankState";
  static constexpr std::string_view csv = "crank_state";
  static const dds_topic_descriptor_t* descriptor() noexcept { return &torque_CrankState_desc; }
};
template <>
struct TopicTraits<torque_DaemonStatus> {
  static constexpr Topic id = Topic::kDaemonStatus;
  static constexpr std::string_view name = "DaemonStatus";
  static constexpr std::string_view csv = "daemon_status";
  static const dds_topic_descriptor_t* descriptor() noexcept { return &torque_DaemonStatus_desc; }
};

/// Topic name suffixes in Topic order (full DDS topic name = config dds.topic_prefix + suffix).
inline constexpr std::string_view kTopicNames[kTopicCount] = {"EngineTorque", "EstimatorTorque",
                                                              "CylinderTorque", "CrankState", "DaemonStatus"};

// Method ids, names and labels of EstimatorTorque.method: the registry in methods.hpp.

}  // namespace torqued::dds
