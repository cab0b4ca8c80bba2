// torque-decode --detect-wheel's analysis (io/wheel_detect.cpp): the wheel read off synthetic captures of
// known wheels (the tests' sensor simulator, with cranking ripple and a speed ramp) and off real captures.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "edge_file_source.hpp"
#include "synthetic_wheel.hpp"
#include "wheel_detect.hpp"

namespace torqued {
namespace {

std::vector<std::int64_t> synthetic_teeth(const WheelGeometry& w) {
  test::SynthOptions o;
  o.wheel = w;
  o.rpm0 = 250.0;
  o.rpm1 = 2500.0;
  o.duration_s = 3.0;
  o.ripple = 0.2;
  o.cam = false;
  std::vector<std::int64_t> t;
  for (const auto& s : test::synthesize(o).teeth) t.push_back(s.t_ns);
  return t;
}

bool has(const std::vector<std::string>& v, const char* s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

TEST(WheelDetect, JeepEvdIsReadOffItsCaptureWithItsCatalogueNames) {
  const WheelDetection d = detect_wheel(synthetic_teeth(test::wheel_runs(36, {17, 2, 15, 2})));
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.positions, 36);
  EXPECT_EQ(d.runs, (std::vector<int>{17, 2, 15, 2}));
  EXPECT_TRUE(has(d.matches, "36-2-2-17-15")) << describe(d);
  EXPECT_TRUE(has(d.matches, "jeep-evd")) << describe(d);
  EXPECT_TRUE(d.decoder_error.empty()) << d.decoder_error;
  ASSERT_EQ(d.tooth_angles_deg.size(), 32u);
  EXPECT_DOUBLE_EQ(d.tooth_angles_deg[17], 190.0);  // after 17 teeth (0..160) and 2 missing (170, 180)
  // the ramp 250 -> 2500 rpm, per revolution (the first and last are partly outside)
  EXPECT_GT(d.rpm_min, 250.0 * 0.9);
  EXPECT_LT(d.rpm_max, 2500.0 * 1.05);
  EXPECT_GT(d.revolutions, 30);
  EXPECT_NE(describe(d).find("tooth_angles_deg: [0, 10, 20,"), std::string::npos) << describe(d);
}

TEST(WheelDetect, SymmetricAndMissingToothWheels) {
  const WheelDetection sym = detect_wheel(synthetic_teeth(test::wheel_runs(36, {16, 2, 16, 2})));
  ASSERT_TRUE(sym.error.empty()) << sym.error;
  EXPECT_EQ(sym.runs, (std::vector<int>{16, 2}));  // one cycle is half a turn: the structure repeats
  EXPECT_EQ(sym.positions, 18);
  const WheelDetection w60 = detect_wheel(synthetic_teeth(test::wheel_nm(60, 2)));
  ASSERT_TRUE(w60.error.empty()) << w60.error;
  EXPECT_TRUE(has(w60.matches, "60-2")) << describe(w60);
  EXPECT_TRUE(has(w60.matches, "bosch-60-2")) << describe(w60);
  const WheelDetection none = detect_wheel(std::vector<std::int64_t>{0, 1000, 2000, 3000, 4000});
  EXPECT_FALSE(none.error.empty());
}

TEST(WheelDetect, RealArcticCatCapture) {
  EdgeCsvOptions o;
  o.crank_column = "Channel 1";
  o.cam_column = "";
  EdgeCsvSource src(std::string(TORQUED_SOURCE_DIR) + "/tests/data/captures/rusefi/arctic-cat.csv", o);
  ASSERT_TRUE(src.ok()) << src.last_error();
  std::vector<std::int64_t> t;
  EdgeEvent e;
  while (src.next(e) == SourceStatus::kOk)
    if (e.channel == 0 && e.level != 0) t.push_back(e.t_ns);
  const WheelDetection d = detect_wheel(t);
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.runs, (std::vector<int>{11, 1, 10, 2}));
  EXPECT_TRUE(has(d.matches, "arctic-cat")) << describe(d);
  std::printf("%s", describe(d).c_str());
}

}  // namespace
}  // namespace torqued
