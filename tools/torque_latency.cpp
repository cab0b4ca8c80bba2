// torque-latency: end-to-end latency of torqued, tooth edge -> sample received by a subscriber in another
// process (this one). Starts the daemon (paced replay) as a child process, subscribes to CrankState and
// EngineTorque, and measures receive time - ingest_t_ns (the edge's due time on CLOCK_REALTIME). Optionally
// loads the other core (stress-ng --cpu 1) and runs cyclictest and ddsperf alongside, printing their figures
// side by side with ours, and the ratio of ours to those floors.
// It subscribes on the daemon's own DDS domain and topic prefix (from --config) and keeps only the samples of
// its engine_id; its logs and the daemon's state directory are in a private temporary directory (mkdtemp in
// $TMPDIR or /tmp, removed at the end unless --keep-logs or the run failed), so two runs or another daemon on
// the machine do not mix their figures. The daemon writes its per-sample stamps there (--stage-trace), from
// which the tail's stages are printed.
//   CYCLONEDDS_URI=file://$PWD/config/cyclonedds-loopback.xml torque-latency --torqued build/service/torqued
//   --config config/demo.yaml --duration 15 --stress --cyclictest [--plot latency.png]
// It says which path the samples took: shared memory (iceoryx: CYCLONEDDS_URI with SharedMemory, RouDi
// running, QoS iceoryx carries) or the network path, for this subscriber's readers and the daemon's writers,
// and ends with one `summary:` line per run; tools/scripts/latency_shm_vs_net.sh runs it both ways and prints
// them side by side.
#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "cli_exit.hpp"
#include "config_loader.hpp"
#include "dds/dds.h"
#include "dds/ddsc/dds_loan_api.h"
#include "dds_from_config.hpp"
#include "latency_stages.hpp"
#include "qos.hpp"
#include "share_dir.hpp"
#include "topics.hpp"

namespace {
using namespace torqued;

std::int64_t now_realtime() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// Starts argv[0] (PATH searched) with stdout/stderr into `log`. When `exec_errno_fd` >= 0 (the write end of
/// a close-on-exec pipe), a failed exec writes its errno there, so the parent can tell "could not start" from
/// "started".
pid_t spawn(const std::vector<std::string>& argv, const char* log, const std::vector<std::string>& env = {},
            int exec_errno_fd = -1) {
  const pid_t p = fork();
  if (p == 0) {
    for (const auto& e : env) putenv(const_cast<char*>(e.c_str()));  // the child's copy: ours stays unchanged
    // Children (daemon, stress-ng, ...) pick their own scheduling and CPUs, not this subscriber's.
    sched_param sp{};
    sched_setscheduler(0, SCHED_OTHER, &sp);
    cpu_set_t all;
    CPU_ZERO(&all);
    for (int c = 0; c < CPU_SETSIZE; ++c) CPU_SET(c, &all);
    sched_setaffinity(0, sizeof all, &all);
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
    if (exec_errno_fd >= 0) {
      const int err = errno;
      (void)!write(exec_errno_fd, &err, sizeof err);
    }
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
    const auto i = static_cast<std::size_t>(
        std::min<double>(static_cast<double>(s.size() - 1), p / 100.0 * static_cast<double>(s.size())));
    return s[i];
  }
  [[nodiscard]] double max() const { return us.empty() ? 0 : *std::max_element(us.begin(), us.end()); }
};

/// One topic's samples, time-stamped on arrival: edge -> received, split at the daemon's publish stamp.
template <class Sample>
struct TopicLatency {
  dds_entity_t reader = 0;
  std::uint16_t engine_id = 0;  ///< only this engine's samples (others on the domain are counted, not used)
  std::size_t other_engines = 0;
  Stats total, in_daemon, dds;
  std::vector<std::array<double, 3>> split;  ///< per stamped sample: total, in the daemon, DDS (us), aligned
  std::vector<std::uint64_t> split_seq;      ///< ... and its seq (joins the daemon's --stage-trace)
  std::array<Sample, 64> buf{};
  std::array<void*, 64> ptr{};
  std::array<dds_sample_info_t, 64> info{};
  TopicLatency() {
    for (std::size_t i = 0; i < buf.size(); ++i) ptr[i] = &buf[i];
    for (Stats* st : {&total, &in_daemon, &dds}) st->us.reserve(1 << 18);
    split.reserve(1 << 18);
    split_seq.reserve(1 << 18);
  }
  void take(std::int64_t now) {
    const int n = dds_take(reader, ptr.data(), info.data(), buf.size(), buf.size());
    for (int i = 0; i < n; ++i) {
      const Sample& v = buf[static_cast<std::size_t>(i)];
      if (!info[static_cast<std::size_t>(i)].valid_data || v.ingest_t_ns <= 0) continue;
      if (v.engine_id != engine_id) {
        ++other_engines;
        continue;
      }
      total.add(static_cast<double>(now - v.ingest_t_ns) * 1e-3);
      if (v.publish_t_ns > 0) {
        in_daemon.add(static_cast<double>(v.publish_t_ns - v.ingest_t_ns) * 1e-3);
        dds.add(static_cast<double>(now - v.publish_t_ns) * 1e-3);
        split.push_back({total.us.back(), in_daemon.us.back(), dds.us.back()});
        split_seq.push_back(v.seq);
      }
    }
  }
};

/// Which stage owns the tail: over the slowest 0.1 % of the stamped samples (total ≥ its p99.9), the mean
/// time spent in the daemon (edge -> dds_write) and in DDS (dds_write -> received); the larger one owns it.
void print_tail_owner(const char* topic, const std::vector<std::array<double, 3>>& split) {
  if (split.size() < 100) return;
  std::vector<double> tot;
  tot.reserve(split.size());
  for (const auto& v : split) tot.push_back(v[0]);
  std::sort(tot.begin(), tot.end());
  const double cut = tot[static_cast<std::size_t>(0.999 * static_cast<double>(tot.size() - 1))];
  double d = 0, n = 0, k = 0;
  for (const auto& v : split)
    if (v[0] >= cut) {
      d += v[1];
      n += v[2];
      ++k;
    }
  std::printf(
      "tail of %s: the %.0f slowest samples (>= %.1f us, p99.9) spent on average %.1f us edge -> dds_write "
      "and %.1f us dds_write -> received: owned by %s\n",
      topic, k, cut, d / k, n / k, d >= n ? "the daemon (edge -> dds_write)" : "DDS (dds_write -> received)");
}

/// Takes CrankState/EngineTorque samples and time-stamps them on arrival (from a listener or a waitset).
struct Receiver {
  TopicLatency<torque_CrankState> crank;
  TopicLatency<torque_EngineTorque> engine;
  void take(dds_entity_t r, std::int64_t now) {
    if (r == crank.reader)
      crank.take(now);
    else if (r == engine.reader)
      engine.take(now);
  }
  void take_all() {
    const std::int64_t now = now_realtime();
    crank.take(now);
    engine.take(now);
  }
  static void on_data(dds_entity_t r, void* arg) { static_cast<Receiver*>(arg)->take(r, now_realtime()); }
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
    const int bar =
        static_cast<int>(std::lround(60.0 * static_cast<double>(n[i]) / static_cast<double>(s.us.size())));
    if (i < 13)
      std::printf("  %6.0f-%-6.0f %8zu %s\n", lo, edges[i], n[i],
                  std::string(static_cast<std::size_t>(bar), '#').c_str());
    else
      std::printf("  %6.0f-       %8zu %s\n", lo, n[i],
                  std::string(static_cast<std::size_t>(bar), '#').c_str());
    lo = edges[i];
  }
}

/// cyclictest -q -h N prints "# Min Latencies", "# Avg", "# Max" and a histogram; we read the histogram.
/// What cyclictest -q -h N writes: its histogram lines "<us> <count>" (1 us bins, empty bins left out), its
/// max and the number of samples beyond the histogram.
struct CyclictestLog {
  std::vector<std::pair<int, long>> hist;
  double max_us = 0;
  long overflows = 0;
};

CyclictestLog read_cyclictest(const char* log) {
  CyclictestLog r;
  FILE* f = std::fopen(log, "r");
  if (!f) return r;
  char line[512];
  while (std::fgets(line, sizeof line, f)) {
    if (line[0] == '#') {
      if (std::strncmp(line, "# Max Latencies:", 16) == 0) r.max_us = std::atof(line + 16);
      if (std::strncmp(line, "# Histogram Overflows:", 22) == 0) r.overflows += std::atol(line + 22);
      continue;
    }
    int us = 0;
    long c = 0;
    if (std::sscanf(line, "%d %ld", &us, &c) == 2 && c > 0) r.hist.emplace_back(us, c);
  }
  std::fclose(f);
  return r;
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// The plot's input (series,us,count): every received sample, and cyclictest's histogram.
bool write_plot_data(const std::string& path, const std::vector<std::pair<const char*, const Stats*>>& series,
                     const std::vector<std::pair<int, long>>& cyclic) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) return false;
  std::fprintf(f, "series,us,count\n");
  for (const auto& [name, st] : series)
    for (double v : st->us) std::fprintf(f, "%s,%.1f,1\n", name, v);
  for (const auto& [us, c] : cyclic) std::fprintf(f, "cyclictest,%d,%ld\n", us, c);
  return std::fclose(f) == 0;
}

/// late_1ms: wake-ups 1 ms or more late (histogram bins >= 1000 us plus its overflows), to compare with the
/// daemon's time-thread overruns (a 1 kHz tick missed).
void cyclictest_summary(const CyclictestLog& log, double& p50, double& p99, double& p999, double& max,
                        long& late_1ms) {
  max = log.max_us;
  late_1ms += log.overflows;
  long total = 0;
  for (const auto& h : log.hist) {
    total += h.second;
    if (h.first >= 1000) late_1ms += h.second;
  }
  long acc = 0;
  p50 = p99 = p999 = -1;
  for (const auto& [us, c] : log.hist) {
    acc += c;
    if (p50 < 0 && acc >= total / 2) p50 = us;
    if (p99 < 0 && acc >= total - total / 100) p99 = us;
    if (p999 < 0 && acc >= total - total / 1000) p999 = us;
  }
}

/// ddsperf ping prints one line per second: "... mean X us min X us 50% X us 90% X us 99% X us max X us cnt
/// N"; returns the medians of the per-second p50 and p99 round trips (the first second, discovery, is
/// skipped).
void ddsperf_summary(const char* log, double& p50, double& p99, std::size_t& n) {
  FILE* f = std::fopen(log, "r");
  if (!f) return;
  std::vector<double> a, b;
  char line[1024];
  while (std::fgets(line, sizeof line, f)) {
    const char* q50 = std::strstr(line, " 50% ");
    const char* q99 = std::strstr(line, " 99% ");
    if (q50 && q99) {
      a.push_back(std::atof(q50 + 5));
      b.push_back(std::atof(q99 + 5));
    }
  }
  std::fclose(f);
  if (a.size() > 1) {
    a.erase(a.begin());
    b.erase(b.begin());
  }
  n = a.size();
  if (n == 0) return;
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  p50 = a[n / 2];
  p99 = b[n / 2];
}

/// The floors measured in the same run and our ratio to them: cyclictest p50 (one timer wake-up of a
/// SCHED_FIFO thread) + ddsperf's one-way p50 (one DDS hop into an idle process) against edge -> received
/// p50; cyclictest's p99.9 against ours (target: 2x). Printed only for the floors that were measured.
void print_floors(const Stats& total, const Stats& daemon, const Stats& dds, double cyc_p50, double cyc_p999,
                  double dds_one_way) {
  if (total.us.empty() || (cyc_p50 < 0 && dds_one_way < 0)) return;
  const double p50 = total.pct(50), p999 = total.pct(99.9);
  if (cyc_p50 >= 0)
    std::printf("vs floor: edge -> dds_write p50 %.1f us = cyclictest p50 %+.1f us; ", daemon.pct(50),
                daemon.pct(50) - cyc_p50);
  if (dds_one_way >= 0)
    std::printf("dds_write -> received p50 %.1f us = ddsperf one-way %+.1f us", dds.pct(50),
                dds.pct(50) - dds_one_way);
  std::printf("\n");
  if (cyc_p50 >= 0 && dds_one_way >= 0) {
    const double floor = cyc_p50 + dds_one_way;
    std::printf(
        "vs floor: edge -> received p50 %.1f us, floor (cyclictest p50 + ddsperf one-way) %.1f us: "
        "%.2fx, %+.1f us (targets: <= floor + 15 us = %.1f us, <= 50 us)\n",
        p50, floor, p50 / floor, p50 - floor, floor + 15.0);
  }
  if (cyc_p999 > 0)
    std::printf("vs floor: edge -> received p99.9 %.1f us, cyclictest p99.9 %.1f us: %.2fx (target <= 2x)\n",
                p999, cyc_p999, p999 / cyc_p999);
}

void remove_dir(const std::string& dir, bool keep) {
  if (keep) {
    std::printf("logs kept in %s\n", dir.c_str());
    return;
  }
  const std::string cmd = "rm -rf " + shell_quote(dir);
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "torque-latency: could not remove %s\n", dir.c_str());
}

/// What the command line asks for (see add_options for each one's meaning).
struct Options {
  std::string torqued, config;  ///< torqued: "" = next to this executable, else from PATH (default_torqued)
  bool keep_logs = false;
  std::vector<std::string> daemon_env;
  std::string plot, plot_script = torqued::tools::share_path("plot_latency.py"), title;
  double duration_s = 15, speed = 1.0;
  bool stress = false, cyclic = false, ddsperf = false, use_waitset = false;
  int sub_prio = 70, ddsperf_rate_hz = 500, sub_cpu = -1, stress_cpu = -1, cyclic_interval_us = 1000;
};

void add_options(CLI::App& app, Options& o) {
  app.add_option("--torqued", o.torqued,
                 "torqued executable (default: the one next to this tool: PREFIX/bin/torqued installed, "
                 "../service/torqued in the build tree; else torqued from PATH)");
  app.add_option("--config", o.config, "daemon configuration (paced replay)")->required();
  app.add_option("--duration", o.duration_s, "measurement time (s)");
  app.add_option("--speed", o.speed, "replay speed factor");
  app.add_flag("--stress", o.stress, "load one core with stress-ng --cpu 1 during the run");
  app.add_flag("--cyclictest", o.cyclic, "run cyclictest (rt-tests) alongside and print its percentiles");
  app.add_flag("--ddsperf", o.ddsperf,
               "run Cyclone's ddsperf ping/pong alongside and print its one-way latency");
  app.add_option("--ddsperf-rate", o.ddsperf_rate_hz,
                 "ddsperf ping rate (Hz), comparable to the sample rate");
  app.add_flag("--waitset", o.use_waitset,
               "take samples from a waitset in the main thread instead of a listener (one more wake-up)");
  app.add_option("--subscriber-priority", o.sub_prio,
                 "SCHED_FIFO priority of this subscriber process and its DDS threads (0: SCHED_OTHER)")
      ->check(CLI::Range(0, 99));
  app.add_option(
      "--subscriber-cpu", o.sub_cpu,
      "pin this subscriber (all its DDS threads) to this CPU; cyclictest and ddsperf (ping and pong) "
      "then run on it too, so their floors are the same CPU's (-1: not pinned)");
  app.add_option(
         "--cyclictest-interval", o.cyclic_interval_us,
         "cyclictest's period (us). It skips the periods a stall swallows (one late sample per stall), "
         "while every tooth edge delayed by a stall is a late sample of ours: at the CrankState rate "
         "(e.g. 3333 at 3000 rpm with crank_state_decimation 10) both p99.9 see stalls equally often")
      ->check(CLI::Range(50, 1000000));
  app.add_option("--stress-cpu", o.stress_cpu, "pin stress-ng to this CPU (-1: not pinned)");
  app.add_option(
      "--plot", o.plot,
      "write a PNG: the latency distributions (tail on a log scale, p50 region as a histogram) next "
      "to cyclictest's, with the targets");
  app.add_option(
      "--plot-script", o.plot_script,
      "plot script, run with /usr/bin/python3 (default: in PREFIX/share/torqued next to PREFIX/bin)");
  app.add_option("--title", o.title, "plot title");
  app.add_option(
         "--daemon-env", o.daemon_env,
         "NAME=VALUE set in the daemon's environment only (repeatable); e.g. TORQUED_DDS_ROLE=daemon with "
         "config/security/cyclonedds-secure-loopback.xml, to measure DDS Security (docs/security.md)")
      ->check(
          [](const std::string& v) { return v.find('=') == std::string::npos ? "expected NAME=VALUE" : ""; });
  app.add_flag("--keep-logs", o.keep_logs,
               "keep the temporary directory with the daemon's and helpers' logs");
  app.footer(
      "Exit status: 0 done; 1 no latency sample measured, the daemon could not be started or DDS failed; 2 "
      "command-line error (unknown option, bad value, file that does not exist).");
}

/// The private temporary directory: logs of the daemon and the helpers, the daemon's state directory.
struct Paths {
  std::string dir, daemon_log, cyclic_log, ddsperf_log, state_dir, stage_trace;
};

/// The subscriber's own CPU and scheduling: Cyclone's receive threads inherit the policy of the thread that
/// creates the participant, so a SCHED_FIFO main thread makes the whole receive path real-time (as a real
/// supervisory controller would configure it). Refused (not root, no CAP_SYS_NICE): measured with
/// SCHED_OTHER, said so.
void pin_and_prioritise(const Options& o) {
  if (o.sub_cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(o.sub_cpu, &set);
    if (sched_setaffinity(0, sizeof set, &set) != 0)
      std::fprintf(stderr, "torque-latency: CPU %d refused (%s): subscriber not pinned\n", o.sub_cpu,
                   std::strerror(errno));
  }
  if (o.sub_prio > 0) {
    sched_param sp{};
    sp.sched_priority = o.sub_prio;
    if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0)
      std::fprintf(stderr, "torque-latency: SCHED_FIFO %d refused (%s): subscriber runs SCHED_OTHER\n",
                   o.sub_prio, std::strerror(errno));
    else
      mlockall(MCL_CURRENT | MCL_FUTURE);
  }
}

/// The two readers on participant `pp`. Listener mode (default): samples are taken and time-stamped in
/// Cyclone's receive thread, no extra wake-up. --waitset: a waitset in this thread (one more wake-up, what a
/// simple polling subscriber sees); returns it (0 in listener mode). Whether both readers are on shared
/// memory goes to `shm`.
dds_entity_t open_readers(const Options& o, const dds::DdsSettings& s, dds_entity_t pp, Receiver& rx,
                          bool& shm) {
  dds_listener_t* lis = nullptr;
  if (!o.use_waitset) {
    lis = dds_create_listener(&rx);
    dds_lset_data_available(lis, &Receiver::on_data);
  }
  auto reader = [&](dds::Topic t) {
    const dds_entity_t topic = dds::create_topic(pp, s, t);
    dds_qos_t* q = dds::make_qos(s.qos[static_cast<std::size_t>(t)]);
    dds_qset_deadline(q, DDS_INFINITY);
    dds_qset_liveliness(q, DDS_LIVELINESS_AUTOMATIC, DDS_INFINITY);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 256);
    const dds_entity_t r = dds_create_reader(pp, topic, q, lis);
    dds_delete_qos(q);
    return r;
  };
  rx.crank.engine_id = rx.engine.engine_id = s.engine_id;
  rx.crank.reader = reader(dds::Topic::kCrankState);
  rx.engine.reader = reader(dds::Topic::kEngineTorque);
  if (lis) dds_delete_listener(lis);
  shm = dds_is_shared_memory_available(rx.crank.reader) && dds_is_shared_memory_available(rx.engine.reader);
  if (!o.use_waitset) return 0;
  const dds_entity_t ws = dds_create_waitset(pp);
  dds_waitset_attach(ws, dds_create_readcondition(rx.crank.reader, DDS_ANY_STATE), 1);
  dds_waitset_attach(ws, dds_create_readcondition(rx.engine.reader, DDS_ANY_STATE), 2);
  return ws;
}

/// stress-ng, cyclictest and ddsperf as asked, each for the run's length plus 3 s.
std::vector<pid_t> start_helpers(const Options& o, const dds::DdsSettings& s, const Paths& p) {
  std::vector<pid_t> helpers;
  const std::string dur = std::to_string(static_cast<int>(o.duration_s + 3));
  if (o.stress) {
    std::vector<std::string> a{"stress-ng", "--cpu", "1", "--timeout", dur + "s", "--quiet"};
    if (o.stress_cpu >= 0) a.insert(a.end(), {"--taskset", std::to_string(o.stress_cpu)});
    helpers.push_back(spawn(a, "/dev/null"));
  }
  if (o.cyclic) {
    std::vector<std::string> a{
        "cyclictest", "-m",   "-q", "-p", "80", "-i", std::to_string(o.cyclic_interval_us),
        "-h",         "2000", "-D", dur};
    if (o.sub_cpu >= 0) a.insert(a.end(), {"-a", std::to_string(o.sub_cpu)});
    helpers.push_back(spawn(a, p.cyclic_log.c_str()));
  }
  if (o.ddsperf) {
    // Same scheduling as our subscriber, and pinged at a rate like the tooth rate (a CPU woken from idle for
    // each sample is much slower than back-to-back ping-pong, so the unpaced figure is not a fair floor).
    const std::string prio = std::to_string(o.sub_prio > 0 ? o.sub_prio : 1);
    const std::string rate = std::to_string(o.ddsperf_rate_hz) + "Hz";
    std::vector<std::string> pre;
    if (o.sub_cpu >= 0) pre.insert(pre.end(), {"taskset", "-c", std::to_string(o.sub_cpu)});
    if (o.sub_prio > 0) pre.insert(pre.end(), {"chrt", "-f", prio});
    auto with_pre = [&pre](std::vector<std::string> a) {
      a.insert(a.begin(), pre.begin(), pre.end());
      return a;
    };
    // On the daemon's domain: the same network path (two runs with --ddsperf on one domain share their
    // pongs).
    const std::string domain = std::to_string(s.domain_id);
    helpers.push_back(spawn(with_pre({"ddsperf", "-i", domain, "-D", dur, "pong"}), "/dev/null"));
    helpers.push_back(
        spawn(with_pre({"ddsperf", "-i", domain, "-D", dur, "ping", rate}), p.ddsperf_log.c_str()));
  }
  return helpers;
}

/// The daemon when --torqued is not given: next to this executable (installed: PREFIX/bin/torqued), then
/// the build tree's (BUILD/tools/torque-latency -> BUILD/service/torqued), else "torqued" from PATH.
std::string default_torqued() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    for (const std::filesystem::path& c :
         {exe.parent_path() / "torqued", exe.parent_path().parent_path() / "service" / "torqued"})
      if (access(c.c_str(), X_OK) == 0) return c.string();
  }
  return "torqued";
}

/// How the daemon ended, when it ended before the measurement did: exec failed, or it exited early. Status 0
/// is the end of its recording (replay.exit_when_done): the samples up to there are measured, not a failure.
struct DaemonEnd {
  bool early = false;
  int exec_errno = 0;  ///< exec failed with this errno (0: it started)
  int status = 0;      ///< waitpid status when it exited early
  double after_s = 0;  ///< when it ended, seconds after the start of the measurement
  [[nodiscard]] bool failed() const {
    return early && (exec_errno != 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0);
  }
};

/// Reads the exec-error pipe (its write end already closed here): an errno if the exec failed, else EOF.
int exec_error(int fd) {
  int err = 0;
  ssize_t n = 0;
  do n = read(fd, &err, sizeof err);
  while (n < 0 && errno == EINTR);
  close(fd);
  return n == static_cast<ssize_t>(sizeof err) ? err : 0;
}

/// Says that the daemon could not be started or ended before the run, naming it and its log.
void print_daemon_end(const std::string& torqued, const Paths& p, const DaemonEnd& d) {
  if (d.exec_errno != 0)
    std::fprintf(stderr, "torque-latency: cannot start the daemon '%s': %s (give --torqued PATH); log %s\n",
                 torqued.c_str(), std::strerror(d.exec_errno), p.daemon_log.c_str());
  else if (WIFEXITED(d.status))
    std::fprintf(stderr,
                 "torque-latency: the daemon '%s' exited with status %d before the run ended; see its "
                 "log %s\n",
                 torqued.c_str(), WEXITSTATUS(d.status), p.daemon_log.c_str());
  else
    std::fprintf(stderr,
                 "torque-latency: the daemon '%s' was killed by signal %d before the run ended; see "
                 "its log %s\n",
                 torqued.c_str(), WTERMSIG(d.status), p.daemon_log.c_str());
}

/// Receives for the run's length plus 1.5 s, then stops the listener, the daemon and the helpers. A daemon
/// that ends on its own before that is an early end (returned; the run stops there).
DaemonEnd measure(const Options& o, Receiver& rx, dds_entity_t ws, pid_t daemon,
                  const std::vector<pid_t>& helpers) {
  DaemonEnd end;
  const auto t0 = std::chrono::steady_clock::now();
  const auto t_end = t0 + std::chrono::duration<double>(o.duration_s + 1.5);
  while (std::chrono::steady_clock::now() < t_end) {
    if (waitpid(daemon, &end.status, WNOHANG) == daemon) {
      end.early = true;
      end.after_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      break;
    }
    if (o.use_waitset) {
      dds_waitset_wait(ws, nullptr, 0, DDS_MSECS(100));
      rx.take_all();
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  if (!o.use_waitset) {  // stop the listener before reading its statistics
    dds_set_listener(rx.crank.reader, nullptr);
    dds_set_listener(rx.engine.reader, nullptr);
  }
  int st = 0;
  if (!end.early) {
    kill(daemon, SIGTERM);
    waitpid(daemon, &st, 0);
  }
  for (pid_t h : helpers) {
    kill(h, SIGINT);
    waitpid(h, &st, 0);
  }
  return end;
}

void print_paths(const Options& o, const dds::DdsSettings& s, const Paths& p, const Receiver& rx,
                 bool sub_shm) {
  std::printf("torque-latency: %.0f s paced replay at %.1fx%s; DDS domain %u, topics %s/*, engine_id %u\n",
              o.duration_s, o.speed, o.stress ? ", stress-ng --cpu 1" : "", s.domain_id,
              s.topic_prefix.c_str(), static_cast<unsigned>(s.engine_id));
  if (rx.crank.other_engines + rx.engine.other_engines > 0)
    std::printf("ignored %zu samples of other engine_ids on this domain and prefix\n",
                rx.crank.other_engines + rx.engine.other_engines);
  std::printf("%-38s %8s %8s %8s %8s %8s\n", "path", "n", "p50_us", "p99_us", "p99.9_us", "max_us");
  auto row = [](const char* name, const Stats& st) {
    std::printf("%-38s %8zu %8.1f %8.1f %8.1f %8.1f\n", name, st.us.size(), st.pct(50), st.pct(99),
                st.pct(99.9), st.max());
  };
  row("tooth edge -> CrankState (subscriber)", rx.crank.total);
  row("  edge -> dds_write (in the daemon)", rx.crank.in_daemon);
  row("  dds_write -> received (DDS)", rx.crank.dds);
  row("tooth edge -> EngineTorque (subscr.)", rx.engine.total);
  row("  edge -> dds_write (in the daemon)", rx.engine.in_daemon);
  row("  dds_write -> received (DDS)", rx.engine.dds);
  print_tail_owner("CrankState", rx.crank.split);
  print_tail_owner("EngineTorque", rx.engine.split);
  tools::print_tail_stages(rx.crank.split, rx.crank.split_seq, p.stage_trace);
  std::printf("subscriber: %s, %s; its readers on %s\n",
              o.use_waitset ? "waitset" : "listener (receive thread)",
              o.sub_prio > 0 ? "SCHED_FIFO requested" : "SCHED_OTHER",
              sub_shm ? "shared memory (iceoryx)" : "the network path");
}

/// The floors measured alongside (cyclictest, ddsperf), printed; what they measured.
struct Floors {
  double cyc_p50 = -1, cyc_p999 = -1, dds_one_way = -1;
};

Floors print_floors_measured(const Options& o, const Paths& p, bool& keep_logs) {
  Floors fl;
  if (o.cyclic) {
    double p50 = 0, p99 = 0, p999 = 0, mx = 0;
    long late_1ms = 0;
    cyclictest_summary(read_cyclictest(p.cyclic_log.c_str()), p50, p99, p999, mx, late_1ms);
    fl.cyc_p50 = p50;
    fl.cyc_p999 = p999;
    const std::string name = "cyclictest -i " + std::to_string(o.cyclic_interval_us) + " (same run)";
    std::printf("%-38s %8s %8.1f %8.1f %8.1f %8.1f\n", name.c_str(), "-", p50, p99, p999, mx);
    std::printf(
        "cyclictest wake-ups >= 1 ms late: %ld (a 1 kHz thread late by that much misses a tick: compare "
        "with the daemon's time-thread overruns below)\n",
        late_1ms);
  }
  if (o.ddsperf) {
    double p50 = 0, p99 = 0;
    std::size_t n = 0;
    ddsperf_summary(p.ddsperf_log.c_str(), p50, p99, n);
    if (n > 0) {
      std::printf("%-38s %8s %8.1f %8.1f %8s %8s\n", "ddsperf one-way (round trip / 2)", "-", p50 / 2,
                  p99 / 2, "-", "-");
      fl.dds_one_way = p50 / 2;
    }
    std::printf(
        "ddsperf ping %d Hz / pong (round trip p50 %.1f us, p99 %.1f us; median of %zu one-second reports)\n",
        o.ddsperf_rate_hz, p50, p99, n);
    if (n == 0) keep_logs = true;
  }
  return fl;
}

/// The daemon's own counters (ring drops, time-thread overruns) from its final log line; returns whether it
/// logged CrankState among its shared-memory topics.
bool print_daemon_counters(const Paths& p, bool& keep_logs) {
  FILE* f = std::fopen(p.daemon_log.c_str(), "r");
  char line[1024];
  std::string last, shm_topics, threads;
  while (f && std::fgets(line, sizeof line, f)) {
    if (std::strstr(line, "stopped:")) last = line;
    if (const char* t = std::strstr(line, "threads over the run")) threads = t;
    if (const char* t = std::strstr(line, "DDS shared memory (iceoryx) for:")) shm_topics = t;
  }
  if (f) std::fclose(f);
  if (last.empty()) keep_logs = true;
  std::printf("daemon: %s", last.empty() ? ("no final counters (see " + p.daemon_log + ")\n").c_str()
                                         : last.substr(last.find("stopped:")).c_str());
  if (!threads.empty()) std::printf("daemon: %s", threads.c_str());
  return shm_topics.find("CrankState") != std::string::npos;
}

/// The PNG of --plot (plot_latency.py on the samples and cyclictest's histogram); false when it failed
/// (said).
bool write_plot(const Options& o, const Paths& p, const Receiver& rx) {
  const std::string csv = o.plot + ".data.csv";
  const auto cyc =
      o.cyclic ? read_cyclictest(p.cyclic_log.c_str()).hist : std::vector<std::pair<int, long>>{};
  if (!write_plot_data(csv,
                       {{"crank_total", &rx.crank.total},
                        {"crank_daemon", &rx.crank.in_daemon},
                        {"crank_dds", &rx.crank.dds},
                        {"engine_total", &rx.engine.total}},
                       cyc)) {
    std::fprintf(stderr, "torque-latency: cannot write %s: %s\n", csv.c_str(), std::strerror(errno));
    return false;
  }
  char dflt[160];
  std::snprintf(dflt, sizeof dflt, "torqued: tooth edge -> subscriber, %.0f s paced replay at %.1fx%s",
                o.duration_s, o.speed, o.stress ? ", stress-ng --cpu 1" : "");
  // Debian's python3-matplotlib lives with /usr/bin/python3 (the PATH python may be another one).
  const std::string cmd = "/usr/bin/python3 " + shell_quote(o.plot_script) + " --data " + shell_quote(csv) +
                          " --out " + shell_quote(o.plot) + " --title " +
                          shell_quote(o.title.empty() ? std::string(dflt) : o.title);
  if (std::system(cmd.c_str()) != 0) {
    std::fprintf(stderr, "torque-latency: plot failed (%s); data kept in %s\n", cmd.c_str(), csv.c_str());
    return false;
  }
  std::remove(csv.c_str());
  std::printf("plot: %s\n", o.plot.c_str());
  return true;
}

/// Everything printed after the run: the latency rows, the floors, the daemon's counters, the summary line,
/// the histogram and the plot. Returns the exit status.
int report(const Options& o, const dds::DdsSettings& s, const Paths& p, const Receiver& rx, bool sub_shm) {
  bool keep_logs = o.keep_logs;
  print_paths(o, s, p, rx, sub_shm);
  const Floors fl = print_floors_measured(o, p, keep_logs);
  const Stats& crank_us = rx.crank.total;
  print_floors(crank_us, rx.crank.in_daemon, rx.crank.dds, fl.cyc_p50, fl.cyc_p999, fl.dds_one_way);
  const bool daemon_shm = print_daemon_counters(p, keep_logs);
  // One line to compare runs (shared memory against the network path): the path is "shm" only when both the
  // daemon's CrankState writer and this subscriber's readers are on shared memory.
  std::printf(
      "summary: path %s edge->CrankState p50 %.1f p99.9 %.1f us, edge->dds_write p50 %.1f, "
      "dds_write->received "
      "p50 %.1f p99.9 %.1f us, cyclictest p50 %.1f p99.9 %.1f us, n %zu\n",
      sub_shm && daemon_shm ? "shm" : (sub_shm || daemon_shm ? "mixed" : "network"), crank_us.pct(50),
      crank_us.pct(99.9), rx.crank.in_daemon.pct(50), rx.crank.dds.pct(50), rx.crank.dds.pct(99.9),
      fl.cyc_p50, fl.cyc_p999, crank_us.us.size());
  histogram(crank_us, "tooth edge -> CrankState");
  if (!o.plot.empty() && !write_plot(o, p, rx)) {
    remove_dir(p.dir, keep_logs);
    return 1;
  }
  if (crank_us.us.empty()) keep_logs = true;
  remove_dir(p.dir, keep_logs);
  return crank_us.us.empty() ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "torque-latency: tooth edge -> subscriber latency of torqued in paced replay (p50/p99/p99.9/max + "
      "histogram), optionally with stress-ng --cpu 1, cyclictest and ddsperf alongside"};
  add_options(app, o);
  TORQUED_CLI_PARSE(app, argc, argv);

  // The daemon's DDS settings: same domain, topic prefix and engine_id as the daemon this run starts.
  const LoadResult cfg = load_config(o.config);
  if (!cfg.ok()) {
    for (const auto& e : cfg.errors) std::fprintf(stderr, "torque-latency: %s\n", e.c_str());
    return 2;
  }
  // Its QoS too: the readers below keep 256 and request no deadline (both what iceoryx carries).
  const dds::DdsSettings s = tools::dds_settings_from(*cfg.config);
  const char* tmpdir = std::getenv("TMPDIR");
  std::string tmpl = std::string(tmpdir && *tmpdir ? tmpdir : "/tmp") + "/torque-latency-XXXXXX";
  const char* tmp = mkdtemp(tmpl.data());
  if (!tmp) {
    std::fprintf(stderr, "torque-latency: mkdtemp: %s\n", std::strerror(errno));
    return 2;
  }
  const std::string dir = tmp;
  const Paths p{dir,
                dir + "/torqued.log",
                dir + "/cyclictest.log",
                dir + "/ddsperf.log",
                dir + "/state",
                dir + "/stages.csv"};
  pin_and_prioritise(o);
  const dds_entity_t pp = dds_create_participant(s.domain_id, nullptr, nullptr);
  if (pp < 0) {
    std::fprintf(stderr, "dds_create_participant failed\n");
    return 1;
  }
  Receiver rx;
  bool sub_shm = false;
  const dds_entity_t ws = open_readers(o, s, pp, rx, sub_shm);
  const std::vector<pid_t> helpers = start_helpers(o, s, p);
  if (o.torqued.empty()) o.torqued = default_torqued();
  int exec_pipe[2] = {-1, -1};
  if (pipe2(exec_pipe, O_CLOEXEC) != 0) exec_pipe[0] = exec_pipe[1] = -1;
  const pid_t daemon =
      spawn({o.torqued, "--config", o.config, "--speed", std::to_string(o.speed), "--wait-subscribers", "1",
             "--state-dir", p.state_dir, "--stage-trace", p.stage_trace},
            p.daemon_log.c_str(), o.daemon_env, exec_pipe[1]);
  if (exec_pipe[1] >= 0) close(exec_pipe[1]);
  DaemonEnd end;
  if (exec_pipe[0] >= 0) end.exec_errno = exec_error(exec_pipe[0]);
  if (end.exec_errno != 0) {
    int st = 0;
    waitpid(daemon, &st, 0);
    end.early = true;
    for (pid_t h : helpers) {
      kill(h, SIGINT);
      waitpid(h, &st, 0);
    }
  } else {
    end = measure(o, rx, ws, daemon, helpers);
  }
  dds_delete(pp);
  if (end.failed()) {
    print_daemon_end(o.torqued, p, end);
    remove_dir(p.dir, true);
    return 1;
  }
  if (end.early)
    std::printf(
        "torque-latency: the daemon's replay ended (exit 0) %.1f s into the run: measured up to there\n",
        end.after_s);
  return report(o, s, p, rx, sub_shm);
}
