// tests/idl/test_qos_defaults.cpp: the topic QoS defaults (idl/qos.hpp default_qos(), docs/conventions.md
// habit 8), the configuration's defaults that must equal them (config/config.hpp DdsConfig), and the
// dds_qos_t make_qos builds. EstimatorTorque keeps 1024 samples per key: at 64 a starved subscriber lost
// samples of the 1450 Hz in-cycle methods.
#include <gtest/gtest.h>

#include "config.hpp"
#include "config_loader.hpp"
#include "qos.hpp"

namespace torqued {
namespace {

dds::TopicQos from_config(const TopicQos& q) {
  return {q.reliability == Reliability::kReliable, q.history_depth, q.deadline_ms, q.lease_ms};
}

void expect_equal(const dds::TopicQos& a, const dds::TopicQos& b, const char* topic) {
  EXPECT_EQ(a.reliable, b.reliable) << topic;
  EXPECT_EQ(a.depth, b.depth) << topic;
  EXPECT_EQ(a.deadline_ms, b.deadline_ms) << topic;
  EXPECT_EQ(a.lease_ms, b.lease_ms) << topic;
}

TEST(QosDefaults, EstimatorTorqueKeepsLast1024PerKey) {
  // GIVEN the defaults of every topic
  const auto q = dds::DdsSettings::default_qos();
  // THEN EstimatorTorque is reliable keep-last 1024, the others unchanged
  const auto& est = q[static_cast<std::size_t>(dds::Topic::kEstimatorTorque)];
  EXPECT_TRUE(est.reliable);
  EXPECT_EQ(est.depth, 1024);
  EXPECT_EQ(q[static_cast<std::size_t>(dds::Topic::kEngineTorque)].depth, 64);
  EXPECT_EQ(q[static_cast<std::size_t>(dds::Topic::kCylinderTorque)].depth, 16);
  EXPECT_EQ(q[static_cast<std::size_t>(dds::Topic::kCrankState)].depth, 1);
  EXPECT_EQ(q[static_cast<std::size_t>(dds::Topic::kDaemonStatus)].depth, 4);
}

TEST(QosDefaults, ConfigurationDefaultsEqualTheTopicDefaults) {
  // GIVEN a default Config and a configuration file without a dds.qos section
  const DdsConfig c;
  const auto q = dds::DdsSettings::default_qos();
  // THEN each topic's configured default is the topic default (reader and writer QoS match by construction)
  expect_equal(from_config(c.engine_torque), q[0], "EngineTorque");
  expect_equal(from_config(c.estimator_torque), q[1], "EstimatorTorque");
  expect_equal(from_config(c.cylinder_torque), q[2], "CylinderTorque");
  expect_equal(from_config(c.crank_state), q[3], "CrankState");
  expect_equal(from_config(c.status), q[4], "DaemonStatus");
  const LoadResult r = load_config(std::string(TORQUED_SOURCE_DIR) + "/config/demo.yaml");
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.config->dds.estimator_torque.history_depth, 1024);
}

TEST(QosDefaults, MakeQosCarriesTheDepth) {
  // WHEN the EstimatorTorque writer QoS is built
  dds_qos_t* qos =
      dds::make_qos(dds::DdsSettings::default_qos()[static_cast<std::size_t>(dds::Topic::kEstimatorTorque)]);
  // THEN it is keep-last 1024, reliable, volatile
  dds_history_kind_t kind{};
  std::int32_t depth = 0;
  ASSERT_TRUE(dds_qget_history(qos, &kind, &depth));
  EXPECT_EQ(kind, DDS_HISTORY_KEEP_LAST);
  EXPECT_EQ(depth, 1024);
  dds_reliability_kind_t rel{};
  dds_duration_t block = 0;
  ASSERT_TRUE(dds_qget_reliability(qos, &rel, &block));
  EXPECT_EQ(rel, DDS_RELIABILITY_RELIABLE);
  dds_durability_kind_t dur{};
  ASSERT_TRUE(dds_qget_durability(qos, &dur));
  EXPECT_EQ(dur, DDS_DURABILITY_VOLATILE);
  dds_delete_qos(qos);
}

}  // namespace
}  // namespace torqued
