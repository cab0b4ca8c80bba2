// tests/integration/test_dds_security.cpp: opt-in DDS Security (config/security, docs/security.md) on
// loopback, with real processes: torqued publishing, torque-echo subscribing, each with its own identity from
// a test PKI made here by tools/scripts/make-test-pki.sh (openssl, offline) in a temporary directory. DDS
// domains 17, 18 and 19, one per test, used by no other test (so they may run beside the others).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "process.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;
using Env = std::vector<std::string>;

const std::string kSrc = TORQUED_SOURCE_DIR;

/// Number in torque-echo's summary line "torque-echo: N samples received" (-1 when it is missing).
long samples_received(const std::string& log) {
  const std::string key = "torque-echo: ";
  for (std::size_t p = 0; (p = log.find(key, p)) != std::string::npos; p += key.size()) {
    std::istringstream in(log.substr(p + key.size()));
    long n = -1;
    std::string word;
    if (in >> n >> word && word == "samples") return n;
  }
  return -1;
}

/// The engine_id column of a recorded engine_cycle.csv (one entry per row).
std::vector<std::string> engine_ids(const std::string& csv_path) {
  std::istringstream in(test::slurp(csv_path));
  std::string line;
  std::vector<std::string> ids;
  int col = -1;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ls(line);
    for (std::string x; std::getline(ls, x, ',');) f.push_back(x);
    if (col < 0) {
      for (std::size_t i = 0; i < f.size(); ++i)
        if (f[i] == "engine_id") col = static_cast<int>(i);
      if (col < 0) return {"no engine_id column"};
      continue;
    }
    if (static_cast<std::size_t>(col) < f.size()) ids.push_back(f[static_cast<std::size_t>(col)]);
  }
  return ids;
}

class DdsSecurity : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("torqued_sec_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    for (const char* pki : {"pki", "rogue_pki"}) {  // ours, and one from another CA (an intruder's)
      const std::string cmd = kSrc + "/tools/scripts/make-test-pki.sh " + (dir_ / pki).string() + " > " +
                              (dir_ / pki).string() + ".log 2>&1";
      ASSERT_EQ(std::system(cmd.c_str()), 0) << test::slurp((dir_ / pki).string() + ".log");
    }
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  [[nodiscard]] std::string path(const std::string& name) const { return (dir_ / name).string(); }
  [[nodiscard]] Env secure(const std::string& role, const std::string& pki = "pki") const {
    return {"CYCLONEDDS_URI=file://" + kSrc + "/config/security/cyclonedds-secure-loopback.xml",
            "TORQUED_DDS_PKI=" + path(pki), "TORQUED_DDS_ROLE=" + role};
  }
  [[nodiscard]] static Env plain() {
    return {"CYCLONEDDS_URI=file://" + kSrc + "/config/cyclonedds-loopback.xml"};
  }
  /// demo.yaml on `domain` with `engine_id`, written as <name>.yaml.
  [[nodiscard]] std::string config(const std::string& name, int domain, int engine_id) const {
    const std::string sub = path(name);
    fs::create_directories(sub);
    std::string y =
        test::slurp(test::write_demo_config(sub, "domain_id: 0", "domain_id: " + std::to_string(domain)));
    const std::string from = "engine_id: 1";
    y.replace(y.find(from), from.size(), "engine_id: " + std::to_string(engine_id));
    std::ofstream(sub + "/torqued.yaml") << y;
    return sub + "/torqued.yaml";
  }
  [[nodiscard]] std::vector<std::string> daemon_args(const std::string& name, int domain, int engine_id,
                                                     bool wait_for_subscriber) const {
    std::vector<std::string> a{TORQUED_EXE,
                               "--config",
                               config(name, domain, engine_id),
                               "--speed",
                               "4",
                               "--exit-when-done",
                               "--state-dir",
                               path(name + "/state")};
    if (wait_for_subscriber) a.insert(a.end(), {"--wait-subscribers", "1"});
    return a;
  }
  [[nodiscard]] std::vector<std::string> echo_args(const std::string& name, int domain,
                                                   double duration_s) const {
    return {TORQUE_ECHO_EXE, "--domain",   std::to_string(domain),
            "--topic",       "engine",     "--cycles-only",
            "--format",      "none",       "--record",
            path(name),      "--duration", std::to_string(duration_s)};
  }
  fs::path dir_;
};

TEST_F(DdsSecurity, OnlyTheAuthenticatedSubscriberReceivesEngineTorque) {
  // GIVEN a secure daemon (daemon identity) on domain 17 and two subscribers: one with the subscriber
  // identity,
  //       one without security (the plain loopback configuration)
  constexpr int kDomain = 17;
  test::Process authed(echo_args("echo_authed", kDomain, 25), secure("subscriber"), path("echo_authed.log"));
  test::Process outsider(echo_args("echo_plain", kDomain, 25), plain(), path("echo_plain.log"));
  test::Process daemon(daemon_args("daemon", kDomain, 1, true), secure("daemon"), path("daemon.log"));
  // WHEN the daemon replays the demo (about 5 s at 4x) and the subscribers run to their end
  ASSERT_TRUE(daemon.wait(60)) << test::slurp(path("daemon.log"));
  EXPECT_EQ(daemon.exit_code(), 0) << test::slurp(path("daemon.log"));
  ASSERT_TRUE(authed.wait(40));
  ASSERT_TRUE(outsider.wait(40));
  // THEN the authenticated subscriber has the engine's cycles and the other one nothing at all
  const std::string authed_log = test::slurp(path("echo_authed.log"));
  const std::string plain_log = test::slurp(path("echo_plain.log"));
  EXPECT_GT(samples_received(authed_log), 300) << authed_log;  // the demo is ~350 cycles
  EXPECT_EQ(samples_received(plain_log), 0) << plain_log;
  EXPECT_GT(engine_ids(path("echo_authed/engine_cycle.csv")).size(), 300u);
  EXPECT_TRUE(engine_ids(path("echo_plain/engine_cycle.csv")).empty());
}

TEST_F(DdsSecurity, UnauthenticatedPublishersCannotInject) {
  // GIVEN an authenticated subscriber on domain 18, our secure daemon (engine 1), and two intruders
  // publishing
  //       EngineTorque for engines 2 and 3: one without security, one with an identity and signed documents
  //       from another CA (a complete PKI of its own, the same subject names)
  constexpr int kDomain = 18;
  test::Process echo(echo_args("echo", kDomain, 25), secure("subscriber"), path("echo.log"));
  test::Process plain_intruder(daemon_args("intruder_plain", kDomain, 2, false), plain(),
                               path("intruder_plain.log"));
  test::Process rogue_intruder(daemon_args("intruder_rogue", kDomain, 3, false),
                               secure("daemon", "rogue_pki"), path("intruder_rogue.log"));
  test::Process daemon(daemon_args("daemon", kDomain, 1, true), secure("daemon"), path("daemon.log"));
  // WHEN all three publish for the length of the demo
  for (auto* p : {&daemon, &plain_intruder, &rogue_intruder}) ASSERT_TRUE(p->wait(60));
  EXPECT_EQ(daemon.exit_code(), 0) << test::slurp(path("daemon.log"));
  // (the intruders themselves run normally: nothing stops them publishing, only nobody takes their samples)
  EXPECT_EQ(plain_intruder.exit_code(), 0) << test::slurp(path("intruder_plain.log"));
  ASSERT_TRUE(echo.wait(40));
  // THEN the subscriber recorded our engine's cycles and not one row of engine 2 or 3
  const std::vector<std::string> ids = engine_ids(path("echo/engine_cycle.csv"));
  EXPECT_GT(ids.size(), 300u) << test::slurp(path("echo.log"));
  for (const std::string& id : ids) ASSERT_EQ(id, "1") << "an intruder's sample was received";
}

TEST_F(DdsSecurity, EachRoleOnlyWhatItsPermissionsGrant) {
  constexpr int kDomain = 19;
  // GIVEN valid identities used in the wrong role: the subscriber identity running the daemon (publishing),
  //       the daemon identity running torque-echo (subscribing)
  test::Process daemon_as_subscriber(daemon_args("daemon_as_sub", kDomain, 1, false), secure("subscriber"),
                                     path("daemon_as_sub.log"));
  test::Process echo_as_daemon(echo_args("echo_as_daemon", kDomain, 10), secure("daemon"),
                               path("echo_as_daemon.log"));
  // WHEN they start
  ASSERT_TRUE(daemon_as_subscriber.wait(30));
  ASSERT_TRUE(echo_as_daemon.wait(30));
  // THEN access control refuses the writer and the reader: both exit with an error naming the refused entity
  const std::string dlog = test::slurp(path("daemon_as_sub.log"));
  EXPECT_NE(daemon_as_subscriber.exit_code(), 0) << dlog;
  EXPECT_NE(dlog.find("dds_create_writer"), std::string::npos) << dlog;
  const std::string elog = test::slurp(path("echo_as_daemon.log"));
  EXPECT_EQ(echo_as_daemon.exit_code(), 1) << elog;
  EXPECT_NE(elog.find("dds_create_reader"), std::string::npos) << elog;
}

}  // namespace
}  // namespace torqued
