// tests/service/test_stage_settings.cpp: the daemon's YAML keys reach StageSettings (publication decimations,
// edge time-out, status period, decoder max_trend/lost_tooth_min_rpm, in-cycle estimator parameters), bad
// values are refused with the key named, and the per-tooth Kalman/Fourier EstimatorTorque samples follow
// dds.tooth_estimator_decimation (Kalman stamped at the edge it refers to, before the tooth that produced
// it).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "config_loader.hpp"
#include "edge_file_source.hpp"
#include "fast_replay.hpp"
#include "sample_sink.hpp"
#include "stage_settings_from.hpp"
#include "synthetic_edge_csv.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

TEST(StageSettings, NewKeysAreMapped) {
  const std::string yaml =
      "wheel: {decoder: {max_trend: 2.5, lost_tooth_min_rpm: 250}}\n"
      "inputs: {edges: {timeout_s: 0.25}}\n"
      "estimators: {kalman: {enabled: false, smoother_lag: 2}, fourier: {harmonics: 8}}\n"
      "dds: {crank_state_decimation: 5, time_estimator_decimation: 4, tooth_estimator_decimation: 3,\n"
      "      status_period_s: 0.5}\n";
  const LoadResult r = load_config_from_string(yaml, "/tmp/x.yaml", LoadOptions{false});
  ASSERT_TRUE(r.ok()) << (r.errors.empty() ? "" : r.errors.front());
  const StageSettings s = stage_settings_from(*r.config);
  EXPECT_EQ(s.crank_decimation, 5);
  EXPECT_EQ(s.time_decimation, 4);
  EXPECT_EQ(s.tooth_estimator_decimation, 3);
  EXPECT_EQ(s.edge_timeout_ns, 250'000'000);
  EXPECT_EQ(s.status_period_ns, 500'000'000);
  EXPECT_DOUBLE_EQ(s.decoder.max_trend, 2.5);
  EXPECT_DOUBLE_EQ(s.decoder.lost_tooth_min_rpm, 250.0);
  EXPECT_FALSE(s.angle.run_kalman);
  EXPECT_TRUE(s.angle.run_fourier);
  EXPECT_EQ(s.angle.kalman.smoother_lag, 2);
  EXPECT_EQ(s.angle.fourier.harmonics, 8);
}

TEST(StageSettings, DefaultsMatchTheStructs) {
  const LoadResult r = load_config_from_string("{}\n", "/tmp/x.yaml", LoadOptions{false});
  ASSERT_TRUE(r.ok()) << (r.errors.empty() ? "" : r.errors.front());
  const StageSettings s = stage_settings_from(*r.config), d{};
  EXPECT_EQ(s.crank_decimation, d.crank_decimation);
  EXPECT_EQ(s.time_decimation, d.time_decimation);
  EXPECT_EQ(s.tooth_estimator_decimation, d.tooth_estimator_decimation);
  EXPECT_EQ(s.edge_timeout_ns, d.edge_timeout_ns);
  EXPECT_EQ(s.status_period_ns, d.status_period_ns);
  EXPECT_DOUBLE_EQ(s.decoder.max_trend, DecoderParams{}.max_trend);
  EXPECT_DOUBLE_EQ(s.decoder.lost_tooth_min_rpm, DecoderParams{}.lost_tooth_min_rpm);
}

TEST(StageSettings, BadValuesNameTheKey) {
  for (const auto& [yaml, key] :
       {std::pair{"dds: {crank_state_decimation: 0}\n", "dds.crank_state_decimation"},
        std::pair{"dds: {tooth_estimator_decimation: -1}\n", "dds.tooth_estimator_decimation"},
        std::pair{"dds: {status_period_s: 0}\n", "dds.status_period_s"},
        std::pair{"inputs: {edges: {timeout_s: -1}}\n", "inputs.edges.timeout_s"},
        std::pair{"wheel: {decoder: {max_trend: 0.5}}\n", "wheel.decoder.max_trend"}}) {
    const LoadResult r = load_config_from_string(yaml, "/tmp/x.yaml", LoadOptions{false});
    ASSERT_FALSE(r.ok()) << yaml;
    ASSERT_FALSE(r.errors.empty());
    EXPECT_NE(r.errors.front().find(key), std::string::npos) << r.errors.front();
  }
}

/// Counts the in-cycle EstimatorTorque samples and checks their stamps.
class InCycleSink final : public SampleSink {
 public:
  void emit(const dds::AnySample& s) noexcept override {
    if (s.topic == dds::Topic::kCrankState) last_tooth_t_ns = s.u.crank.source_t_ns;
    if (s.topic != dds::Topic::kEstimatorTorque) return;
    const auto& m = s.u.estimator;
    if (m.method == torque_METHOD_KALMAN) {
      ++kalman;
      if (m.source_t_ns < last_tooth_t_ns) ++kalman_before_tooth;
    } else if (m.method == torque_METHOD_FOURIER) {
      ++fourier;
      if (m.source_t_ns == last_tooth_t_ns) ++fourier_at_tooth;
    }
  }
  std::int64_t last_tooth_t_ns = -1;
  int kalman = 0, fourier = 0, kalman_before_tooth = 0, fourier_at_tooth = 0;
};

TEST(StageSettings, ToothEstimatorDecimation) {
  const fs::path dir = fs::temp_directory_path() / ("torqued_stage_settings_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string edges = (dir / "edges.csv").string();
  ASSERT_GT(test::write_edge_csv(edges, test::WheelRun{2000.0, 2000.0, 1.0}), 1000);
  int counts[3] = {};
  for (const int dec : {0, 1, 3}) {
    StageSettings s;
    s.crank_decimation = 1;  // every tooth: the sink knows the current tooth's time
    s.tooth_estimator_decimation = dec;
    EdgeCsvSource src(edges, {});
    ASSERT_TRUE(src.ok()) << src.last_error();
    InCycleSink sink;
    const ReplayResult r = run_fast_replay(s, &src, nullptr, 0, nullptr, sink);
    ASSERT_TRUE(r.error.empty()) << r.error;
    EXPECT_EQ(sink.kalman, sink.fourier) << "decimation " << dec;
    if (dec == 1) {
      EXPECT_GT(sink.kalman, 1500) << "2000 rpm 60-2 for 1 s: ~1900 teeth";
      EXPECT_GT(sink.kalman_before_tooth, sink.kalman * 9 / 10)
          << "Kalman = fixed-lag smoother: stamped at an earlier edge";
      EXPECT_GT(sink.fourier_at_tooth, sink.fourier * 9 / 10);
    }
    counts[dec == 0 ? 0 : dec == 1 ? 1 : 2] = sink.kalman;
  }
  EXPECT_EQ(counts[0], 0);
  EXPECT_NEAR(counts[2], counts[1] / 3, 2);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace torqued
