// tests/service/test_web_starvation.cpp: the metrics endpoint keeps answering scrapes while hostile peers
// hold connections (the finding: two held TCP connections, one silent and one trickling a header line every 2
// s, made it serve 0 of 4 scrapes: 2 worker threads, no time-outs; Prometheus would have fired TorquedDown on
// a healthy daemon). Loopback only, bounded in count and time.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "loopback_client.hpp"
#include "metrics.hpp"

namespace torqued::metrics {
namespace {
using namespace std::chrono_literals;

class NullSink final : public SampleSink {
 public:
  void emit(const dds::AnySample&) noexcept override {}
};

TEST(MetricsHostilePeers, HeldConnectionsDoNotBlockScrapes) {
  NullSink next;
  std::string err;
  auto m = MetricsServer::start(MetricsConfig{true, "127.0.0.1:0"}, next, "", &err);
  ASSERT_NE(m, nullptr) << err;
  const int port = m->port();
  // Peer 1: connects and says nothing. Peer 2: a request line, then one header line every 300 ms, never done.
  test::LoopbackSocket silent(port), trickle(port);
  ASSERT_GE(silent.fd(), 0);
  ASSERT_GE(trickle.fd(), 0);
  ASSERT_TRUE(trickle.send_all("GET /metrics HTTP/1.1\r\n"));
  std::atomic<bool> done{false};
  std::thread trickler([&] {
    for (int i = 0; i < 40 && !done; ++i) {
      if (!trickle.send_all("X-Slow: " + std::to_string(i) + "\r\n")) break;
      std::this_thread::sleep_for(300ms);
    }
  });
  std::this_thread::sleep_for(200ms);  // both held connections are now with the server
  int served = 0;
  for (int i = 0; i < 4; ++i) {
    const std::string r = test::http_get(port, "/metrics", 3000ms);
    if (r.rfind("HTTP/1.1 200", 0) == 0 && r.find("torqued_") != std::string::npos) ++served;
  }
  done = true;
  trickler.join();
  EXPECT_EQ(served, 4) << "scrapes served while two connections are held";
}

}  // namespace
}  // namespace torqued::metrics
