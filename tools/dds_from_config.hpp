#pragma once
// A subscriber's DDS settings from the daemon's configuration file: the same domain, topic prefix, engine_id
// and per-topic QoS the daemon offers (config dds.*), so that the reader's requests match the writer's offer
// (e.g. deadline_ms 0 in a shared-memory configuration: a reader requesting 1 s would not match at all).
#include <stdexcept>
#include <string>

#include "config.hpp"
#include "config_loader.hpp"
#include "physical_range.hpp"
#include "qos.hpp"

namespace torqued::tools {

inline dds::TopicQos to_dds_qos(const TopicQos& q) {
  return {q.reliability == Reliability::kReliable, q.history_depth, q.deadline_ms, q.lease_ms};
}

inline dds::DdsSettings dds_settings_from(const Config& c) {
  dds::DdsSettings s;
  s.domain_id = static_cast<std::uint32_t>(c.dds.domain_id);
  s.topic_prefix = c.dds.topic_prefix;
  s.engine_id = static_cast<std::uint16_t>(c.dds.engine_id);
  s.qos = {to_dds_qos(c.dds.engine_torque), to_dds_qos(c.dds.estimator_torque),
           to_dds_qos(c.dds.cylinder_torque), to_dds_qos(c.dds.crank_state), to_dds_qos(c.dds.status)};
  return s;
}

/// Loads `path` (input files need not exist here: they are the daemon's); throws with every error listed.
inline dds::DdsSettings dds_settings_from_file(const std::string& path) {
  LoadOptions lo;
  lo.check_files = false;
  const LoadResult r = load_config(path, lo);
  if (!r.ok()) {
    std::string msg = "configuration " + path + " is not valid:";
    for (const auto& e : r.errors) msg += "\n  " + e;
    throw std::runtime_error(msg);
  }
  return dds_settings_from(*r.config);
}

/// Physical torque range of the configuration's engine (dds/physical_range.hpp).
inline dds::TorqueRange torque_range_from_file(const std::string& path) {
  LoadOptions lo;
  lo.check_files = false;
  const LoadResult r = load_config(path, lo);
  if (!r.ok()) return {};
  return dds::torque_range(r.config->engine.cylinders, r.config->engine.bore_m, r.config->engine.stroke_m);
}

}  // namespace torqued::tools
