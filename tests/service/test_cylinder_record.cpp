// tests/service/test_cylinder_record.cpp: the CylinderTorque topic carries, besides each cycle's shares, the
// filtered per-cylinder pattern and its 1σ (the pattern the --cylinders table scores, and what it rests
// on). Replays the bundled demo recording (config/demo.yaml) through the daemon's fast replay.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "config_loader.hpp"
#include "fast_replay.hpp"
#include "replay_inputs.hpp"

namespace torqued {
namespace {

struct CylinderTap final : SampleSink {
  std::vector<torque_CylinderTorque> records;
  void emit(const dds::AnySample& s) noexcept override {
    if (s.topic == dds::Topic::kCylinderTorque) records.push_back(s.u.cylinder);
  }
};

TEST(CylinderRecord, CarriesTheFilteredPatternAndItsSigmaOnTheDemo) {
  // GIVEN the demo recording (an I4 whose cylinders burn alike within a few %)
  const LoadResult lr = load_config(std::string(TORQUED_SOURCE_DIR) + "/config/demo.yaml");
  ASSERT_TRUE(lr.config.has_value());
  RunInputs inputs = open_inputs(*lr.config);
  ASSERT_TRUE(inputs.ok()) << inputs.error;
  CylinderTap tap;
  // WHEN the daemon's chain replays it
  const ReplayResult r = run_fast_replay(inputs.settings, inputs.edges.get(), inputs.can.get(),
                                         inputs.can_offset_ns, inputs.dbc_ptr(), tap);
  ASSERT_TRUE(r.error.empty()) << r.error;
  ASSERT_GT(tap.records.size(), 200u);
  // THEN each cylinder's filtered imbalance is an average of the cycles' shares: inside the range they
  // spanned, mostly neither this cycle's share nor empty, and quieter than the shares; its 1σ is stated once
  // measured
  int averaged = 0, with_sd = 0;
  double ss_raw = 0.0, ss_filt = 0.0;
  for (int c = 0; c < 4; ++c) {
    double lo = 1e300, hi = -1e300;
    for (const auto& rec : tap.records) {
      if (rec.cylinders != 4) continue;  // a record without cylinder values (health says why)
      lo = std::min(lo, rec.imbalance_pct[c]);
      hi = std::max(hi, rec.imbalance_pct[c]);
      const double f = rec.imbalance_filtered_pct[c];
      EXPECT_GE(f, lo - 1e-9) << "cycle " << rec.cycle;
      EXPECT_LE(f, hi + 1e-9) << "cycle " << rec.cycle;
      if (f != 0.0 && f != rec.imbalance_pct[c]) ++averaged;
      if (rec.cycle > 50) {
        ss_raw += rec.imbalance_pct[c] * rec.imbalance_pct[c];
        ss_filt += f * f;
      }
    }
  }
  for (const auto& rec : tap.records) {
    EXPECT_GE(rec.imbalance_sd_pct, 0.0);
    if (rec.imbalance_sd_pct > 0.0) ++with_sd;
  }
  const auto n = static_cast<int>(tap.records.size());
  EXPECT_GE(averaged, 4 * n / 2);
  EXPECT_GE(with_sd, n / 2);
  EXPECT_LT(ss_filt, 0.5 * ss_raw);
}

}  // namespace
}  // namespace torqued
