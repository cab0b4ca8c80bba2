// tests/chain/test_time_chain.cpp: the time chain driven directly (no stage, no topics): the stage is a thin
// mapping of it, so the same inputs give the chain's estimates unchanged in the published samples.
#include <gtest/gtest.h>

#include <numbers>
#include <vector>

#include "steady_teeth.hpp"
#include "time_chain.hpp"
#include "time_stage.hpp"

namespace torqued {
namespace {

struct Capture final : SampleSink {
  std::vector<dds::AnySample> v;
  void emit(const dds::AnySample& s) noexcept override { v.push_back(s); }
};

TEST(TimeChain, StageIsAThinMappingOfTheChain) {
  // GIVEN the same steady 2500 rpm teeth fed to a time chain and to a time stage (decimation 1, no CAN)
  // WHEN both step 500 times THEN every published sample carries the chain's estimate of that step and
  // method, bit for bit, and the chain's step follows the configured rate.
  StageSettings s;
  s.time_decimation = 1;
  TimeChain chain(s, nullptr);
  Capture out;
  TimeStage stage(s, nullptr, out);
  ASSERT_TRUE(chain.ok()) << chain.error();
  EXPECT_EQ(chain.step_ns(), 1'000'000);
  const double w = 2500.0 * std::numbers::pi / 30.0;
  std::int64_t tooth_t = 0;
  std::size_t compared = 0;
  for (int k = 1; k <= 500; ++k) {
    const std::int64_t now = k * 1'000'000LL;
    while (tooth_t < now) {
      const ToothSample ts = test::next_steady_tooth(tooth_t, w);
      chain.on_tooth(ts);
      stage.on_tooth(ts);
    }
    const std::size_t before = out.v.size();
    const TimePipelineOutput& o = chain.step(now);
    stage.step(now, 0);
    for (std::size_t i = before; i < out.v.size(); ++i) {
      const auto& m = out.v[i].u.estimator;
      for (const TimeMethodOutput& b : kTimeMethodOutputs) {
        if (b.method != m.method) continue;
        const TorqueEstimate& e = o.*b.estimate;
        EXPECT_EQ(m.value_nm, e.torque_nm);
        EXPECT_EQ(m.uncertainty, e.uncertainty);
        EXPECT_EQ(m.health, static_cast<std::uint8_t>(e.health));
        EXPECT_EQ(m.source_t_ns, now);
        ++compared;
      }
    }
  }
  EXPECT_GE(compared, 500u) << "at least one method published per step";
}

TEST(TimeChain, NonPositiveStepIsRefusedWithAReason) {
  StageSettings s;
  s.time_pipeline.step_s = 0.0;
  const TimeChain chain(s, nullptr);
  EXPECT_FALSE(chain.ok());
  EXPECT_NE(chain.error().find("step"), std::string::npos);
}

}  // namespace
}  // namespace torqued
