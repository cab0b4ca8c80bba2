// daemon/metrics: what a scrape returns for known samples and a known DaemonStatus (no HTTP: collect() +
// the text exposition), that the tap forwards every sample unchanged, the learned-state age, and that
// metrics.address is checked by the configuration loader.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

#include "clocks.hpp"
#include "config_loader.hpp"
#include "metrics.hpp"

namespace torqued::metrics {
namespace {

struct CountingSink final : SampleSink {
  std::vector<dds::AnySample> got;
  void emit(const dds::AnySample& s) noexcept override { got.push_back(s); }
};

bool has_line(const std::string& text, const std::string& line) {
  return text.find("\n" + line + "\n") != std::string::npos;
}

TEST(Metrics, ExpositionReflectsSamplesAndStatus) {
  CountingSink next;
  MetricsServer m(next, "");
  dds::AnySample e;
  e.topic = dds::Topic::kEstimatorTorque;
  e.u.estimator.method = torque_METHOD_KALMAN;
  e.u.estimator.value_nm = 123.5;
  e.u.estimator.uncertainty = 2.25;
  e.u.estimator.health = 1;
  e.u.estimator.ingest_t_ns = realtime_ns() - 30'000;  // 30 us ago: lands in the 50 us bucket
  m.sink().emit(e);
  m.sink().emit(e);
  dds::AnySample c;
  c.topic = dds::Topic::kCrankState;
  c.u.crank.sync = 2;
  m.sink().emit(c);
  ASSERT_EQ(next.got.size(), 3u);  // forwarded, unchanged
  EXPECT_EQ(next.got[0].u.estimator.value_nm, 123.5);
  EXPECT_TRUE(has_line("\n" + to_text(m.collect()), "torqued_status_received 0"));  // no DaemonStatus yet

  torque_DaemonStatus s{};
  s.edges = 1000;
  s.rejected_edges = 4;
  s.ring_drops_can = 7;
  s.health = torque_DAEMON_DEGRADED;
  s.flags = torque_STATUS_CAN_TIMEOUT;
  s.sensor_timeouts = 1u << 1;  // maf
  s.latency_p99_ns = 150'000;
  s.burn_phase_state = 2;  // converged
  s.burn_phase_offset_deg = -3.5;
  dds::AnySample st;  // DaemonStatus reaches the tap like every other sample
  st.topic = dds::Topic::kDaemonStatus;
  st.u.status = s;
  m.sink().emit(st);

  const std::string t = "\n" + to_text(m.collect());
  EXPECT_TRUE(has_line(t, "torqued_edges_total 1000")) << t;
  EXPECT_TRUE(has_line(t, "torqued_rejected_edges_total 4"));
  EXPECT_TRUE(has_line(t, "torqued_status_received 1"));
  EXPECT_TRUE(has_line(t, "torqued_status_flag{flag=\"record_error\"} 0"));
  EXPECT_TRUE(has_line(t, "torqued_ring_drops_total{ring=\"can\"} 7"));
  EXPECT_TRUE(has_line(t, "torqued_health 1"));
  EXPECT_TRUE(has_line(t, "torqued_synced 1"));  // NO_SYNC not set
  EXPECT_TRUE(has_line(t, "torqued_status_flag{flag=\"can_timeout\"} 1"));
  EXPECT_TRUE(has_line(t, "torqued_status_flag{flag=\"no_sync\"} 0"));
  EXPECT_TRUE(has_line(t, "torqued_sensor_timeout{signal=\"maf\"} 1"));
  EXPECT_TRUE(has_line(t, "torqued_sensor_timeout{signal=\"map\"} 0"));
  EXPECT_TRUE(has_line(t, "torqued_latency_period_seconds{stat=\"p99\"} 0.00015"));
  EXPECT_TRUE(has_line(t, "torqued_burn_phase_state 2"));
  EXPECT_TRUE(has_line(t, "torqued_burn_phase_offset_degrees -3.5"));
  EXPECT_EQ(t.find("quantile="), std::string::npos);  // only a summary may carry quantile labels
  EXPECT_TRUE(has_line(t, "torqued_estimator_in_cycle_torque_nm{method=\"kalman\"} 123.5"));  // in-cycle
  EXPECT_EQ(t.find("torqued_estimator_torque_nm{method=\"kalman\"}"), std::string::npos);
  EXPECT_TRUE(has_line(t, "torqued_replay_done 0"));
  EXPECT_TRUE(has_line(t, "torqued_estimator_uncertainty{method=\"kalman\"} 2.25"));
  EXPECT_TRUE(has_line(t, "torqued_estimator_health{method=\"kalman\"} 1"));
  EXPECT_TRUE(has_line(t, "torqued_estimator_samples_total{method=\"kalman\"} 2"));
  EXPECT_EQ(t.find("method=\"uio\""), std::string::npos);  // no sample: no series
  EXPECT_TRUE(has_line(t, "torqued_crank_sync_state 2"));
  EXPECT_TRUE(has_line(t, "torqued_publish_latency_seconds_count 2"));
  EXPECT_TRUE(has_line(t, "torqued_publish_latency_seconds_bucket{le=\"2.5e-05\"} 0"));
  EXPECT_TRUE(has_line(t, "torqued_publish_latency_seconds_bucket{le=\"+Inf\"} 2"));
  EXPECT_TRUE(has_line(t, "torqued_learned_state_present 0"));
}

/// The value of the series `name` (e.g. `torqued_health`) in an exposition; NaN text parses as NaN.
double value_of(const std::string& text, const std::string& name) {
  const auto at = text.find("\n" + name + " ");
  if (at == std::string::npos) return -12345.0;
  return std::strtod(text.c_str() + at + name.size() + 2, nullptr);
}

TEST(Metrics, StaleOrFailedTorqueIsNaNAndReplayDoneIsAState) {
  // GIVEN a fused estimate and a cycle EngineTorque WHEN no new sample came for longer than kStaleAfterNs
  // (the sample time set back, no waiting) THEN their gauges read NaN; WHEN the daemon's health is failed
  // THEN fresh values read NaN too. REPLAY_DONE seen once stays 1 in torqued_replay_done and the status flag.
  CountingSink next;
  MetricsServer m(next, "");
  dds::AnySample e;
  e.topic = dds::Topic::kEstimatorTorque;
  e.u.estimator.method = torque_METHOD_FUSED;
  e.u.estimator.value_nm = 112.0;
  m.sink().emit(e);
  dds::AnySample g;
  g.topic = dds::Topic::kEngineTorque;
  g.u.engine.kind = torque_KIND_CYCLE;
  g.u.engine.fused_nm = 110.0;
  m.sink().emit(g);
  std::string t = "\n" + to_text(m.collect());
  EXPECT_EQ(value_of(t, "torqued_estimator_torque_nm{method=\"fused\"}"), 112.0) << t;
  EXPECT_EQ(value_of(t, "torqued_engine_torque_nm{kind=\"cycle\",quantity=\"fused\"}"), 110.0) << t;

  auto& tap = static_cast<MetricsTap&>(m.sink());
  tap.method[torque_METHOD_FUSED].at_ns.store(realtime_ns() - kStaleAfterNs - 1'000'000);
  t = "\n" + to_text(m.collect());
  EXPECT_TRUE(std::isnan(value_of(t, "torqued_estimator_torque_nm{method=\"fused\"}"))) << t;
  EXPECT_EQ(value_of(t, "torqued_engine_torque_nm{kind=\"cycle\",quantity=\"fused\"}"), 110.0) << t;

  dds::AnySample st;
  st.topic = dds::Topic::kDaemonStatus;
  st.u.status.health = torque_DAEMON_FAILED;
  st.u.status.flags = torque_STATUS_REPLAY_DONE | torque_STATUS_NO_SYNC;
  m.sink().emit(st);
  m.sink().emit(e);  // fresh, but the daemon says its outputs are not usable
  t = "\n" + to_text(m.collect());
  EXPECT_TRUE(std::isnan(value_of(t, "torqued_estimator_torque_nm{method=\"fused\"}"))) << t;
  EXPECT_TRUE(std::isnan(value_of(t, "torqued_engine_torque_nm{kind=\"cycle\",quantity=\"fused\"}")));
  EXPECT_EQ(value_of(t, "torqued_replay_done"), 1.0);

  st.u.status.health = torque_DAEMON_OK;
  st.u.status.flags = 0;  // a later status without the flag: the replay is still done
  m.sink().emit(st);
  m.sink().emit(e);
  t = "\n" + to_text(m.collect());
  EXPECT_EQ(value_of(t, "torqued_estimator_torque_nm{method=\"fused\"}"), 112.0) << t;
  EXPECT_EQ(value_of(t, "torqued_replay_done"), 1.0) << t;
  EXPECT_EQ(value_of(t, "torqued_status_flag{flag=\"replay_done\"}"), 1.0) << t;
}

TEST(Metrics, LearnedStateAgeFromFileTime) {
  const auto dir = std::filesystem::temp_directory_path() / ("torqued_metrics_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto file = dir / "learned_state.txt";
  std::ofstream(file) << "x\n";
  std::filesystem::last_write_time(file,
                                   std::filesystem::file_time_type::clock::now() - std::chrono::seconds(100));
  CountingSink next;
  MetricsServer m(next, file.string());
  const std::string t = "\n" + to_text(m.collect());
  EXPECT_TRUE(has_line(t, "torqued_learned_state_present 1"));
  const auto pos = t.find("\ntorqued_learned_state_age_seconds ");
  ASSERT_NE(pos, std::string::npos) << t;
  const double age = std::stod(t.substr(pos + 35));
  EXPECT_NEAR(age, 100.0, 5.0);
  std::filesystem::remove_all(dir);
}

TEST(Metrics, ServesOnBoundPortAndRefusesBadAddress) {
  CountingSink next;
  std::string err;
  auto m = MetricsServer::start(MetricsConfig{true, "127.0.0.1:0"}, next, "", &err);
  ASSERT_TRUE(m) << err;
  EXPECT_GT(m->port(), 0);
  // The same port again cannot be bound: start() reports it, it does not throw.
  auto again =
      MetricsServer::start(MetricsConfig{true, "127.0.0.1:" + std::to_string(m->port())}, next, "", &err);
  EXPECT_FALSE(again);
  EXPECT_NE(err.find("cannot listen"), std::string::npos) << err;
}

TEST(Metrics, ConfigChecksAddress) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("torqued_metrics_cfg_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto file = (dir / "c.yaml").string();
  std::ofstream(file) << "metrics:\n  enabled: true\n  address: \"localhost\"\n";
  const LoadResult bad = load_config(file, LoadOptions{false});
  ASSERT_FALSE(bad.ok());
  bool named = false;
  for (const auto& e : bad.errors)
    named |= e.find("metrics.address") != std::string::npos && e.find(":3:") != std::string::npos;
  EXPECT_TRUE(named) << bad.errors.front();
  std::ofstream(file) << "metrics:\n  enabled: true\n  address: \"127.0.0.1:9464\"\n";
  const LoadResult good = load_config(file, LoadOptions{false});
  for (const auto& e : good.errors) EXPECT_EQ(e.find("metrics"), std::string::npos) << e;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace torqued::metrics
