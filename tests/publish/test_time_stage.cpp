// tests/publish/test_time_stage.cpp: the time chain's DDS mapping (publish/time_stage.cpp) and the one
// validity mapping shared with the angle stage (publish/validity.hpp): decimation, method ids, every Health
// flagged the same way, a non-finite value never valid, and a bad step rejected.
#include <gtest/gtest.h>

#include <limits>
#include <numbers>
#include <vector>

#include "dbc.hpp"
#include "steady_teeth.hpp"
#include "time_stage.hpp"
#include "validity.hpp"

namespace torqued {
namespace {

struct Capture final : SampleSink {
  std::vector<dds::AnySample> v;
  void emit(const dds::AnySample& s) noexcept override { v.push_back(s); }
};

// Synced 6° teeth at constant speed `w` (rad/s) up to `now`; `tooth_t` is the last tooth's time (ns).
void feed_teeth_until(TimeStage& t, std::int64_t now, double w, std::int64_t& tooth_t) {
  while (tooth_t < now) t.on_tooth(test::next_steady_tooth(tooth_t, w));
}

TEST(Validity, EveryHealthHasOneMeaning) {
  EXPECT_EQ(validity_of(Health::kValid), 0u);
  EXPECT_EQ(validity_of(Health::kNotConverged), static_cast<std::uint32_t>(torque_VALIDITY_NOT_CONVERGED));
  EXPECT_EQ(validity_of(Health::kNotExcited), static_cast<std::uint32_t>(torque_VALIDITY_NOT_CONVERGED));
  EXPECT_EQ(validity_of(Health::kStaleInput), static_cast<std::uint32_t>(torque_VALIDITY_STALE_CAN));
  EXPECT_EQ(validity_of(Health::kNoSync), static_cast<std::uint32_t>(torque_VALIDITY_NO_SYNC));
  for (Health h : {Health::kInvalidInput, Health::kNumerical, Health::kDisabled})
    EXPECT_EQ(validity_of(h), static_cast<std::uint32_t>(torque_VALIDITY_ESTIMATOR_FAULT)) << to_string(h);
  // NaN never leaves as valid, whatever the health says.
  EXPECT_NE(
      validity_of(Health::kValid, std::numeric_limits<double>::quiet_NaN()) & torque_VALIDITY_ESTIMATOR_FAULT,
      0u);
  EXPECT_EQ(validity_of(TorqueEstimate{0, 12.0, 1.0, Health::kValid}), 0u);
}

TEST(TimeStage, EmitsEveryNthStepWithTheSharedValidity) {
  // GIVEN 1 kHz steps, decimation 10, teeth of a steady 3000 rpm wheel and no CAN WHEN 1000 steps run THEN
  // 100 rounds of the four Na et al. methods are emitted, stamped with their step time, each flagged by the
  // shared mapping of its health (no CAN: the load input is missing, so none is valid).
  StageSettings s;
  s.time_decimation = 10;
  Capture out;
  TimeStage t(s, nullptr, out);
  ASSERT_TRUE(t.ok()) << t.error();
  EXPECT_EQ(t.step_ns(), 1'000'000);
  const double w = 3000.0 * std::numbers::pi / 30.0;
  std::int64_t tooth_t = 0;
  for (int k = 1; k <= 1000; ++k) {
    const std::int64_t now = k * 1'000'000LL;
    feed_teeth_until(t, now, w, tooth_t);
    t.step(now, 0);
  }
  EXPECT_EQ(t.steps(), 1000u);
  ASSERT_EQ(out.v.size() % 100, 0u);
  EXPECT_GE(out.v.size(), 100u);
  EXPECT_LE(out.v.size(), 400u);
  for (const auto& a : out.v) {
    ASSERT_EQ(a.topic, dds::Topic::kEstimatorTorque);
    const auto& m = a.u.estimator;
    EXPECT_EQ(m.source_t_ns % 10'000'000, 0) << "decimated to every 10th step";
    EXPECT_TRUE(m.method == torque_METHOD_UIO || m.method == torque_METHOD_SLIDING_MODE ||
                m.method == torque_METHOD_DIRTY_DIFF || m.method == torque_METHOD_ADAPTIVE);
    EXPECT_EQ(m.validity, validity_of(static_cast<Health>(m.health), m.value_nm));
    EXPECT_NE(m.validity, 0u) << "no load torque on CAN: nothing may be published as valid";
  }
}

TEST(TimeStage, NonPositiveStepIsRejected) {
  StageSettings s;
  s.time_pipeline.step_s = 0.0;
  Capture out;
  const TimeStage t(s, nullptr, out);
  EXPECT_FALSE(t.ok());
  EXPECT_NE(t.error().find("step"), std::string::npos) << t.error();
}

TEST(TimeStage, ElectricMachineSignalGoesStaleThenItsEstimatesSayStaleCan) {
  // GIVEN the machine's torque bound (EM_1.EmTorque, sole load, ratio 2, time-out 50 ms) and frames until 0.5
  // s WHEN the time stage steps to 1 s THEN before 0.5 s no estimate carries STALE_CAN (the folded load is
  // known without any load signal), after 0.6 s every one does (adaptive left out: it also needs MAF).
  const char* kDbc =
      "VERSION \"\"\n\nBU_: EM\n\nBO_ 528 EM_1: 4 EM\n"
      " SG_ EmTorque : 0|16@1- (0.1,0) [-3276.8|3276.7] \"Nm\" Vector__XXX\n";
  auto r = DbcDatabase::parse_string(kDbc, "em.dbc");
  ASSERT_TRUE(r.db.has_value()) << (r.errors.empty() ? "" : r.errors.front());
  StageSettings s;
  s.time_decimation = 10;
  s.signals[static_cast<std::size_t>(Quantity::kEmTorque)] = {"EM_1", "EmTorque", 50'000'000};
  s.angle.e_machine.bound = true;
  s.angle.e_machine.ratio = 2.0;
  s.angle.e_machine.sole_load = true;
  Capture out;
  TimeStage t(s, &*r.db, out);
  ASSERT_TRUE(t.ok()) << t.error();
  const double w = 3000.0 * std::numbers::pi / 30.0;
  std::int64_t tooth_t = 0;
  std::size_t early_stale = 0, late_fresh = 0, early = 0, late = 0;
  for (int k = 1; k <= 1000; ++k) {
    const std::int64_t now = k * 1'000'000LL;
    feed_teeth_until(t, now, w, tooth_t);
    if (k % 10 == 0 && k <= 500) {
      CanFrame f;
      f.t_ns = now;
      f.id = 528;
      f.len = 4;
      const auto raw = static_cast<std::int16_t>(-100);  // −10 N m: generating
      f.data[0] = static_cast<std::uint8_t>(raw & 0xFF);
      f.data[1] = static_cast<std::uint8_t>((raw >> 8) & 0xFF);
      t.on_frame(f);
    }
    const std::size_t before = out.v.size();
    t.step(now, 0);
    for (std::size_t i = before; i < out.v.size(); ++i) {
      if (out.v[i].u.estimator.method == torque_METHOD_ADAPTIVE) continue;  // also needs MAF (not bound here)
      const bool stale = (out.v[i].u.estimator.validity & torque_VALIDITY_STALE_CAN) != 0;
      if (k > 20 && k < 500) {
        ++early;
        early_stale += stale;
      } else if (k > 600) {
        ++late;
        late_fresh += !stale;
      }
    }
  }
  ASSERT_GT(early, 0u);
  ASSERT_GT(late, 0u);
  EXPECT_EQ(early_stale, 0u);
  EXPECT_EQ(late_fresh, 0u);
}

}  // namespace
}  // namespace torqued
