// tests/integration/test_dds_shm.cpp: opt-in same-host delivery through shared memory (Cyclone DDS +
// iceoryx). RouDi (iox-roudi, config/roudi_config.toml) runs; torqued publishes the paced demo at 4x with
// config/cyclonedds-shm.xml and QoS that iceoryx can carry (no deadline, keep-last 16, reliable). Two
// subscribers on this host take EngineTorque and CrankState: one with cyclonedds-shm.xml (its readers must
// report shared memory), one with cyclonedds-loopback.xml (no SharedMemory: the network path, as a subscriber
// on another host has). Both must receive the same samples, bit for bit, with no seq gap; the daemon's
// writers must have gone through shared memory with loans. Skipped when iox-roudi is not installed.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "dds/dds.h"
#include "dds/ddsc/dds_loan_api.h"
#include "process.hpp"
#include "qos.hpp"
#include "topics.hpp"

namespace torqued {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
constexpr std::uint32_t kDomain = 6;  // other tests use 0, 7, 8, 9
constexpr int kDepth = 16;            // writer history: <= iceoryx's history capacity
constexpr int kReaderDepth = 256;     // the readers keep more, so a descheduled subscriber loses nothing

const std::string kSrc = TORQUED_SOURCE_DIR;

/// Cyclone configuration text of a file, for dds_create_domain (a per-domain configuration in this process).
std::string xml(const std::string& name) { return test::slurp(kSrc + "/config/" + name); }

/// QoS iceoryx can carry (and the daemon offers with the test's YAML): reliable, keep-last, volatile, no
/// deadline, automatic liveliness.
dds::TopicQos shm_qos() { return dds::TopicQos{true, kDepth, 0, 1000}; }

struct Received {
  std::vector<torque_EngineTorque> engine;
  std::vector<torque_CrankState> crank;
};

/// A subscriber of EngineTorque and CrankState on kDomain with the given Cyclone configuration.
class Subscriber {
 public:
  explicit Subscriber(const std::string& config) {
    domain_ = dds_create_domain(kDomain, config.c_str());
    participant_ = dds_create_participant(kDomain, nullptr, nullptr);
    if (participant_ < 0) return;
    engine_ = reader(dds::Topic::kEngineTorque);
    crank_ = reader(dds::Topic::kCrankState);
  }
  ~Subscriber() {
    if (participant_ > 0) dds_delete(participant_);
    if (domain_ > 0) dds_delete(domain_);
  }
  [[nodiscard]] bool ok() const { return participant_ > 0 && engine_ > 0 && crank_ > 0; }
  [[nodiscard]] bool shared_memory() const {
    return dds_is_shared_memory_available(engine_) && dds_is_shared_memory_available(crank_);
  }
  /// Takes everything available; returns the number of samples taken.
  std::size_t take(Received& r) { return take_into(engine_, r.engine) + take_into(crank_, r.crank); }

 private:
  dds_entity_t reader(dds::Topic t) {
    dds::DdsSettings s;
    s.domain_id = kDomain;
    const dds_entity_t topic = dds::create_topic(participant_, s, t);
    dds_qos_t* q = dds::make_qos(shm_qos());
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, kReaderDepth);
    const dds_entity_t r = dds_create_reader(participant_, topic, q, nullptr);
    dds_delete_qos(q);
    return r;
  }
  template <class T>
  static std::size_t take_into(dds_entity_t reader, std::vector<T>& out) {
    std::array<T, kDepth> buf{};
    std::array<void*, kDepth> ptr{};
    std::array<dds_sample_info_t, kDepth> info{};
    for (std::size_t i = 0; i < buf.size(); ++i) ptr[i] = &buf[i];
    std::size_t n_all = 0;
    for (;;) {
      const int n = dds_take(reader, ptr.data(), info.data(), buf.size(), buf.size());
      if (n <= 0) break;
      for (int i = 0; i < n; ++i)
        if (info[static_cast<std::size_t>(i)].valid_data) out.push_back(buf[static_cast<std::size_t>(i)]);
      n_all += static_cast<std::size_t>(n);
    }
    return n_all;
  }
  dds_entity_t domain_ = 0, participant_ = 0, engine_ = 0, crank_ = 0;
};

template <class T>
void write_all(const std::string& path, const std::vector<T>& v) {
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(T)));
}
template <class T>
std::vector<T> read_all(const std::string& path) {
  const std::string b = test::slurp(path);
  std::vector<T> v(b.size() / sizeof(T));
  std::memcpy(v.data(), b.data(), v.size() * sizeof(T));
  return v;
}

/// Child process: one subscriber. Receives until 3 s without a sample (after the first) or 60 s, writes what
/// it got to dir/<tag>_engine.bin and dir/<tag>_crank.bin, exits 0 (2: DDS set-up failed, 3: its readers use
/// shared memory or not, unlike `shm`). In a child so that this process never registers with RouDi (which
/// sends SIGTERM to its registered processes when it stops).
[[noreturn]] void subscriber(const std::string& config, bool shm, const std::string& dir,
                             const std::string& tag) {
  Subscriber sub(xml(config));
  if (!sub.ok()) _exit(2);
  if (sub.shared_memory() != shm) _exit(3);
  Received r;
  r.engine.reserve(1 << 16);
  r.crank.reserve(1 << 16);
  const auto start = Clock::now();
  auto last = start;
  while (Clock::now() - start < std::chrono::seconds(60)) {
    if (sub.take(r) > 0) last = Clock::now();
    if (!r.engine.empty() && Clock::now() - last > std::chrono::seconds(3)) break;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  write_all(dir + "/" + tag + "_engine.bin", r.engine);
  write_all(dir + "/" + tag + "_crank.bin", r.crank);
  _exit(0);
}

template <class T>
void expect_same(std::vector<T> shm, std::vector<T> net, const char* topic) {
  auto by_seq = [](const T& a, const T& b) { return a.seq < b.seq; };
  std::sort(shm.begin(), shm.end(), by_seq);
  std::sort(net.begin(), net.end(), by_seq);
  ASSERT_GT(shm.size(), 50u) << topic << ": too few samples over shared memory";
  ASSERT_EQ(shm.size(), net.size()) << topic << ": shared memory and network path received different counts";
  for (std::size_t i = 0; i < shm.size(); ++i) {
    ASSERT_EQ(shm[i].seq, i + 1) << topic << ": seq gap over shared memory";
    ASSERT_EQ(0, std::memcmp(&shm[i], &net[i], sizeof(T)))
        << topic << " sample seq " << shm[i].seq << " differs";
  }
}

TEST(DdsSharedMemory, SameSamplesOverSharedMemoryAndTheNetworkPath) {
  const char* roudi = "/usr/bin/iox-roudi";
  if (::access(roudi, X_OK) != 0) GTEST_SKIP() << "iox-roudi not installed (Debian package iceoryx)";
  const fs::path dir = fs::temp_directory_path() / ("torqued_shm_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);

  // The paced demo at 4x on kDomain with QoS iceoryx can carry.
  std::string y = test::slurp(kSrc + "/config/demo.yaml");
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"../data/demo/", kSrc + "/data/demo/"},
           {"dbc: demo.dbc", "dbc: " + kSrc + "/config/demo.dbc"},
           {"domain_id: 0",
            "domain_id: " + std::to_string(kDomain) +
                "\n  qos:\n"
                "    engine_torque: {reliability: reliable, history_depth: 16, deadline_ms: 0}\n"
                "    estimator_torque: {reliability: reliable, history_depth: 16, deadline_ms: 0}\n"
                "    cylinder_torque: {reliability: reliable, history_depth: 16, deadline_ms: 0}\n"
                "    crank_state: {reliability: reliable, history_depth: 16, deadline_ms: 0}\n"
                "    status: {reliability: reliable, history_depth: 4, deadline_ms: 0}"}}) {
    for (std::size_t at = y.find(from); at != std::string::npos; at = y.find(from, at + to.size()))
      y.replace(at, from.size(), to);
  }
  const std::string cfg = (dir / "demo_shm.yaml").string();
  std::ofstream(cfg) << y;

  test::Process rd({roudi, "-c", kSrc + "/config/roudi_config.toml"}, {}, (dir / "roudi.log").string());
  const auto roudi_log = [&] { return test::slurp((dir / "roudi.log").string()); };
  ASSERT_TRUE(test::eventually(
      10, [&] { return roudi_log().find("RouDi is ready") != std::string::npos || !rd.running(); }));
  if (!rd.running())
    GTEST_SKIP() << "RouDi did not start (one per host: another one running?): " << roudi_log();

  // Both subscribers in children, forked before anything here creates a thread.
  const pid_t net = ::fork();
  if (net == 0) subscriber("cyclonedds-loopback.xml", false, dir.string(), "net");
  const pid_t shm = ::fork();
  if (shm == 0) subscriber("cyclonedds-shm.xml", true, dir.string(), "shm");

  test::Process d({TORQUED_EXE, "--config", cfg, "--speed", "4", "--exit-when-done", "--wait-subscribers",
                   "2", "--state-dir", (dir / "state").string()},
                  {"CYCLONEDDS_URI=file://" + kSrc + "/config/cyclonedds-shm.xml"},
                  (dir / "daemon.log").string());
  const bool exited = d.wait(60);
  const std::string log = test::slurp((dir / "daemon.log").string());
  for (const auto& [pid, what] : {std::pair{net, "network"}, std::pair{shm, "shared-memory"}}) {
    int st = 0;
    ASSERT_EQ(::waitpid(pid, &st, 0), pid);
    EXPECT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0)
        << what << " subscriber: status " << st << " (exit 3: shared memory "
        << (what[0] == 'n' ? "used" : "not used") << ")";
  }
  rd.signal(SIGINT);
  EXPECT_TRUE(rd.wait(10));
  ASSERT_TRUE(exited) << log;
  EXPECT_EQ(d.exit_code(), 0) << log;

  EXPECT_NE(
      log.find("DDS shared memory (iceoryx) for: EngineTorque EstimatorTorque CylinderTorque CrankState"),
      std::string::npos)
      << log;
  const auto at = log.find(" through shared-memory loans");
  ASSERT_NE(at, std::string::npos) << log;
  const auto open = log.rfind('(', at);
  EXPECT_GT(std::stoull(log.substr(open + 1)), 1000u) << "loaned writes: " << log.substr(open, 40);
  expect_same(read_all<torque_EngineTorque>((dir / "shm_engine.bin").string()),
              read_all<torque_EngineTorque>((dir / "net_engine.bin").string()), "EngineTorque");
  expect_same(read_all<torque_CrankState>((dir / "shm_crank.bin").string()),
              read_all<torque_CrankState>((dir / "net_crank.bin").string()), "CrankState");
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace torqued
