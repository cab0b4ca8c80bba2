// FuelAngleWindow (estimators/energy/fuel_angle_window.hpp): the fuel and MAP of a 720° window come from the
// intake events of the cylinders whose work lies in it; cut-off events are counted apart (fuel model).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "alloc_counter.hpp"
#include "fuel_angle_window.hpp"

using torqued::FuelAngleWindow;
using torqued::FuelIntakeInput;
using torqued::FuelWindow;
using torqued::kMaxCylinders;
using torqued::test::AllocationScope;

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;
// I4, firing TDCs 0/180/360/540°; intake 132° BTDC and centroid 162° ATDC are multiples of the 6° tooth
// pitch, so every intake event is recorded on the tooth exactly at its angle.
constexpr int kCyl = 4;
constexpr double kIntakeBtdc = 132.0, kCentroidAtdc = 162.0, kPitch = 6.0;
std::array<double, kMaxCylinders> tdcs() {
  std::array<double, kMaxCylinders> t{};
  for (int m = 0; m < kCyl; ++m) t[static_cast<std::size_t>(m)] = 4.0 * std::numbers::pi * m / kCyl;
  return t;
}
std::int64_t t_of(double unwrapped_deg) { return static_cast<std::int64_t>(unwrapped_deg * 1e5); }  // 10°/ms
double fuel_at(double unwrapped_deg) { return 20e-6 * (1.0 + unwrapped_deg / 720.0); }  // a fuel ramp (kg)
double map_at(double unwrapped_deg) { return 50000.0 + 10.0 * unwrapped_deg; }          // a MAP ramp (Pa)

// Intake angle (unwrapped, deg) of firing position m whose work centroid lies in (end − 720°, end].
double intake_in_window(int m, double end_deg) {
  const double lead = kIntakeBtdc + kCentroidAtdc;
  const double a = 180.0 * m - kIntakeBtdc;  // congruent intake angles mod 720
  double i = a + 720.0 * std::floor((end_deg - lead - a) / 720.0);
  return i;  // largest i ≡ a with i + lead <= end
}
}  // namespace

TEST(FuelAngleWindow, AveragesTheIntakeEventsWhoseWorkLiesInTheWindow) {
  // GIVEN a window fed with a fuel and MAP ramp, tooth by tooth over three cycles
  FuelAngleWindow w(kCyl, tdcs(), kIntakeBtdc, kCentroidAtdc, 0.0);
  double deg = 0.0;
  for (; deg <= 3 * 720.0 + 300.0; deg += kPitch) {
    FuelIntakeInput in{fuel_at(deg), map_at(deg), false, true};
    AllocationScope alloc;
    w.on_tooth(t_of(deg), deg * kDeg, in);
    ASSERT_EQ(alloc.count(), 0u);
  }
  deg -= kPitch;  // the last tooth fed
  // WHEN the window ending at boundary 0 (cylinder 1's TDC − 20°, relative 700°) is read
  const double end_rel = 700.0;
  const double end = deg - std::fmod(deg - end_rel + 720.0, 720.0);
  const FuelWindow fw = w.window(end_rel * kDeg);
  // THEN it holds the four events chosen by angle, their fuel and MAP averaged (ramps: mean of the angles)
  ASSERT_TRUE(fw.valid);
  EXPECT_EQ(fw.fired, 4);
  EXPECT_EQ(fw.cut, 0);
  double mean_i = 0.0, lo = 1e9, hi = -1e9;
  for (int m = 0; m < kCyl; ++m) {
    const double i = intake_in_window(m, end);
    mean_i += i / kCyl;
    lo = std::min(lo, i);
    hi = std::max(hi, i);
  }
  EXPECT_NEAR(fw.fuel_kg, fuel_at(mean_i), 1e-12);
  EXPECT_NEAR(fw.map_fired_pa, map_at(mean_i), 1e-6);
  EXPECT_NEAR(fw.fuel_min_kg, fuel_at(lo), 1e-12);
  EXPECT_NEAR(fw.fuel_max_kg, fuel_at(hi), 1e-12);
  // ... which lags the instantaneous value by the intake→work delay (not the CAN value at the window end)
  EXPECT_LT(fw.fuel_kg, fuel_at(end) - 0.2 * (fuel_at(720.0) - fuel_at(0.0)));
}

TEST(FuelAngleWindow, SplitsAWindowStraddlingAFuelCutOffEntry) {
  // GIVEN fuel cut-off from unwrapped angle 1450° on, read 20° after the window's end (as the pipeline does)
  FuelAngleWindow w(kCyl, tdcs(), kIntakeBtdc, kCentroidAtdc, 0.0);
  const double cut_from = 1450.0;
  double deg = 0.0;
  for (; deg <= 2160.0; deg += kPitch)
    w.on_tooth(t_of(deg), deg * kDeg, {fuel_at(deg), 60000.0, deg >= cut_from, true});
  deg -= kPitch;
  // WHEN the window ending at the last passage of 700° is read
  const double end = deg - std::fmod(deg - 700.0 + 720.0, 720.0);
  const FuelWindow fw = w.window(700.0 * kDeg);
  // THEN the events whose intake was at or after the cut are cut-off events, the others fired
  int cut = 0;
  double fuel = 0.0;
  for (int m = 0; m < kCyl; ++m) {
    const double i = intake_in_window(m, end);
    if (i >= cut_from)
      ++cut;
    else
      fuel += fuel_at(i);
  }
  ASSERT_TRUE(fw.valid);
  ASSERT_GT(cut, 0);
  ASSERT_LT(cut, kCyl);
  EXPECT_EQ(fw.cut, cut);
  EXPECT_EQ(fw.fired, kCyl - cut);
  EXPECT_NEAR(fw.fuel_kg, fuel / (kCyl - cut), 1e-12);  // fuel mean over the fired events only
  EXPECT_NEAR(fw.map_cut_pa, 60000.0, 1e-9);
}

TEST(FuelAngleWindow, AFiringEventReadingZeroFuelTakesTheNextReport) {
  // GIVEN a cut-off exit where the ECU's fuel mass still reads 0 for 60° after the flag cleared
  FuelAngleWindow w(kCyl, tdcs(), kIntakeBtdc, kCentroidAtdc, 0.0);
  const double exit_at = 1800.0;
  double deg = 0.0;
  for (; deg <= 3200.0; deg += kPitch) {
    const bool cut = deg < exit_at;
    const double fuel = deg < exit_at + 60.0 ? 0.0 : 25e-6;
    w.on_tooth(t_of(deg), deg * kDeg, {fuel, 60000.0, cut, true});
  }
  // WHEN a window holding only events after the exit is read
  const FuelWindow fw = w.window(std::fmod(deg - kPitch, 720.0) * kDeg);
  // THEN every event fired with the resumed fuel (none at 0 fuel)
  ASSERT_TRUE(fw.valid);
  EXPECT_EQ(fw.cut, 0);
  EXPECT_NEAR(fw.fuel_min_kg, 25e-6, 1e-15);
  EXPECT_NEAR(fw.fuel_kg, 25e-6, 1e-15);
}

TEST(FuelAngleWindow, UnknownUntilEveryCylinderHasAnEventAndAfterABreak) {
  // GIVEN half a cycle of teeth: not every cylinder's work is in the window yet
  FuelAngleWindow w(kCyl, tdcs(), kIntakeBtdc, kCentroidAtdc, 0.0);
  for (double deg = 0.0; deg <= 360.0; deg += kPitch)
    w.on_tooth(t_of(deg), deg * kDeg, {20e-6, 60000.0, false, true});
  EXPECT_FALSE(w.window(0.0).valid);
  for (double deg = 366.0; deg <= 3000.0; deg += kPitch)
    w.on_tooth(t_of(deg), deg * kDeg, {20e-6, 60000.0, false, true});
  EXPECT_TRUE(w.window(0.0).valid);
  // WHEN the sequence breaks THEN the window is unknown again
  w.break_sequence();
  w.on_tooth(0, 0.0, {20e-6, 60000.0, false, true});
  EXPECT_FALSE(w.window(0.0).valid);
  // and an event with invalid inputs makes its window unknown
  FuelAngleWindow v(kCyl, tdcs(), kIntakeBtdc, kCentroidAtdc, 0.0);
  for (double deg = 0.0; deg <= 3000.0; deg += kPitch)
    v.on_tooth(t_of(deg), deg * kDeg, {20e-6, 60000.0, false, deg < 2000.0});
  EXPECT_FALSE(v.window(std::fmod(3000.0, 720.0) * kDeg).valid);
}

TEST(FuelAngleWindow, AConsistentReportAfterTheIntakeRevisesItsCutOffState) {
  // GIVEN a report window of 3 ms (30° here) and a cut-off exit whose CAN frame arrives 2 ms (20°) after the
  // intake of firing position 0 at unwrapped 1308° (flag still set and no fuel at the intake itself)
  FuelAngleWindow w(kCyl, tdcs(), kIntakeBtdc, kCentroidAtdc, 0.003);
  const double frame_at = 1308.0 + 20.0;
  double deg = 0.0;
  for (; deg <= 2160.0; deg += kPitch) {
    const bool cut = deg < frame_at;
    w.on_tooth(t_of(deg), deg * kDeg, {cut ? 0.0 : 25e-6, 60000.0, cut, true});
  }
  // WHEN the window holding that event (intakes 1128..1668°) is read
  const FuelWindow fw = w.window(700.0 * kDeg);
  // THEN the event at 1308° fired with the reported fuel; the one at 1128° stays cut
  ASSERT_TRUE(fw.valid);
  EXPECT_EQ(fw.cut, 1);
  EXPECT_EQ(fw.fired, 3);
  EXPECT_NEAR(fw.fuel_kg, 25e-6, 1e-15);
  // and a report later than the window does not revise: the same exit 5 ms after the intake leaves it cut
  FuelAngleWindow late(kCyl, tdcs(), kIntakeBtdc, kCentroidAtdc, 0.003);
  for (deg = 0.0; deg <= 2160.0; deg += kPitch) {
    const bool cut = deg < 1308.0 + 50.0;
    late.on_tooth(t_of(deg), deg * kDeg, {cut ? 0.0 : 25e-6, 60000.0, cut, true});
  }
  EXPECT_EQ(late.window(700.0 * kDeg).cut, 2);
}
