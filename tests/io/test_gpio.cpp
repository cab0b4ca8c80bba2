// GPIO backend checks without GPIO hardware: config validation, clear errors for a missing chip, and the pure
// kernel-event -> EdgeEvent conversion (levels, times, lost-edge detection).
#include <gtest/gtest.h>

#include "alloc_counter.hpp"
#include "gpio_source.hpp"

namespace torqued {
namespace {

constexpr int kRising = 1;   // GPIOD_LINE_EVENT_RISING_EDGE
constexpr int kFalling = 2;  // GPIOD_LINE_EVENT_FALLING_EDGE

TEST(GpioConfig, ValidationNamesTheKey) {
  GpioConfig c;
  EXPECT_NE(validate(c).find("crank_line"), std::string::npos);  // crank line is required
  c.crank_line = 3;
  EXPECT_EQ(validate(c), "");
  c.cam_line = 3;
  EXPECT_NE(validate(c).find("differ"), std::string::npos);
  c.cam_line = -2;
  EXPECT_NE(validate(c).find("cam_line"), std::string::npos);
  c.cam_line = 4;
  c.chip = "";
  EXPECT_NE(validate(c).find("chip"), std::string::npos);
  c.chip = "gpiochip0";
  c.poll_timeout_ms = 0;
  EXPECT_NE(validate(c).find("poll_timeout_ms"), std::string::npos);
}

TEST(GpioConfig, BiasNames) {
  GpioConfig::Bias b{};
  EXPECT_TRUE(parse_gpio_bias("pull-up", b));
  EXPECT_EQ(b, GpioConfig::Bias::kPullUp);
  EXPECT_TRUE(parse_gpio_bias("as-is", b));
  EXPECT_EQ(b, GpioConfig::Bias::kAsIs);
  EXPECT_FALSE(parse_gpio_bias("pullup", b));
}

TEST(GpioEdgeSource, MissingChipGivesClearError) {
  GpioConfig c;
  c.chip = "gpiochip97";
  c.crank_line = 0;
  GpioEdgeSource s(c);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.last_error().find("cannot open chip 'gpiochip97'"), std::string::npos) << s.last_error();
  EXPECT_NE(s.last_error().find("gpiodetect"), std::string::npos);
  EdgeEvent e;
  EXPECT_EQ(s.next(e), SourceStatus::kError);
  s.request_stop();  // harmless on a failed source
}

TEST(GpioEdgeSource, InvalidConfigIsReportedBeforeOpening) {
  GpioConfig c;  // no crank line
  GpioEdgeSource s(c);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.last_error().find("crank_line"), std::string::npos);
}

TEST(GpioEdgeConverter, ConvertsLevelsTimesAndOffset) {
  GpioEdgeConverter conv(5);
  EdgeEvent e;
  ASSERT_TRUE(conv.convert(kRising, 12, 345'678'901, 1'000, e));
  EXPECT_EQ(e.t_ns, 12'345'679'901);
  EXPECT_EQ(e.channel, 5);
  EXPECT_EQ(e.level, 1);
  ASSERT_TRUE(conv.convert(kFalling, 12, 400'000'000, 0, e));
  EXPECT_EQ(e.level, 0);
  EXPECT_EQ(e.t_ns, 12'400'000'000);
  EXPECT_EQ(conv.lost(), 0u);
}

TEST(GpioEdgeConverter, RejectsUnknownTypesAndBadTimes) {
  GpioEdgeConverter conv(0);
  EdgeEvent e{77, 9, 9};
  EXPECT_FALSE(conv.convert(0, 1, 0, 0, e));
  EXPECT_FALSE(conv.convert(3, 1, 0, 0, e));
  EXPECT_FALSE(conv.convert(kRising, -1, 0, 0, e));
  EXPECT_FALSE(conv.convert(kRising, 1, 1'000'000'000, 0, e));
  EXPECT_EQ(e.t_ns, 77);  // untouched
}

TEST(GpioEdgeConverter, RepeatedLevelCountsALostEdgeWithoutAllocating) {
  // GIVEN rise, fall, fall (a rise went missing), rise, rise (a fall went missing), and a time step backwards
  GpioEdgeConverter conv(0);
  EdgeEvent e;
  test::AllocationScope scope;
  conv.convert(kRising, 0, 100, 0, e);
  conv.convert(kFalling, 0, 200, 0, e);
  conv.convert(kFalling, 0, 300, 0, e);
  conv.convert(kRising, 0, 400, 0, e);
  conv.convert(kRising, 0, 350, 0, e);
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_EQ(conv.lost(), 2u);
  EXPECT_EQ(conv.backwards(), 1u);
}

}  // namespace
}  // namespace torqued
