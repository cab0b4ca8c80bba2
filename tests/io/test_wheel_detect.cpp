// torque-decode --detect-wheel's analysis (io/wheel_detect.cpp): the wheel read off synthetic captures of
// known wheels (the tests' sensor simulator, with cranking ripple and a speed ramp) and off real captures.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "edge_file_source.hpp"
#include "synthetic_wheel.hpp"
#include "wheel_detect.hpp"
#include "wheel_names.hpp"

namespace torqued {
namespace {

/// Cranking up, 250 -> 2500 rpm in 3 s with +-20 % speed ripple per compression.
test::SynthOptions cranking(const WheelGeometry& w) {
  test::SynthOptions o;
  o.wheel = w;
  o.rpm0 = 250.0;
  o.rpm1 = 2500.0;
  o.duration_s = 3.0;
  o.ripple = 0.2;
  return o;
}

std::vector<std::int64_t> synthetic_teeth(const WheelGeometry& w) {
  test::SynthOptions o = cranking(w);
  o.cam = false;
  std::vector<std::int64_t> t;
  for (const auto& s : test::synthesize(o).teeth) t.push_back(s.t_ns);
  return t;
}

/// A catalogue wheel's marking edges while cranking up (+-20 % speed ripple per compression, 250 -> 2500
/// rpm), each period's end moved by up to +-2 % of it (edge jitter, fixed seed).
std::vector<std::int64_t> jittered_teeth(const char* name) {
  WheelGeometry w;
  EXPECT_TRUE(wheel_from_name(name, w, nullptr)) << name;
  std::vector<std::int64_t> t = synthetic_teeth(w);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  for (std::size_t k = 1; k + 1 < t.size(); ++k)
    t[k] +=
        static_cast<std::int64_t>(u(rng) * static_cast<double>(std::min(t[k] - t[k - 1], t[k + 1] - t[k])));
  return t;
}

bool has(const std::vector<std::string>& v, const char* s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

/// 40 turns of 24 equal teeth at 600 rpm with +-10 % speed ripple twice per turn (edge times, ns).
std::vector<std::int64_t> equal_teeth_600rpm() {
  std::vector<std::int64_t> t;
  double s = 0.0;
  for (int k = 0; k < 40 * 24; ++k) {
    t.push_back(static_cast<std::int64_t>(s * 1e9));
    s += 15.0 / (3600.0 * (1.0 + 0.1 * std::sin(4.0 * M_PI * k / 24.0)));
  }
  return t;
}

/// A catalogue wheel cranking up: its rising crank edges (each stamped `copies` times) and its cam edges.
struct CrankAndCam {
  std::vector<std::int64_t> teeth;
  std::vector<WheelCamEdge> cam;
};
CrankAndCam crank_and_cam(const char* name, std::size_t copies = 1) {
  WheelGeometry w;
  EXPECT_TRUE(wheel_from_name(name, w, nullptr)) << name;
  CrankAndCam c;
  for (const EdgeEvent& e : test::synthesize(cranking(w)).edges) {
    if (e.channel == 0 && e.level != 0) c.teeth.insert(c.teeth.end(), copies, e.t_ns);
    if (e.channel != 0) c.cam.push_back({e.t_ns, e.level != 0});
  }
  return c;
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

TEST(WheelDetect, UnevenPatternWheelIsACandidateByTheCrankAloneAndNamedWithItsCam) {
  // GIVEN miata-nb2 (4 teeth at 0, 70, 180, 250 deg, no missing-tooth gap), cranking ripple and jitter
  const WheelDetection d = detect_wheel(jittered_teeth("miata-nb2"));
  // THEN the repeat (2 teeth, 70/110) is found; it repeats twice per turn, which the crank cannot observe (a
  // wheel with the repeat once per turn gives the same edge times): a candidate, no angles, no match
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.positions, 0);
  EXPECT_EQ(d.pattern_teeth, 2) << describe(d);
  EXPECT_TRUE(d.matches.empty()) << describe(d);
  EXPECT_EQ(d.candidates, (std::vector<std::string>{"miata-nb2"})) << describe(d);
  EXPECT_TRUE(d.tooth_angles_deg.empty()) << describe(d);
  EXPECT_NE(describe(d).find("catalogue: not identified: candidates miata-nb2 (miata-nb2 repeats its 2 teeth "
                             "every 180 deg, 2 times per turn; edge times cannot tell"),
            std::string::npos)
      << describe(d);
  EXPECT_LT(d.noise_periods, 10) << describe(d);  // the 70 deg periods are no noise
  // GIVEN the same wheel with a cam (one window per 720 deg: its edges repeat every 8 teeth)
  const auto [teeth, cam] = crank_and_cam("miata-nb2");
  const WheelDetection c = detect_wheel(teeth, {}, cam);
  // THEN 4 teeth per turn: miata-nb2 is named, with its angles and the speed per turn
  ASSERT_TRUE(c.error.empty()) << c.error;
  EXPECT_EQ(c.cam_cycle_teeth, 8) << describe(c);
  EXPECT_EQ(c.matches, (std::vector<std::string>{"miata-nb2"})) << describe(c);
  EXPECT_DOUBLE_EQ(c.repeat_deg, 180.0);
  ASSERT_EQ(c.tooth_angles_deg.size(), 4u) << describe(c);
  const double truth[] = {0.0, 70.0, 180.0, 250.0};
  for (std::size_t i = 0; i < 4; ++i)
    EXPECT_NEAR(c.tooth_angles_deg[i], truth[i], 14.0) << describe(c);  // +-20 % speed ripple on 70 deg
  EXPECT_GT(c.revolutions, 20);
  EXPECT_LT(c.rpm_max, 2500.0 * 1.05) << describe(c);
  EXPECT_NE(describe(c).find("cam: its edges repeat every 8 crank teeth (one cam turn = 720 deg: 4 teeth per "
                             "revolution)\ncatalogue: miata-nb2 (its teeth repeat every 180 deg:"),
            std::string::npos)
      << describe(c);
}

TEST(WheelDetect, EquallySpacedWheelsAreNeverGivenACatalogueNameByTheCrankAlone) {
  // GIVEN the equally spaced catalogue wheels (4g63: 2 teeth, nissan-cas-24+1: 12), ripple and jitter
  for (const char* name : {"4g63", "nissan-cas-24+1"}) {
    const WheelDetection d = detect_wheel(jittered_teeth(name));
    // THEN equal spacing is found, no entry is printed as the match, the right one is among the candidates
    ASSERT_TRUE(d.error.empty()) << name << ": " << d.error;
    EXPECT_EQ(d.pattern_teeth, 1) << name << "\n" << describe(d);
    EXPECT_TRUE(d.matches.empty()) << name << "\n" << describe(d);
    EXPECT_TRUE(has(d.candidates, name)) << name << "\n" << describe(d);
    EXPECT_NE(describe(d).find("not identified by the crank alone"), std::string::npos) << describe(d);
  }
}

/// Cam edges at `edges` (deg of 720, polarity) every 720 deg, placed between the teeth `t` of an equally
/// spaced wheel (tooth k at k pitch deg) by interpolation.
std::vector<WheelCamEdge> cam_at(const std::vector<std::int64_t>& t, double pitch,
                                 const std::vector<std::pair<double, bool>>& edges) {
  std::vector<WheelCamEdge> cam;
  for (int cyc = 0; cyc * 720.0 < static_cast<double>(t.size()) * pitch; ++cyc)
    for (const auto& [deg, rising] : edges) {
      const double a = cyc * 720.0 + deg;
      const auto k = static_cast<std::size_t>(a / pitch);
      if (k + 1 >= t.size()) continue;
      const double frac = a / pitch - static_cast<double>(k);
      cam.push_back({t[k] + static_cast<std::int64_t>(frac * static_cast<double>(t[k + 1] - t[k])), rising});
    }
  std::sort(cam.begin(), cam.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  return cam;
}

TEST(WheelDetect, TheCamGivesTheTeethPerRevolutionOfAnEquallySpacedWheel) {
  for (const char* name : {"4g63", "nissan-cas-24+1"}) {
    // GIVEN the wheel's crank edges (cranking ripple) and its catalogue cam pattern, rotated by 100 deg
    WheelGeometry w;
    ASSERT_TRUE(wheel_from_name(name, w, nullptr));
    const std::vector<std::int64_t> teeth = synthetic_teeth(w);
    const auto entry = std::find_if(wheel_catalogue().begin(), wheel_catalogue().end(),
                                    [&](const NamedWheel& e) { return std::string(e.name) == name; });
    std::vector<std::pair<double, bool>> edges;
    for (int i = 0; i < entry->n_cam; ++i)
      edges.emplace_back(std::fmod(entry->cam[i].angle_deg + 100.0, 720.0), entry->cam[i].rising);
    std::sort(edges.begin(), edges.end());
    const WheelDetection d = detect_wheel(teeth, {}, cam_at(teeth, 360.0 / w.teeth(), edges));
    // THEN the cam cycle holds twice the teeth per revolution, and that names the one entry
    ASSERT_TRUE(d.error.empty()) << name << ": " << d.error;
    EXPECT_EQ(d.cam_cycle_teeth, 2 * w.teeth()) << name << "\n" << describe(d);
    EXPECT_EQ(d.matches, (std::vector<std::string>{name})) << describe(d);
    EXPECT_DOUBLE_EQ(d.repeat_deg, 360.0 / w.teeth());
    EXPECT_EQ(d.tooth_angles_deg.size(), static_cast<std::size_t>(w.teeth()));
  }
}

TEST(WheelDetect, ASymmetricCamDoesNotNameAnEntryWhoseCamPatternItIsNot) {
  // GIVEN 24 equal teeth per turn (600 rpm, +-10 % ripple twice per turn) and a cam high for 90 deg every
  // 360 deg (two equal windows per cam turn: the cam cycle looks like 24 teeth = 12 per revolution)
  const std::vector<std::int64_t> t = equal_teeth_600rpm();
  const auto cam = cam_at(t, 15.0, {{82.5, false}, {352.5, true}, {442.5, false}, {712.5, true}});
  const WheelDetection d = detect_wheel(t, {}, cam);
  // THEN nissan-cas-24+1 (12 teeth, one 11.5 deg cam slot per 720) is a candidate only, nothing is named
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.cam_cycle_teeth, 24) << describe(d);
  EXPECT_TRUE(d.matches.empty()) << describe(d);
  EXPECT_TRUE(has(d.candidates, "nissan-cas-24+1")) << describe(d);
  EXPECT_NE(describe(d).find("catalogue: not identified"), std::string::npos) << describe(d);
}

TEST(WheelDetect, WidthCodedWheelNeedsBothEdges) {
  // GIVEN GM 24x falling edges every 15 deg, the rising edge 3 or 12 deg later by the code 0x0A33BE
  std::vector<std::int64_t> fall, rise;
  const std::int64_t pitch = 5'000'000;  // 15 deg at 500 rpm
  for (int k = 0; k < 72; ++k) {
    fall.push_back(k * pitch);
    const bool narrow = ((0x0A33BEu >> (k % 24)) & 1u) != 0;
    rise.push_back(k * pitch + (narrow ? pitch / 5 : pitch * 4 / 5));
  }
  // THEN, from either marking edge, it says the widths carry the position, never a gap or pattern match
  for (const auto& [teeth, other] : {std::pair{fall, rise}, std::pair{rise, fall}}) {
    const WheelDetection d = detect_wheel(teeth, other);
    EXPECT_NE(d.error.find("pulse-width-coded"), std::string::npos) << describe(d);
    EXPECT_NE(d.error.find("needs both edges"), std::string::npos) << describe(d);
    EXPECT_NE(d.error.find("gm-24x"), std::string::npos) << describe(d);
    EXPECT_TRUE(d.matches.empty());
  }
}

TEST(WheelDetect, WideTeethOnAnUnevenWheelAreNoWidthCode) {
  // GIVEN miata-nb2 (teeth at 0, 70, 180, 250 deg) with 45 deg wide teeth, 600 rpm, +-10 % ripple per
  // compression: its duty is 45/70 or 45/110 of a period with nothing coded
  std::vector<std::int64_t> rise, fall;
  double s = 0.0;
  int prev = 0;                      // whole degrees integrated so far
  const auto at = [&](double deg) {  // time at crank angle deg (increasing), ripple twice per turn
    for (; prev + 1 <= deg; ++prev) s += 1.0 / (3600.0 * (1.0 + 0.1 * std::sin(2.0 * prev * M_PI / 180)));
    return static_cast<std::int64_t>(s * 1e9);
  };
  for (int r = 0; r < 40; ++r)
    for (const double a : {0.0, 70.0, 180.0, 250.0}) {
      rise.push_back(at(r * 360.0 + a));
      fall.push_back(at(r * 360.0 + a + 45.0));
    }
  // THEN from either edge it reads miata-nb2 (a candidate: no cam), not a width-coded wheel
  for (const auto& [teeth, other] : {std::pair{rise, fall}, std::pair{fall, rise}}) {
    const WheelDetection d = detect_wheel(teeth, other);
    ASSERT_TRUE(d.error.empty()) << d.error;
    EXPECT_TRUE(d.width_code.empty()) << d.width_code;
    EXPECT_EQ(d.candidates, (std::vector<std::string>{"miata-nb2"})) << describe(d);
  }
}

TEST(WheelDetect, GapWheelIsReadOffTheLongestCleanStretchOfANoisyCapture) {
  // GIVEN a 36-2 capture: clean revolutions, then a burst of noise edges and an irregular stretch
  std::vector<std::int64_t> t = synthetic_teeth(test::wheel_nm(36, 2));
  const std::size_t n = t.size();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t k = n / 3; k + 1 < n; ++k)  // from a third on: the teeth land anywhere in their period
    t[k] =
        t[k - 1] + 1 + static_cast<std::int64_t>(u(rng) * 1.9 * static_cast<double>(t[k + 1] - t[k - 1]) / 2);
  std::sort(t.begin(), t.end());
  const WheelDetection d = detect_wheel(t);
  // THEN the clean third gives 36-2, and the output says a stretch was read
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.runs, (std::vector<int>{34, 2})) << describe(d);
  EXPECT_TRUE(has(d.matches, "36-2")) << describe(d);
  EXPECT_FALSE(d.stretch.empty()) << describe(d);
  EXPECT_NE(describe(d).find("read: "), std::string::npos) << describe(d);
}

/// Tooth angles of a wheel (N-M wheels: their equally spaced teeth before the gap).
std::vector<double> angles_of(const WheelGeometry& w) {
  std::vector<double> a;
  for (int i = 0; i < w.teeth(); ++i)
    a.push_back(w.tooth_count > 0 ? w.tooth_angles_deg[static_cast<std::size_t>(i)]
                                  : 360.0 * i / w.positions);
  return a;
}

TEST(WheelDetect, NoCatalogueWheelIsEverGivenAWrongName) {
  // GIVEN every catalogue wheel read by its edge times (the width-coded gm-24x needs both edges), cranking
  // ripple and jitter
  for (const NamedWheel& entry : wheel_catalogue()) {
    if (entry.width_coded) continue;
    WheelGeometry truth;
    ASSERT_TRUE(wheel_from_name(entry.name, truth, nullptr));
    const WheelDetection d = detect_wheel(jittered_teeth(entry.name));
    // THEN it is read, and every name printed as the match has the same tooth list (an alias or N-M)
    ASSERT_TRUE(d.error.empty()) << entry.name << ": " << d.error;
    for (const std::string& m : d.matches) {
      WheelGeometry w;
      ASSERT_TRUE(wheel_from_name(m, w, nullptr)) << m;
      EXPECT_EQ(angles_of(w), angles_of(truth)) << entry.name << " read as " << m << "\n" << describe(d);
    }
    // (equally spaced teeth, or a cycle repeating within a turn: no match, the entry among the candidates)
    const bool ambiguous = (d.positions == 0 && d.pattern_teeth == 1) || !d.ambiguity.empty();
    EXPECT_TRUE(ambiguous || has(d.matches, entry.name)) << entry.name << "\n" << describe(d);
    if (ambiguous) EXPECT_TRUE(has(d.candidates, entry.name)) << entry.name << "\n" << describe(d);
    if (std::string(entry.name) == "36-2-2-16-16") {  // its half turn, 18-2, is another wheel (speed x2)
      EXPECT_FALSE(has(d.matches, "18-2")) << describe(d);
      EXPECT_TRUE(has(d.candidates, "18-2")) << describe(d);
      EXPECT_NE(describe(d).find("edge times cannot tell"), std::string::npos) << describe(d);
    }
  }
}

TEST(WheelDetect, TheCamTellsTheSymmetricWheelFromItsHalf) {
  // GIVEN 36-2-2-16-16 (16, 2 twice per turn) with its cam (rising 45 deg, falling 225 deg of 720)
  const auto [teeth, cam] = crank_and_cam("36-2-2-16-16");
  const WheelDetection d = detect_wheel(teeth, {}, cam);
  // THEN 64 teeth per cam turn = two cycles per turn: the whole wheel, its 32 angles, the speed per turn
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.matches, (std::vector<std::string>{"36-2-2-16-16"})) << describe(d);
  EXPECT_EQ(d.positions, 36) << describe(d);
  EXPECT_EQ(d.tooth_angles_deg.size(), 32u) << describe(d);
  EXPECT_LT(d.rpm_max, 2500.0 * 1.05) << describe(d);
}

TEST(WheelDetect, RandomPeriodsAreNeverGivenACatalogueName) {
  // GIVEN 30 captures of 300 random periods (1, 1.05, 0.95, 2.2 or 3.1 ms: teeth and gap-like periods in no
  // order), seeded
  for (unsigned seed = 1; seed <= 30; ++seed) {
    std::mt19937 rng(seed);
    const double choice[] = {1.0, 1.0, 1.0, 1.0, 1.05, 0.95, 2.2, 3.1};
    std::uniform_int_distribution<int> pick(0, 7);
    std::vector<std::int64_t> t{0};
    for (int k = 0; k < 300; ++k) t.push_back(t.back() + static_cast<std::int64_t>(choice[pick(rng)] * 1e6));
    const WheelDetection d = detect_wheel(t);
    // THEN no name is printed as the match (a chance repeat is at most a candidate)
    EXPECT_TRUE(d.matches.empty()) << "seed " << seed << "\n" << describe(d);
    EXPECT_EQ(describe(d).find("catalogue: ") == std::string::npos ||
                  describe(d).find("catalogue: not identified") != std::string::npos ||
                  describe(d).find("catalogue: no entry") != std::string::npos,
              true)
        << "seed " << seed << "\n"
        << describe(d);
  }
}

TEST(WheelDetect, DuplicatedAndBackwardTimeStampsAreNoise) {
  // GIVEN 36-2-2-17-15 while cranking with every edge duplicated (the same time twice: zero periods, half the
  // periods around each) and a time stamp running backwards every 100 edges
  const std::vector<std::int64_t> t = jittered_teeth("36-2-2-17-15");
  std::vector<std::int64_t> dup;
  for (std::size_t k = 0; k < t.size(); ++k) {
    dup.push_back(t[k]);
    dup.push_back(k % 100 == 50 ? t[k] - 1000 : t[k]);
  }
  const WheelDetection d = detect_wheel(dup);
  // THEN each period <= 0 is a noise period, and the wheel reads as without them
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.noise_periods, static_cast<int>(t.size())) << describe(d);
  EXPECT_EQ(d.runs, (std::vector<int>{17, 2, 15, 2})) << describe(d);
  EXPECT_TRUE(has(d.matches, "36-2-2-17-15")) << describe(d);
  EXPECT_EQ(describe(d).find("nan"), std::string::npos) << describe(d);
  // AND the same for a pattern wheel with its cam (the cam edges are read per crank period)
  const auto [teeth, cam] = crank_and_cam("miata-nb2", 2);
  const WheelDetection c = detect_wheel(teeth, {}, cam);
  ASSERT_TRUE(c.error.empty()) << c.error;
  EXPECT_EQ(c.matches, (std::vector<std::string>{"miata-nb2"})) << describe(c);
  EXPECT_GE(c.noise_periods, static_cast<int>(teeth.size() / 2)) << describe(c);
}

TEST(WheelDetect, RevolutionsCountTurnsNotOneTurnWindows) {
  // GIVEN 20 turns of 36-2-2-17-15 (two gaps per turn) at a steady 1200 rpm
  WheelGeometry w;
  ASSERT_TRUE(wheel_from_name("36-2-2-17-15", w, nullptr));
  std::vector<std::int64_t> t;
  for (int r = 0; r < 20; ++r)
    for (int i = 0; i < w.teeth(); ++i)
      t.push_back(std::llround((r * 360.0 + w.tooth_angles_deg[static_cast<std::size_t>(i)]) / 7200.0 * 1e9));
  const WheelDetection d = detect_wheel(t);
  // THEN 19 whole turns lie between the first and the last gap (one-turn windows sliding gap by gap: 37)
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.revolutions, 19) << describe(d);
  EXPECT_NEAR(d.rpm_min, 1200.0, 1.0);
  EXPECT_NEAR(d.rpm_max, 1200.0, 1.0);
}

TEST(WheelDetect, TheWidthCodedEntryIsNeverReadOffOneEdge) {
  // GIVEN 24 equal teeth per turn, one edge only, at 600 rpm (+-10 % ripple twice per turn), with a cam
  // window every 720 deg (its edges repeat every 48 teeth: 24 per turn, as gm-24x has)
  const std::vector<std::int64_t> t = equal_teeth_600rpm();
  const WheelDetection d = detect_wheel(t, {}, cam_at(t, 15.0, {{100.0, true}, {290.0, false}}));
  // THEN gm-24x (its position is in the pulse widths) is neither the match nor a candidate
  ASSERT_TRUE(d.error.empty()) << d.error;
  EXPECT_EQ(d.cam_cycle_teeth, 48) << describe(d);
  EXPECT_FALSE(has(d.matches, "gm-24x")) << describe(d);
  EXPECT_FALSE(has(d.candidates, "gm-24x")) << describe(d);
  EXPECT_EQ(describe(d).find("gm-24x"), std::string::npos) << describe(d);
  // AND without the cam neither
  const WheelDetection n = detect_wheel(t);
  EXPECT_FALSE(has(n.candidates, "gm-24x")) << describe(n);
}

}  // namespace
}  // namespace torqued
