// SocketCAN backend checks that need no CAN-capable kernel: config validation, behaviour when CAN is missing
// (clear error, keeps retrying, never blocks longer than its poll time-out, stops on request). The receive
// paths (frames, FD, timestamps, filters, down/up) are tested inside the VM (tests/vm).
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "socketcan_source.hpp"

namespace torqued {
namespace {

TEST(SocketCanConfig, RejectsBadValuesWithReason) {
  SocketCanConfig c;
  EXPECT_EQ(validate(c), "");
  c.interface = "";
  EXPECT_NE(validate(c).find("empty"), std::string::npos);
  c.interface = "averyveryverylongname";
  EXPECT_NE(validate(c).find("longer than"), std::string::npos);
  c.interface = "vcan0";
  c.poll_timeout_ms = 0;
  EXPECT_NE(validate(c).find("poll_timeout_ms"), std::string::npos);
  c.poll_timeout_ms = 100;
  c.filters.push_back({0x800, 0x7FF, false});
  EXPECT_NE(validate(c).find("0x800"), std::string::npos);
  c.filters.back().extended = true;
  EXPECT_EQ(validate(c), "");
}

TEST(SocketCanSource, InvalidConfigGivesErrorStatus) {
  SocketCanConfig c;
  c.interface = "";
  SocketCanSource s(c);
  EXPECT_FALSE(s.ok());
  CanFrame f;
  EXPECT_EQ(s.next(f), SourceStatus::kError);
  EXPECT_NE(s.last_error().find("empty"), std::string::npos);
}

TEST(SocketCanSource, MissingInterfaceIsReportedRetriedAndStoppable) {
  // GIVEN an interface that does not exist (or a kernel without CAN at all, like this build host)
  SocketCanConfig c;
  c.interface = "tqnocan9";
  c.poll_timeout_ms = 20;
  c.reopen_interval_ms = 10;
  SocketCanSource s(c);
  ASSERT_TRUE(s.ok());
  EXPECT_NE(s.link_state(), CanLinkState::kUp);
  EXPECT_NE(s.last_error().find("tqnocan9"), std::string::npos) << s.last_error();
  // WHEN polled: each call returns within about its time-out, and keeps retrying the open
  CanFrame f;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 5; ++i) EXPECT_EQ(s.next(f), SourceStatus::kWouldBlock);
  const auto dt = std::chrono::steady_clock::now() - t0;
  EXPECT_LT(dt, std::chrono::seconds(5));  // generous: proves it does not block forever
  EXPECT_GE(s.can_stats().open_failures, 2u);
  EXPECT_EQ(s.stats().records, 0u);
  // THEN a stop request from another thread ends it
  std::thread stopper([&] { s.request_stop(); });
  stopper.join();
  EXPECT_EQ(s.next(f), SourceStatus::kEnd);
  EXPECT_NE(s.describe().find("tqnocan9"), std::string::npos);
}

TEST(SocketCanSource, StopWakesABlockedNext) {
  SocketCanConfig c;
  c.interface = "tqnocan8";
  c.poll_timeout_ms = 10000;
  c.reopen_interval_ms = 60000;
  SocketCanSource s(c);
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    s.request_stop();
  });
  CanFrame f;
  SourceStatus st = SourceStatus::kWouldBlock;
  const auto t0 = std::chrono::steady_clock::now();
  while (st == SourceStatus::kWouldBlock &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30)) {
    st = s.next(f);
  }
  stopper.join();
  EXPECT_EQ(st, SourceStatus::kEnd);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(9));  // woke before the 10 s time-out
}

TEST(CanLinkState, Names) {
  EXPECT_STREQ(to_string(CanLinkState::kUp), "up");
  EXPECT_STREQ(to_string(CanLinkState::kDown), "down");
  EXPECT_STREQ(to_string(CanLinkState::kMissing), "missing");
}

}  // namespace
}  // namespace torqued
