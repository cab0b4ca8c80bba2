// tests/tools/test_echo_range.cpp: a foreign plain-DDS writer publishes an absurd EngineTorque (fused 1e9 N
// m, quality 0) on the daemon's topic; torque-echo with the daemon's configuration flags it (stderr says the
// value is outside the configured engine's physical range, its table row is marked OUT OF RANGE, the count is
// said at exit and --fail-on-range exits 6), while the plausible samples of the same writer pass unmarked.
// Loopback DDS on a domain of its own (CYCLONEDDS_URI from ctest).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "dds/dds.h"
#include "qos.hpp"
#include "torque.h"

namespace {
using namespace std::chrono_literals;

std::string slurp(const std::string& path) {
  std::ifstream f(path);
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

TEST(TorqueEchoRange, ForeignWritersAbsurdTorqueIsFlagged) {
  constexpr std::uint32_t kDomain = 31;
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("torqued_echo_range_" + std::to_string(::getpid())))
          .string();
  std::filesystem::create_directories(dir);
  const std::string cmd = std::string(TORQUE_ECHO_EXE) + " --config " + TORQUED_SOURCE_DIR +
                          "/config/demo.yaml --domain " + std::to_string(kDomain) +
                          " --topic engine --count 3 --duration 20 --fail-on-range >" + dir + "/out.txt 2>" +
                          dir + "/err.txt";
  // The foreign writer: plain DDS, the daemon's topic name and QoS, no daemon.
  const dds_entity_t pp = dds_create_participant(kDomain, nullptr, nullptr);
  ASSERT_GT(pp, 0);
  const dds_entity_t topic =
      dds_create_topic(pp, &torque_EngineTorque_desc, "torque/EngineTorque", nullptr, nullptr);
  ASSERT_GT(topic, 0);
  dds_qos_t* q = torqued::dds::make_qos(torqued::dds::DdsSettings::default_qos()[0]);
  const dds_entity_t w = dds_create_writer(pp, topic, q, nullptr);
  dds_delete_qos(q);
  ASSERT_GT(w, 0);
  std::thread echo([&] {
    const int rc = std::system(cmd.c_str());
    ::testing::Test::RecordProperty("echo_rc", rc);
    std::ofstream(dir + "/rc.txt") << (WIFEXITED(rc) ? WEXITSTATUS(rc) : -1);
  });
  dds_publication_matched_status_t st{};
  for (int i = 0; i < 200 && st.current_count == 0; ++i) {  // torque-echo's reader matched (≤ 20 s)
    std::this_thread::sleep_for(100ms);
    dds_get_publication_matched_status(w, &st);
  }
  EXPECT_GT(st.current_count, 0u) << "torque-echo never subscribed";
  for (std::uint64_t seq = 1; seq <= 3; ++seq) {
    torque_EngineTorque s{};
    s.engine_id = 1;
    s.seq = seq;
    s.source_t_ns = static_cast<std::int64_t>(seq) * 100'000'000;
    s.kind = torque_KIND_CYCLE;
    s.speed_rad_s = 300.0;
    s.brake_nm = s.fused_nm = seq == 2 ? 1e9 : 80.0;  // the middle one: absurd, quality 0 (valid)
    s.indicated_nm = 95.0;
    s.friction_nm = 15.0;
    ASSERT_EQ(dds_write(w, &s), DDS_RETCODE_OK);
  }
  echo.join();
  dds_delete(pp);
  const std::string out = slurp(dir + "/out.txt"), err = slurp(dir + "/err.txt");
  EXPECT_EQ(slurp(dir + "/rc.txt"), "6") << "exit status with --fail-on-range\n" << err;
  EXPECT_NE(err.find("outside the physical range of the configured engine"), std::string::npos) << err;
  EXPECT_NE(err.find("1 samples outside the engine's physical range"), std::string::npos) << err;
  std::size_t marked = 0;
  for (std::size_t p = out.find("OUT OF RANGE"); p != std::string::npos; p = out.find("OUT OF RANGE", p + 1))
    ++marked;
  EXPECT_EQ(marked, 1u) << out;
  std::filesystem::remove_all(dir);
}

}  // namespace
