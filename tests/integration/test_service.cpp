// tests/integration/test_service.cpp: torqued as a service, for real, in child processes:
//   - the sd_notify protocol on our own NOTIFY_SOCKET (unix datagram): READY=1, STATUS=, regular WATCHDOG=1,
//     and the pings stop when a pipeline stalls (test-only hook TORQUED_TEST_STALL_AFTER_S);
//   - SIGTERM drains and exits 0 within a bounded time with complete CSV files;
//   - SIGHUP reloads the safe parts of the configuration;
//   - learned state survives kill -9 (atomic writes) and is loaded at the next start;
//   - fast replay through the real binary is byte-identical across runs (determinism);
//   - Cyclone DDS's own threads in the daemon run with the publisher thread's real-time scheduling;
//   - paced with DDS and mlockall, the daemon stays within 64 MiB resident (thread stacks of 512 KiB);
//   - without the right to SCHED_FIFO and mlockall it runs anyway, says so and flags it in DaemonStatus,
//     unless realtime.require_rt is set.
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/socket.h>
#include <sys/un.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>
#include <tuple>

#include "daemon_test.hpp"
#include "process.hpp"
#include "state_store.hpp"

namespace torqued {
namespace {

/// Complete rows of a recorded CSV (header excluded); the recorder flushes at least once a second.
std::size_t csv_rows(const std::string& path) {
  const std::string t = test::slurp(path);
  const auto n = static_cast<std::size_t>(std::count(t.begin(), t.end(), '\n'));
  return n > 0 ? n - 1 : 0;
}

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

class Service : public test::DaemonTest {
 protected:
  Service() : DaemonTest("torqued_svc_") {}
};

/// A NOTIFY_SOCKET of our own: collects the datagrams with their arrival time.
class NotifySocket {
 public:
  explicit NotifySocket(const std::string& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::snprintf(a.sun_path, sizeof a.sun_path, "%s", path.c_str());
    ::unlink(path.c_str());
    bound_ = ::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    timeval tv{0, 50'000};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }
  ~NotifySocket() {
    ::close(fd_);
    ::unlink(path_.c_str());
  }
  [[nodiscard]] bool bound() const { return bound_; }
  /// Receives for `seconds`, appending (time since t0, message) pairs.
  void receive_for(double seconds, Clock::time_point t0) {
    const auto until = Clock::now() + std::chrono::duration<double>(seconds);
    char buf[4096];
    while (Clock::now() < until) {
      const ssize_t n = ::recv(fd_, buf, sizeof buf - 1, 0);
      if (n > 0)
        msgs.emplace_back(std::chrono::duration<double>(Clock::now() - t0).count(),
                          std::string(buf, static_cast<std::size_t>(n)));
    }
  }
  std::vector<std::pair<double, std::string>> msgs;

 private:
  std::string path_;
  int fd_ = -1;
  bool bound_ = false;
};

TEST_F(Service, NotifyReadyStatusWatchdogAndPingsStopOnStall) {
  // GIVEN our own NOTIFY_SOCKET and WATCHDOG_USEC = 400 ms WHEN torqued runs a paced replay and its angle
  // pipeline is frozen after 2 s THEN we see READY=1, STATUS=..., WATCHDOG=1 at least every 400 ms before the
  // stall and none for the 2 s after it (systemd would kill and restart the service).
  const std::string sock = (dir_ / "notify.sock").string();
  NotifySocket ns(sock);
  ASSERT_TRUE(ns.bound());
  const auto t0 = Clock::now();
  test::Process d(args({}), {"NOTIFY_SOCKET=" + sock, "WATCHDOG_USEC=400000", "TORQUED_TEST_STALL_AFTER_S=2"},
                  (dir_ / "daemon.log").string());
  ns.receive_for(5.0, t0);
  d.signal(SIGTERM);
  ASSERT_TRUE(d.wait(10)) << log();
  bool ready = false, status = false;
  std::vector<double> pings;
  for (const auto& [t, m] : ns.msgs) {
    if (m.find("READY=1") != std::string::npos) ready = true;
    if (m.find("STATUS=") != std::string::npos) status = true;
    if (m.find("WATCHDOG=1") != std::string::npos) pings.push_back(t);
  }
  EXPECT_TRUE(ready) << log();
  EXPECT_TRUE(status);
  ASSERT_GE(pings.size(), 3u) << log();
  // Regular pings while healthy: the gaps between pings before the stall stay below WATCHDOG_USEC.
  double last = -1, max_gap = 0;
  for (double t : pings)
    if (t < 1.9) {
      if (last >= 0) max_gap = std::max(max_gap, t - last);
      last = t;
    }
  EXPECT_GT(last, 0.0);
  EXPECT_LT(max_gap, 0.4);
  // The stall starts 2 s after the daemon's own start (which is a few 100 ms after ours); after that, no
  // ping: the last one comes before 3 s and then nothing for the remaining 2 s of the observation.
  EXPECT_LT(pings.back(), 3.0) << "watchdog pinged while the angle pipeline was stalled";
}

TEST_F(Service, SigtermDrainsAndFlushesWithinBound) {
  const std::string rec = (dir_ / "rec").string();
  test::Process d(args({"--record", rec}), {}, (dir_ / "daemon.log").string());
  ASSERT_TRUE(test::eventually(10, [&] { return log().find("running") != std::string::npos; })) << log();
  ASSERT_TRUE(test::eventually(10, [&] { return csv_rows(rec + "/engine_segment.csv") > 10; })) << log();
  const auto t = Clock::now();
  d.signal(SIGTERM);
  ASSERT_TRUE(d.wait(5.0)) << "no exit within 5 s of SIGTERM\n" << log();
  const double took = std::chrono::duration<double>(Clock::now() - t).count();
  EXPECT_EQ(d.exit_code(), 0) << log();
  EXPECT_LT(took, 3.0);  // drain bound 2 s + flush
  EXPECT_NE(log().find("SIGTERM: draining"), std::string::npos) << log();
  const std::string csv = test::slurp(rec + "/engine_segment.csv");
  ASSERT_GT(csv.size(), 200u);
  EXPECT_EQ(csv.back(), '\n') << "last row torn";
  EXPECT_GT(std::count(csv.begin(), csv.end(), '\n'), 10);
}

TEST_F(Service, SighupReloadsLoggingLevel) {
  test::Process d(args({}), {}, (dir_ / "daemon.log").string());
  ASSERT_TRUE(test::eventually(10, [&] { return log().find("running") != std::string::npos; })) << log();
  // Edit the file in place: logging level info -> debug (safe), domain 0 -> 7 (needs a restart: refused).
  std::string y = test::slurp(config_);
  y.replace(y.find("level: info"), 11, "level: debug");
  y.replace(y.find("domain_id: 0"), 12, "domain_id: 7");
  std::ofstream(config_) << y;
  d.signal(SIGHUP);
  EXPECT_TRUE(test::eventually(5, [&] { return log().find("SIGHUP: configuration") != std::string::npos; }))
      << log();
  EXPECT_NE(log().find("SIGHUP: logging.level"), std::string::npos) << log();
  EXPECT_NE(log().find("need a restart"), std::string::npos) << log();
  EXPECT_TRUE(d.running()) << "SIGHUP must not stop the daemon";
  d.signal(SIGTERM);
  ASSERT_TRUE(d.wait(5));
  EXPECT_EQ(d.exit_code(), 0);
}

TEST_F(Service, SighupAppliesDecimationLive) {
  // GIVEN a paced replay recording CrankState every 10th tooth WHEN the file is changed to every tooth and
  // the daemon gets SIGHUP THEN later CrankState rows are one tooth apart, earlier ones ten, without a
  // restart.
  const std::string rec = (dir_ / "rec").string();
  test::Process d(args({"--record", rec}), {}, (dir_ / "daemon.log").string());
  ASSERT_TRUE(test::eventually(10, [&] { return log().find("running") != std::string::npos; })) << log();
  ASSERT_TRUE(test::eventually(10, [&] { return csv_rows(rec + "/crank_state.csv") > 60; }))
      << log();  // > 20 steps of 10
  std::string y = test::slurp(config_);
  y.replace(y.find("  engine_id: 1"), 14, "  engine_id: 1\n  crank_state_decimation: 1");
  std::ofstream(config_) << y;
  d.signal(SIGHUP);
  ASSERT_TRUE(test::eventually(5, [&] {
    return log().find("SIGHUP: applied decimation") != std::string::npos;
  })) << log();
  const std::size_t at_reload = csv_rows(rec + "/crank_state.csv");
  ASSERT_TRUE(test::eventually(10, [&] { return csv_rows(rec + "/crank_state.csv") > at_reload + 300; }))
      << log();
  d.signal(SIGTERM);
  ASSERT_TRUE(d.wait(5));
  EXPECT_EQ(d.exit_code(), 0);
  // Tooth index is column 7 of crank_state.csv (t_ns, engine_id, seq, source_t_ns, ingest_t_ns, publish_t_ns,
  // validity, tooth, ...): count steps of 10 and of 1 (modulo the 58 teeth of a 60-2 wheel, 116 per cycle).
  std::ifstream in(rec + "/crank_state.csv");
  std::string line;
  std::getline(in, line);
  const auto header = line;
  std::size_t col = 0;
  {
    std::size_t pos = 0, k = 0;
    for (std::size_t q; (q = header.find(',', pos)) != std::string::npos || pos < header.size(); ++k) {
      const std::string name = header.substr(pos, q == std::string::npos ? std::string::npos : q - pos);
      if (name == "tooth") col = k;
      if (q == std::string::npos) break;
      pos = q + 1;
    }
  }
  ASSERT_GT(col, 0u) << header;
  int prev = -1, steps10 = 0, steps1 = 0, last_step = 0;
  while (std::getline(in, line)) {
    std::size_t pos = 0;
    for (std::size_t k = 0; k < col; ++k) pos = line.find(',', pos) + 1;
    const int tooth = std::atoi(line.c_str() + pos);
    if (prev >= 0 && tooth >= 0) {
      const int step = (tooth - prev + 116) % 116;
      if (step == 10) ++steps10;
      if (step == 1) ++steps1;
      last_step = step;
    }
    prev = tooth;
  }
  EXPECT_GT(steps10, 20) << "every 10th tooth before the reload";
  EXPECT_GT(steps1, 200) << "every tooth after the reload";
  EXPECT_EQ(last_step, 1) << "the last rows come after the reload";
}

TEST_F(Service, FastReplayCarriesLearnedStateLikeTheService) {
  // GIVEN fast replay with --state-dir WHEN run twice THEN the first run learns from the prior and saves, the
  // second starts from that state (friction law and the wheel's table) and gives different (learned) output;
  // --fresh-state starts from the prior again and reproduces the first run byte for byte.
  const auto run = [&](const std::string& rec, std::vector<std::string> extra, const std::string& log_name) {
    extra.insert(extra.end(), {"--replay", "fast", "--record", (dir_ / rec).string()});
    test::Process d(args(extra), {}, (dir_ / log_name).string());
    EXPECT_TRUE(d.wait(60));
    EXPECT_EQ(d.exit_code(), 0) << test::slurp((dir_ / log_name).string());
    return test::slurp((dir_ / log_name).string());
  };
  const std::string l1 = run("r1", {}, "1.log");
  EXPECT_NE(l1.find("learned state applied at start: nothing"), std::string::npos) << l1;
  EXPECT_NE(l1.find("learned state saved to"), std::string::npos) << l1;
  const std::string l2 = run("r2", {}, "2.log");
  EXPECT_NE(l2.find("learned state applied at start: friction law"), std::string::npos) << l2;
  EXPECT_NE(l2.find("58 tooth corrections"), std::string::npos) << l2;
  const std::string l3 = run("r3", {"--fresh-state"}, "3.log");
  EXPECT_NE(l3.find("--fresh-state"), std::string::npos) << l3;
  const std::string c1 = test::slurp((dir_ / "r1" / "engine_cycle.csv").string());
  ASSERT_GT(c1.size(), 1000u);
  EXPECT_FALSE(c1 == test::slurp((dir_ / "r2" / "engine_cycle.csv").string()))
      << "the learned state changed nothing";
  EXPECT_TRUE(c1 == test::slurp((dir_ / "r3" / "engine_cycle.csv").string()))
      << "--fresh-state is not a fresh start";
}

TEST_F(Service, LearnedStateSurvivesKill9) {
  // GIVEN a paced replay at 4x WHEN the learned state has been saved and the daemon is killed with SIGKILL
  // THEN the state file is complete and parses, and the next start applies it (friction law and the wheel's
  // 58 tooth corrections reach the angle chain).
  const std::string state = (dir_ / "state" / "learned_state.txt").string();
  {
    test::Process d(args({"--speed", "4"}), {}, (dir_ / "daemon.log").string());
    ASSERT_TRUE(test::eventually(30, [&] {
      std::string e;
      auto s = load_state(state, &e);
      return s && s->tooth_corrections_rad.size() == 58 && s->friction.has_value();
    })) << log();
    d.signal(SIGKILL);
    ASSERT_TRUE(d.wait(5));
    EXPECT_EQ(d.exit_code(), 128 + SIGKILL);
  }
  std::string err;
  const auto s = load_state(state, &err);
  ASSERT_TRUE(s.has_value()) << err;
  EXPECT_EQ(s->tooth_corrections_rad.size(), 58u);
  test::Process d2(args({}), {}, (dir_ / "daemon2.log").string());
  const std::string log2 = (dir_ / "daemon2.log").string();
  ASSERT_TRUE(test::eventually(10, [&] { return test::slurp(log2).find("running") != std::string::npos; }))
      << test::slurp(log2);
  // The line lists what the angle chain applied (a table the decoder refused would say REJECTED instead).
  EXPECT_NE(test::slurp(log2).find("learned state loaded from " + state + ": friction law"),
            std::string::npos)
      << test::slurp(log2);
  EXPECT_NE(test::slurp(log2).find(", 58 tooth corrections"), std::string::npos) << test::slurp(log2);
  EXPECT_EQ(test::slurp(log2).find("REJECTED"), std::string::npos) << test::slurp(log2);
  d2.signal(SIGTERM);
  EXPECT_TRUE(d2.wait(5));
}

TEST_F(Service, FastReplayOfDemoIsByteIdentical) {
  // Same input, same (empty) learned state: --fresh-state, or the second run would start from the first's
  // state.
  for (const char* run : {"a", "b"}) {
    test::Process d(args({"--replay", "fast", "--fresh-state", "--record", (dir_ / run).string()}), {},
                    (dir_ / (std::string(run) + ".log")).string());
    ASSERT_TRUE(d.wait(60));
    ASSERT_EQ(d.exit_code(), 0) << test::slurp((dir_ / (std::string(run) + ".log")).string());
  }
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "a")) {
    // A boolean, not EXPECT_EQ on the strings: gtest's diff of two multi-MB files needs O(n·m) memory.
    EXPECT_TRUE(test::slurp(e.path().string()) == test::slurp((dir_ / "b" / e.path().filename()).string()))
        << e.path().filename() << " differs";
    ++files;
  }
  EXPECT_EQ(files, 6);
}

/// Runs `argv` without real-time rights: RLIMIT_RTPRIO and RLIMIT_MEMLOCK 0 and, when we are root, as user
/// nobody without capabilities (root's CAP_SYS_NICE/CAP_IPC_LOCK would ignore the limits). argv[0] is copied
/// into `dir` first: user nobody may not be able to reach the build tree.
std::vector<std::string> unprivileged(std::vector<std::string> argv, const fs::path& dir) {
  const fs::path exe = dir / fs::path(argv[0]).filename();
  fs::copy_file(argv[0], exe, fs::copy_options::overwrite_existing);
  argv[0] = exe.string();
  std::vector<std::string> a{"/usr/bin/prlimit", "--rtprio=0:0", "--memlock=0:0"};
  if (::geteuid() == 0)
    a.insert(a.end(), {"/usr/bin/setpriv", "--reuid=65534", "--regid=65534", "--clear-groups",
                       "--inh-caps=-all", "--bounding-set=-all"});
  a.insert(a.end(), argv.begin(), argv.end());
  return a;
}

/// The demo configuration with its inputs copied into `dir` (readable by user nobody wherever the source tree
/// is), its `realtime:` lock_memory/require_rt lines replaced by `rt_keys`.
std::string portable_demo_config(const fs::path& dir, const std::string& rt_keys) {
  for (const char* f : {"data/demo/edges.csv", "data/demo/can.log", "config/demo.dbc"})
    fs::copy_file(fs::path(TORQUED_SOURCE_DIR) / f, dir / fs::path(f).filename(),
                  fs::copy_options::overwrite_existing);
  std::string y = test::slurp(std::string(TORQUED_SOURCE_DIR) + "/config/demo.yaml");
  auto replace = [&y](const std::string& from, const std::string& to) {
    const auto p = y.find(from);
    if (p != std::string::npos) y.replace(p, from.size(), to);
    return p != std::string::npos;
  };
  EXPECT_TRUE(replace("../data/demo/edges.csv", (dir / "edges.csv").string()));
  EXPECT_TRUE(replace("../data/demo/can.log", (dir / "can.log").string()));
  EXPECT_TRUE(replace("dbc: demo.dbc", "dbc: " + (dir / "demo.dbc").string()));
  EXPECT_TRUE(replace("  lock_memory: true\n  require_rt: false", rt_keys));
  const std::string path = (dir / "torqued.yaml").string();
  std::ofstream(path) << y;
  return path;
}

TEST_F(Service, RunsWithoutRealtimeRightsAndFlagsIt) {
  if (!fs::exists("/usr/bin/prlimit") || (::geteuid() == 0 && !fs::exists("/usr/bin/setpriv")))
    GTEST_SKIP() << "needs prlimit (and setpriv as root)";
  fs::permissions(dir_, fs::perms::all);  // user nobody writes its log, state and recording here
  const std::string cfg = portable_demo_config(dir_, "  require_rt: false\n  lock_memory: true");
  const std::string rec = (dir_ / "rec").string();
  test::Process d(unprivileged({TORQUED_EXE, "--config", cfg, "--no-dds", "--state-dir",
                                (dir_ / "state").string(), "--record", rec},
                               dir_),
                  {}, (dir_ / "daemon.log").string());
  ASSERT_TRUE(test::eventually(15, [&] { return log().find("running") != std::string::npos; })) << log();
  ASSERT_TRUE(test::eventually(10, [&] { return csv_rows(rec + "/daemon_status.csv") >= 2; }))  // two periods
      << log();
  d.signal(SIGTERM);
  ASSERT_TRUE(d.wait(5)) << log();
  EXPECT_EQ(d.exit_code(), 0) << log();
  // A clear warning naming what was refused and what it does instead.
  EXPECT_NE(log().find("pthread_setschedparam(SCHED_FIFO): Operation not permitted"), std::string::npos)
      << log();
  EXPECT_NE(log().find("running the pipelines with SCHED_OTHER"), std::string::npos) << log();
  EXPECT_NE(log().find("mlockall"), std::string::npos) << log();
  // DaemonStatus: RT_NOT_PERMITTED (1) and MLOCK_FAILED (2) set, health DEGRADED (1), and the estimates still
  // come.
  const std::string st = test::slurp(rec + "/daemon_status.csv");
  std::istringstream in(st);
  std::string header, row, last;
  std::getline(in, header);
  while (std::getline(in, row)) last = row;
  ASSERT_FALSE(last.empty()) << st;
  std::vector<std::string> names, vals;
  for (std::stringstream hs(header); std::getline(hs, row, ',');) names.push_back(row);
  for (std::stringstream ls(last); std::getline(ls, row, ',');) vals.push_back(row);
  auto col = [&](const std::string& n) {
    for (std::size_t i = 0; i < names.size() && i < vals.size(); ++i)
      if (names[i] == n) return std::stoll(vals[i]);
    ADD_FAILURE() << n << " not in " << header;
    return -1LL;
  };
  EXPECT_EQ(col("flags") & 3, 3) << last;
  EXPECT_EQ(col("health"), 1) << last;
  EXPECT_GT(col("cycles"), 10) << last;
  EXPECT_GT(test::slurp(rec + "/engine_cycle.csv").size(), 1000u);
}

TEST_F(Service, RefusesToStartWithoutRealtimeRightsWhenRequired) {
  if (!fs::exists("/usr/bin/prlimit") || (::geteuid() == 0 && !fs::exists("/usr/bin/setpriv")))
    GTEST_SKIP() << "needs prlimit (and setpriv as root)";
  fs::permissions(dir_, fs::perms::all);
  const std::string cfg = portable_demo_config(dir_, "  require_rt: true\n  lock_memory: false");
  test::Process d(
      unprivileged({TORQUED_EXE, "--config", cfg, "--no-dds", "--state-dir", (dir_ / "state").string()},
                   dir_),
      {}, (dir_ / "daemon.log").string());
  ASSERT_TRUE(d.wait(15)) << log();
  EXPECT_NE(d.exit_code(), 0) << log();
  EXPECT_NE(log().find("SCHED_FIFO): Operation not permitted (realtime.require_rt is set)"),
            std::string::npos)
      << log();
  EXPECT_EQ(log().find("running"), std::string::npos) << log();
}

/// Scheduling policy and priority of every thread of `pid`, by thread name.
std::vector<std::tuple<std::string, int, int>> thread_scheduling(pid_t pid) {
  std::vector<std::tuple<std::string, int, int>> out;
  for (const auto& t : fs::directory_iterator("/proc/" + std::to_string(pid) + "/task")) {
    const auto tid = static_cast<pid_t>(std::stol(t.path().filename().string()));
    std::string name = test::slurp((t.path() / "comm").string());
    while (!name.empty() && name.back() == '\n') name.pop_back();
    sched_param sp{};
    const int policy = ::sched_getscheduler(tid);
    ::sched_getparam(tid, &sp);
    out.emplace_back(name, policy, sp.sched_priority);
  }
  return out;
}

// A SCHED_OTHER Cyclone thread (timed events, receive, gc) that holds a writer lock can be preempted by
// ordinary load for a whole CFS slice while the SCHED_FIFO publisher waits on that lock. The daemon creates
// its participant with the publisher's scheduling so Cyclone's threads inherit it.
TEST_F(Service, CycloneThreadsInheritThePublisherScheduling) {
  {  // needs permission for SCHED_FIFO (root or CAP_SYS_NICE): checked on a throw-away thread of our own
    bool permitted = false;
    std::thread([&] {
      sched_param sp{};
      sp.sched_priority = 1;
      permitted = ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &sp) == 0;
    }).join();
    if (!permitted) GTEST_SKIP() << "SCHED_FIFO not permitted here";
  }
  // On DDS domain 9: the end-to-end and Fast DDS tests (domain 0) may run at the same time.
  const std::string cfg = test::write_demo_config(
      dir_.string(), "realtime:", "realtime:\n  publisher: {policy: fifo, priority: 42}");
  {
    std::string y = test::slurp(cfg);
    ASSERT_NE(y.find("domain_id: 0"), std::string::npos);
    y.replace(y.find("domain_id: 0"), 12, "domain_id: 9");
    std::ofstream(cfg) << y;
  }
  test::Process d(
      {TORQUED_EXE, "--config", cfg, "--state-dir", (dir_ / "state").string()},
      {std::string("CYCLONEDDS_URI=file://") + TORQUED_SOURCE_DIR + "/config/cyclonedds-loopback.xml"},
      (dir_ / "daemon.log").string());
  ASSERT_TRUE(test::eventually(15, [&] { return log().find("running") != std::string::npos; })) << log();
  // "running" is logged once the threads are started; each names itself right after it starts: wait for the
  // names.
  std::map<std::string, std::pair<int, int>> by_name;
  (void)test::eventually(10, [&] {
    by_name.clear();
    for (const auto& [name, policy, prio] : thread_scheduling(d.pid())) by_name[name] = {policy, prio};
    return by_name.count("torqued-pub") > 0 && by_name.count("torqued-angle") > 0;
  });
  d.signal(SIGTERM);
  EXPECT_TRUE(d.wait(5));
  std::string all;
  for (const auto& [name, pp] : by_name)
    all += name + ":" + std::to_string(pp.first) + "/" + std::to_string(pp.second) + " ";
  ASSERT_TRUE(by_name.count("torqued-pub")) << all;
  EXPECT_EQ(by_name["torqued-pub"], std::make_pair(SCHED_FIFO, 42)) << all;
  int cyclone = 0;
  for (const char* n : {"tev", "gc", "recv", "recvUC", "dq.builtins"}) {
    if (!by_name.count(n)) continue;
    ++cyclone;
    EXPECT_EQ(by_name[n], std::make_pair(SCHED_FIFO, 42)) << n << " in " << all;
  }
  EXPECT_GE(cyclone, 3) << "Cyclone's threads not found by name: " << all;
  // The main (supervisor) thread went back to what it had.
  EXPECT_EQ(by_name["torqued"].first, SCHED_OTHER) << all;
}

/// A field of /proc/<pid>/status in kB (-1 when not found).
long proc_status_kb(pid_t pid, const std::string& field) {
  std::istringstream in(test::slurp("/proc/" + std::to_string(pid) + "/status"));
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(field + ":", 0) == 0) return std::stol(line.substr(field.size() + 1));
  return -1;
}

TEST_F(Service, PacedWithDdsAndLockedMemoryStaysWithin64MiB) {
  // mlockall makes every mapped page resident, thread stacks included: 8 MiB each by default (108 MiB in all
  // before the stacks were sized). On DDS domain 11 (other tests use 0, 7, 8 and 9).
  const std::string cfg = test::write_demo_config(dir_.string(), "domain_id: 0", "domain_id: 11");
  ASSERT_NE(test::slurp(cfg).find("domain_id: 11"), std::string::npos);
  test::Process d(
      {TORQUED_EXE, "--config", cfg, "--state-dir", (dir_ / "state").string()},
      {std::string("CYCLONEDDS_URI=file://") + TORQUED_SOURCE_DIR + "/config/cyclonedds-loopback.xml"},
      (dir_ / "daemon.log").string());
  ASSERT_TRUE(test::eventually(15, [&] { return log().find("running") != std::string::npos; })) << log();
  std::this_thread::sleep_for(std::chrono::seconds(2));  // rings, recorder, DDS in use
  const long rss_kb = proc_status_kb(d.pid(), "VmRSS"), locked_kb = proc_status_kb(d.pid(), "VmLck");
  d.signal(SIGTERM);
  ASSERT_TRUE(d.wait(5)) << log();
  ASSERT_GT(rss_kb, 0);
  EXPECT_LE(rss_kb, 64 * 1024) << "VmRSS " << rss_kb << " kB (VmLck " << locked_kb << " kB)";
  if (locked_kb == 0) std::printf("note: mlockall refused here, RSS %ld kB without it\n", rss_kb);
  // The stopped line reports it too.
  const std::string l = log();
  const auto at = l.find("memory RSS ");
  ASSERT_NE(at, std::string::npos) << l;
  EXPECT_LE(std::stod(l.substr(at + 11)), 64.0) << l.substr(at, 60);
}

}  // namespace
}  // namespace torqued
