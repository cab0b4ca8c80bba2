// torque-latency: end-to-end latency of torqued, tooth edge -> sample received by a subscriber in another
// process (this one). Starts the daemon (paced replay) as a child process, subscribes to CrankState and
// EngineTorque, and measures receive time - ingest_t_ns (the edge's due time on CLOCK_REALTIME). Optionally
// loads the other core (stress-ng --cpu 1) and runs cyclictest and ddsperf alongside, printing their figures
// side by side with ours.
//   CYCLONEDDS_URI=file://$PWD/config/cyclonedds-loopback.xml \
//   torque-latency --torqued build/daemon/torqued --config config/demo.yaml --duration 15 --stress --cyclictest
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "dds/dds.h"
#include "qos.hpp"
#include "topics.hpp"

namespace {
using namespace torqued;

std::int64_t now_realtime() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

pid_t spawn(const std::vector<std::string>& argv, const char* log) {
  const pid_t p = fork();
  if (p == 0) {
    if (log) {
      FILE* f = std::fopen(log, "w");
      if (f) {
        dup2(fileno(f), 1);
        dup2(fileno(f), 2);
      }
    }
    std::vector<char*> a;
    for (const auto& s : argv) a.push_back(const_cast<char*>(s.c_str()));
    a.push_back(nullptr);
    execvp(a[0], a.data());
    _exit(127);
  }
  return p;
}

struct Stats {
  std::vector<double> us;
  void add(double v) { us.push_back(v); }
  [[nodiscard]] double pct(double p) const {
    if (us.empty()) return 0;
    std::vector<double> s = us;
    std::sort(s.begin(), s.end());
    const auto i = static_cast<std::size_t>(std::min<double>(static_cast<double>(s.size() - 1), p / 100.0 * static_cast<double>(s.size())));
    return s[i];
  }
  [[nodiscard]] double max() const { return us.empty() ? 0 : *std::max_element(us.begin(), us.end()); }
};

void histogram(const Stats& s, const char* title) {
  if (s.us.empty()) return;
  const double edges[] = {10, 20, 30, 50, 75, 100, 150, 200, 300, 500, 1000, 2000, 5000, 1e12};
  std::array<std::size_t, 14> n{};
  for (double v : s.us)
    for (std::size_t i = 0; i < 14; ++i)
      if (v < edges[i]) {
        ++n[i];
        break;
      }
  std::printf("%s histogram (us):\n", title);
  double lo = 0;
  for (std::size_t i = 0; i < 14; ++i) {
    const int bar = static_cast<int>(60.0 * static_cast<double>(n[i]) / static_cast<double>(s.us.size()) + 0.5);
    if (i < 13) std::printf("  %6.0f-%-6.0f %8zu %s\n", lo, edges[i], n[i], std::string(static_cast<std::size_t>(bar), '#').c_str());
    else std::printf("  %6.0f-       %8zu %s\n", lo, n[i], std::string(static_cast<std::size_t>(bar), '#').c_str());
    lo = edges[i];
  }
}

/// cyclictest -q -h N prints "# Min Latencies", "# Avg", "# Max" and a histogram; we read the histogram.
void cyclictest_summary(const char* log, double& p50, double& p99, double& p999, double& max) {
  FILE* f = std::fopen(log, "r");
  if (!f) return;
  char line[512];
  std::vector<std::pair<int, long>> hist;
  while (std::fgets(line, sizeof line, f)) {
    if (line[0] == '#') {
      if (std::strncmp(line, "# Max Latencies:", 16) == 0) max = std::atof(line + 16);
      continue;
    }
    int us = 0;
    long c = 0;
    if (std::sscanf(line, "%d %ld", &us, &c) == 2) hist.emplace_back(us, c);
  }
  std::fclose(f);
  long total = 0;
  for (auto& h : hist) total += h.second;
  long acc = 0;
  p50 = p99 = p999 = -1;
  for (auto& [us, c] : hist) {
    acc += c;
    if (p50 < 0 && acc >= total / 2) p50 = us;
    if (p99 < 0 && acc >= total - total / 100) p99 = us;
    if (p999 < 0 && acc >= total - total / 1000) p999 = us;
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string torqued = "torqued", config, ddsperf_log = "/tmp/torque-latency-ddsperf.log";
  double duration_s = 15, speed = 1.0;
  bool stress = false, cyclic = false, ddsperf = false;
  CLI::App app{"torque-latency: tooth edge -> subscriber latency of torqued in paced replay (p50/p99/p99.9/max + "
               "histogram), optionally with stress-ng --cpu 1, cyclictest and ddsperf alongside"};
  app.add_option("--torqued", torqued, "torqued executable");
  app.add_option("--config", config, "daemon configuration (paced replay)")->required();
  app.add_option("--duration", duration_s, "measurement time (s)");
  app.add_option("--speed", speed, "replay speed factor");
  app.add_flag("--stress", stress, "load one core with stress-ng --cpu 1 during the run");
  app.add_flag("--cyclictest", cyclic, "run cyclictest (rt-tests) alongside and print its percentiles");
  app.add_flag("--ddsperf", ddsperf, "run Cyclone's ddsperf ping/pong alongside (raw output in a log)");
  CLI11_PARSE(app, argc, argv);

  dds::DdsSettings s;
  const dds_entity_t pp = dds_create_participant(s.domain_id, nullptr, nullptr);
  if (pp < 0) {
    std::fprintf(stderr, "dds_create_participant failed\n");
    return 1;
  }
  auto reader = [&](dds::Topic t) {
    const dds_entity_t topic = dds::create_topic(pp, s, t);
    dds_qos_t* q = dds::make_qos(s.qos[static_cast<std::size_t>(t)]);
    dds_qset_deadline(q, DDS_INFINITY);
    dds_qset_liveliness(q, DDS_LIVELINESS_AUTOMATIC, DDS_INFINITY);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 256);
    const dds_entity_t r = dds_create_reader(pp, topic, q, nullptr);
    dds_delete_qos(q);
    return r;
  };
  const dds_entity_t crank = reader(dds::Topic::kCrankState), engine = reader(dds::Topic::kEngineTorque);
  const dds_entity_t ws = dds_create_waitset(pp);
  dds_waitset_attach(ws, dds_create_readcondition(crank, DDS_ANY_STATE), 1);
  dds_waitset_attach(ws, dds_create_readcondition(engine, DDS_ANY_STATE), 2);

  std::vector<pid_t> helpers;
  const std::string dur = std::to_string(static_cast<int>(duration_s + 3));
  if (stress) helpers.push_back(spawn({"stress-ng", "--cpu", "1", "--timeout", dur + "s", "--quiet"}, "/dev/null"));
  if (cyclic)
    helpers.push_back(spawn({"cyclictest", "-m", "-q", "-p", "80", "-i", "1000", "-h", "2000", "-D", dur}, "/tmp/torque-latency-cyclictest.log"));
  if (ddsperf) {
    helpers.push_back(spawn({"ddsperf", "-D", dur, "pong"}, "/dev/null"));
    helpers.push_back(spawn({"ddsperf", "-D", dur, "ping"}, ddsperf_log.c_str()));
  }
  const pid_t daemon = spawn({torqued, "--config", config, "--speed", std::to_string(speed), "--wait-subscribers", "1",
                              "--state-dir", "/tmp/torque-latency-state"},
                             "/tmp/torque-latency-torqued.log");

  Stats crank_us, engine_us;
  std::array<torque_CrankState, 64> cb{};
  std::array<torque_EngineTorque, 64> eb{};
  std::array<void*, 64> cp{}, ep{};
  std::array<dds_sample_info_t, 64> info{};
  for (std::size_t i = 0; i < 64; ++i) cp[i] = &cb[i], ep[i] = &eb[i];
  const auto t_end = std::chrono::steady_clock::now() + std::chrono::duration<double>(duration_s + 1.5);
  while (std::chrono::steady_clock::now() < t_end) {
    dds_waitset_wait(ws, nullptr, 0, DDS_MSECS(100));
    const std::int64_t now = now_realtime();
    int n = dds_take(crank, cp.data(), info.data(), 64, 64);
    for (int i = 0; i < n; ++i)
      if (info[static_cast<std::size_t>(i)].valid_data && cb[static_cast<std::size_t>(i)].ingest_t_ns > 0)
        crank_us.add(static_cast<double>(now - cb[static_cast<std::size_t>(i)].ingest_t_ns) * 1e-3);
    n = dds_take(engine, ep.data(), info.data(), 64, 64);
    for (int i = 0; i < n; ++i)
      if (info[static_cast<std::size_t>(i)].valid_data && eb[static_cast<std::size_t>(i)].ingest_t_ns > 0)
        engine_us.add(static_cast<double>(now - eb[static_cast<std::size_t>(i)].ingest_t_ns) * 1e-3);
  }
  kill(daemon, SIGTERM);
  int st = 0;
  waitpid(daemon, &st, 0);
  for (pid_t h : helpers) {
    kill(h, SIGINT);
    waitpid(h, &st, 0);
  }
  dds_delete(pp);

  std::printf("torque-latency: %.0f s paced replay at %.1fx%s\n", duration_s, speed, stress ? ", stress-ng --cpu 1" : "");
  std::printf("%-34s %8s %8s %8s %8s %8s\n", "path", "n", "p50_us", "p99_us", "p99.9_us", "max_us");
  std::printf("%-34s %8zu %8.1f %8.1f %8.1f %8.1f\n", "tooth edge -> CrankState (subscr.)", crank_us.us.size(),
              crank_us.pct(50), crank_us.pct(99), crank_us.pct(99.9), crank_us.max());
  std::printf("%-34s %8zu %8.1f %8.1f %8.1f %8.1f\n", "tooth edge -> EngineTorque (subscr.)", engine_us.us.size(),
              engine_us.pct(50), engine_us.pct(99), engine_us.pct(99.9), engine_us.max());
  if (cyclic) {
    double p50 = 0, p99 = 0, p999 = 0, mx = 0;
    cyclictest_summary("/tmp/torque-latency-cyclictest.log", p50, p99, p999, mx);
    std::printf("%-34s %8s %8.1f %8.1f %8.1f %8.1f\n", "cyclictest (same run)", "-", p50, p99, p999, mx);
  }
  if (ddsperf) std::printf("ddsperf ping/pong output: %s\n", ddsperf_log.c_str());
  histogram(crank_us, "tooth edge -> CrankState");
  return crank_us.us.empty() ? 1 : 0;
}
