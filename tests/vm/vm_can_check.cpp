// Checks of the SocketCAN paths, run inside the test VM (tests/vm/run_in_vm.sh) where vcan0 exists.
//   vm_can_check frames  --log can.log [--dbc demo.dbc] [--iface vcan0]
//       canplayer replays the log onto vcan0 while SocketCanSource receives it; the frames (id, type, length,
//       payload, order) and the DBC-decoded signal values must equal those of the candump file backend; a
//       second socket with a kernel filter receives exactly the frames of one id.
//   vm_can_check encoder --edges edges.csv --log encoder.log [--tick-ns 1] [--iface vcan0]
//       canplayer replays encoder frames (made by torque-canreplay encode); CanEncoderEdgeSource over
//       SocketCanSource must give the same edges as the edge CSV, and the crank decoder the same teeth and no
//       sync loss.
//   vm_can_check compare --a sent.log --b captured.log
//       the frames of two candump logs (id, type, length, payload, order) are equal; used with candump
//       capturing what torque-canreplay send put on vcan0.
//   vm_can_check downup [--iface vcan0]
//       a sender thread writes frames every ms; vcan0 is set down and up, then deleted and re-created; the
//       source must report each loss (link state, counters, last_error) and receive again after each
//       recovery.
// Prints "PASS ..." / "FAIL ..." lines; exit code 0 only if every assertion held.
#include <linux/can.h>
#include <net/if.h>
#include <spawn.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "can_encoder.hpp"
#include "candump_source.hpp"
#include "crank_decoder.hpp"
#include "edge_file_source.hpp"
#include "socketcan_source.hpp"
#include "vm_check.hpp"
#ifdef TORQUED_HAVE_DBC
#include "dbc.hpp"
#endif

extern char** environ;

namespace torqued {
namespace {

using Clock = std::chrono::steady_clock;
using vm::arg;
using vm::check;

pid_t spawn(const std::vector<std::string>& args) {
  std::vector<char*> av;
  for (const auto& a : args) av.push_back(const_cast<char*>(a.c_str()));
  av.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawnp(&pid, av[0], nullptr, nullptr, av.data(), environ) != 0) return -1;
  return pid;
}

int run(const std::vector<std::string>& args) {
  const pid_t pid = spawn(args);
  if (pid < 0) return -1;
  int st = 0;
  waitpid(pid, &st, 0);
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

bool same_frame(const CanFrame& a, const CanFrame& b) {
  return a.id == b.id && a.extended == b.extended && a.fd == b.fd && a.len == b.len &&
         std::memcmp(a.data.data(), b.data.data(), a.len) == 0;
}

/// Receives from `src` in a thread until stopped; stores the frames.
struct Receiver {
  explicit Receiver(SocketCanConfig cfg) : src(std::move(cfg)) {}
  void start() {
    frames.reserve(1 << 20);
    thread = std::thread([this] {
      CanFrame f;
      for (;;) {
        const SourceStatus s = src.next(f);
        if (s == SourceStatus::kOk) {
          frames.push_back(f);
          count.store(frames.size(), std::memory_order_release);
          last_rx = Clock::now().time_since_epoch().count();
        } else if (s == SourceStatus::kEnd || s == SourceStatus::kError) {
          break;
        }
      }
    });
  }
  /// Waits until no frame arrived for `quiet`, then stops.
  void finish(std::chrono::milliseconds quiet, std::chrono::seconds limit) {
    const auto t0 = Clock::now();
    std::size_t n = count.load();
    auto since = Clock::now();
    while (Clock::now() - t0 < limit) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      const std::size_t m = count.load();
      if (m != n) {
        n = m;
        since = Clock::now();
      } else if (Clock::now() - since > quiet) {
        break;
      }
    }
    src.request_stop();
    thread.join();
  }
  SocketCanSource src;
  std::vector<CanFrame> frames;
  std::atomic<std::size_t> count{0};
  std::atomic<long long> last_rx{0};
  std::thread thread;
};

std::vector<CanFrame> read_log(const std::string& path, std::string& iface, std::uint64_t& bad) {
  CandumpSource log(path);
  std::vector<CanFrame> out;
  if (!log.ok()) {
    std::printf("cannot read %s: %s\n", path.c_str(), log.last_error().c_str());
    return out;
  }
  CanFrame f;
  while (log.next(f) == SourceStatus::kOk) out.push_back(f);
  iface = std::string(log.bus_name(0));
  bad = log.stats().bad_lines;
  return out;
}

int cmd_frames(int argc, char** argv) {
  const std::string path = arg(argc, argv, "--log", "data/demo/can.log");
  const std::string ifname = arg(argc, argv, "--iface", "vcan0");
  std::string log_if;
  std::uint64_t bad = 0;
  const auto expected = read_log(path, log_if, bad);
  check(!expected.empty(), "frames: file backend read " + std::to_string(expected.size()) + " frames from " +
                               path + " (" + std::to_string(bad) + " bad lines)");
  if (expected.empty()) return 1;
  const std::uint32_t filter_id = expected.front().id;
  const bool filter_ext = expected.front().extended;

  SocketCanConfig all;
  all.interface = ifname;
  all.fd = true;
  all.rcvbuf_bytes = 8 << 20;
  SocketCanConfig one = all;
  one.filters.push_back({filter_id, 0x1FFFFFFF, filter_ext});
  Receiver rx_all(all), rx_one(one);
  check(rx_all.src.link_state() == CanLinkState::kUp,
        "frames: socket on " + ifname + " is up (" + to_string(rx_all.src.link_state()) + ")");
  rx_all.start();
  rx_one.start();
  const auto t0 = Clock::now();
  const int rc = run({"canplayer", "-I", path, ifname + "=" + log_if});
  const double replay_s = std::chrono::duration<double>(Clock::now() - t0).count();
  check(rc == 0,
        "frames: canplayer exit code " + std::to_string(rc) + " after " + std::to_string(replay_s) + " s");
  rx_all.finish(std::chrono::milliseconds(500), std::chrono::seconds(60));
  rx_one.finish(std::chrono::milliseconds(100), std::chrono::seconds(5));

  const auto& got = rx_all.frames;
  check(got.size() == expected.size(), "frames: received " + std::to_string(got.size()) + " of " +
                                           std::to_string(expected.size()) + " frames, kernel drops " +
                                           std::to_string(rx_all.src.stats().dropped));
  std::size_t mismatch = 0, first_bad = got.size();
  for (std::size_t i = 0; i < std::min(got.size(), expected.size()); ++i) {
    if (!same_frame(got[i], expected[i])) {
      if (mismatch++ == 0) first_bad = i;
    }
  }
  check(mismatch == 0, "frames: id/type/length/payload/order equal to the file backend (" +
                           std::to_string(mismatch) + " mismatches, first at " + std::to_string(first_bad) +
                           ")");
  std::size_t fd_frames = 0, with_ts = 0;
  for (const auto& f : got) {
    fd_frames += f.fd;
    with_ts += f.t_ns > 0;
  }
  check(rx_all.src.can_stats().no_timestamp == 0 && with_ts == got.size(),
        "frames: every frame carries a kernel timestamp (SO_TIMESTAMPNS)");
  // Inter-frame times from the kernel follow the log's (reported, not asserted: the VM's timing is loose).
  if (got.size() > 2 && got.size() == expected.size()) {
    const double log_span = static_cast<double>(expected.back().t_ns - expected.front().t_ns) * 1e-9;
    const double rx_span = static_cast<double>(got.back().t_ns - got.front().t_ns) * 1e-9;
    std::printf("info: log span %.3f s, kernel receive span %.3f s, FD frames %zu\n", log_span, rx_span,
                fd_frames);
  }
  std::size_t n_id = 0;
  for (const auto& f : expected) n_id += (f.id == filter_id && f.extended == filter_ext);
  bool only_id = true;
  for (const auto& f : rx_one.frames) only_id = only_id && f.id == filter_id;
  char idbuf[32];
  std::snprintf(idbuf, sizeof idbuf, "0x%X", filter_id);
  check(only_id && rx_one.frames.size() == n_id, std::string("frames: kernel filter for ") + idbuf +
                                                     " passed " + std::to_string(rx_one.frames.size()) +
                                                     " of " + std::to_string(n_id) +
                                                     " frames and nothing else");
#ifdef TORQUED_HAVE_DBC
  const std::string dbc_path = arg(argc, argv, "--dbc", "");
  if (!dbc_path.empty()) {
    auto res = DbcDatabase::parse_file(dbc_path);
    check(res.db.has_value(),
          "frames: DBC " + dbc_path + " parsed (" + std::to_string(res.errors.size()) + " errors)");
    if (res.db) {
      std::size_t values = 0, diffs = 0;
      std::map<std::string, std::pair<double, double>> ranges;
      for (std::size_t i = 0; i < std::min(got.size(), expected.size()); ++i) {
        const DbcMessage* m = res.db->find(expected[i].id, expected[i].extended);
        if (m == nullptr) continue;
        for (const DbcSignal& s : m->signals) {
          if (s.bytes_needed() > expected[i].len ||
              !m->signal_present(s, expected[i].data.data(), expected[i].len))
            continue;
          const double a = s.decode(expected[i].data.data(), expected[i].len);
          const double b = got[i].len >= s.bytes_needed() ? s.decode(got[i].data.data(), got[i].len) : -1e300;
          ++values;
          if (a != b) ++diffs;
          auto& r = ranges.try_emplace(s.name, a, a).first->second;
          r.first = std::min(r.first, b);
          r.second = std::max(r.second, b);
        }
      }
      check(values > 0 && diffs == 0, "frames: " + std::to_string(values) +
                                          " decoded signal values equal to the file "
                                          "backend's (" +
                                          std::to_string(diffs) + " differ)");
      for (const auto& [name, r] : ranges)
        std::printf("info: %-14s %12.4f .. %12.4f\n", name.c_str(), r.first, r.second);
    }
  }
#endif
  return vm::failures() == 0 ? 0 : 1;
}

struct DecodeSummary {
  std::vector<EdgeEvent> edges;
  DecoderStats stats;
};

DecodeSummary decode_all(EdgeSource& src, bool live, const std::atomic<bool>* done = nullptr) {
  DecodeSummary out;
  CrankDecoder dec(WheelGeometry{}, DecoderParams{});
  EdgeEvent e;
  ToothEvent t;
  auto quiet_since = Clock::now();
  for (;;) {
    const SourceStatus s = src.next(e);
    if (s == SourceStatus::kOk) {
      out.edges.push_back(e);
      dec.on_edge(e, t);
      quiet_since = Clock::now();
    } else if (s == SourceStatus::kWouldBlock && live) {
      if (done && done->load() && Clock::now() - quiet_since > std::chrono::milliseconds(500)) break;
    } else {
      break;
    }
  }
  out.stats = dec.stats();
  return out;
}

int cmd_encoder(int argc, char** argv) {
  const std::string edges_path = arg(argc, argv, "--edges", "data/demo/edges.csv");
  const std::string log_path = arg(argc, argv, "--log", "/tmp/encoder.log");
  const std::string ifname = arg(argc, argv, "--iface", "vcan0");
  CanEncoderConfig enc;
  enc.tick_ns = std::stoll(arg(argc, argv, "--tick-ns", "1"));
  enc.id = static_cast<std::uint32_t>(std::stoul(arg(argc, argv, "--id", "0x300"), nullptr, 0));

  EdgeCsvSource file(edges_path);
  check(file.ok(), "encoder: edge CSV " + edges_path + " opened " + file.last_error());
  if (!file.ok()) return 1;
  const DecodeSummary ref = decode_all(file, false);

  SocketCanConfig sc;
  sc.interface = ifname;
  sc.fd = true;
  sc.rcvbuf_bytes = 8 << 20;
  sc.filters.push_back({enc.id, 0x1FFFFFFF, false});
  SocketCanSource can(sc);
  CanEncoderEdgeSource src(can, enc);
  std::atomic<bool> done{false};
  DecodeSummary live;
  std::thread rx([&] { live = decode_all(src, true, &done); });
  std::string log_if = "can0";
  const int rc = run({"canplayer", "-I", log_path, ifname + "=" + log_if});
  done = true;
  rx.join();
  check(rc == 0, "encoder: canplayer replayed " + log_path + " (exit " + std::to_string(rc) + ")");
  check(live.edges.size() == ref.edges.size(), "encoder: " + std::to_string(live.edges.size()) + " of " +
                                                   std::to_string(ref.edges.size()) + " edges received");
  std::size_t diff = 0;
  for (std::size_t i = 0; i < std::min(live.edges.size(), ref.edges.size()); ++i) {
    const auto q = (ref.edges[i].t_ns / enc.tick_ns) * enc.tick_ns;
    if (live.edges[i].t_ns != q || live.edges[i].channel != ref.edges[i].channel ||
        live.edges[i].level != ref.edges[i].level) {
      ++diff;
    }
  }
  check(diff == 0,
        "encoder: edge times (to the tick), channels and levels equal (" + std::to_string(diff) + " differ)");
  check(src.encoder_stats().lost_frames == 0 && src.encoder_stats().bad_frames == 0,
        "encoder: " + std::to_string(src.encoder_stats().frames) + " frames, lost " +
            std::to_string(src.encoder_stats().lost_frames) + ", bad " +
            std::to_string(src.encoder_stats().bad_frames));
  check(live.stats.sync_losses == 0 && live.stats.syncs >= 1,
        "encoder: decoder synced " + std::to_string(live.stats.syncs) + "x, sync losses " +
            std::to_string(live.stats.sync_losses) + " (file: " + std::to_string(ref.stats.sync_losses) +
            ")");
  check(live.stats.synced_teeth == ref.stats.synced_teeth && live.stats.teeth == ref.stats.teeth,
        "encoder: synced teeth " + std::to_string(live.stats.synced_teeth) + " = file " +
            std::to_string(ref.stats.synced_teeth));
  return vm::failures() == 0 ? 0 : 1;
}

int cmd_compare(int argc, char** argv) {
  const std::string a_path = arg(argc, argv, "--a", "");
  const std::string b_path = arg(argc, argv, "--b", "");
  std::string ia, ib;
  std::uint64_t bad_a = 0, bad_b = 0;
  const auto a = read_log(a_path, ia, bad_a);
  const auto b = read_log(b_path, ib, bad_b);
  check(!a.empty() && a.size() == b.size(), "compare: " + std::to_string(b.size()) + " frames captured on " +
                                                ib + " of " + std::to_string(a.size()) + " sent");
  std::size_t diff = 0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) diff += !same_frame(a[i], b[i]);
  check(diff == 0 && bad_b == 0, "compare: frames equal (" + std::to_string(diff) + " differ, " +
                                     std::to_string(bad_b) + " bad lines in the capture)");
  return vm::failures() == 0 ? 0 : 1;
}

/// Raw sender with reopen: writes id 0x123 frames carrying a 32-bit counter.
void sender(const std::string& ifname, std::atomic<bool>& stop, std::atomic<std::uint32_t>& sent) {
  int fd = -1;
  std::uint32_t counter = 0;
  while (!stop.load()) {
    if (fd < 0) {
      fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
      const unsigned idx = if_nametoindex(ifname.c_str());
      sockaddr_can a{};
      a.can_family = AF_CAN;
      a.can_ifindex = static_cast<int>(idx);
      if (idx == 0 || bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) < 0) {
        close(fd);
        fd = -1;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        continue;
      }
    }
    can_frame f{};
    f.can_id = 0x123;
    f.len = 4;
    std::memcpy(f.data, &counter, 4);
    if (write(fd, &f, sizeof f) == static_cast<ssize_t>(sizeof f)) {
      ++counter;
      sent.store(counter);
    } else if (errno == ENODEV || errno == ENXIO) {
      close(fd);
      fd = -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (fd >= 0) close(fd);
}

int cmd_downup(int argc, char** argv) {
  const std::string ifname = arg(argc, argv, "--iface", "vcan0");
  SocketCanConfig sc;
  sc.interface = ifname;
  sc.poll_timeout_ms = 50;
  sc.reopen_interval_ms = 50;
  sc.filters.push_back({0x123, 0x7FF, false});
  SocketCanSource src(sc);
  std::atomic<bool> stop{false};
  std::atomic<std::uint32_t> sent{0};
  std::atomic<std::size_t> received{0};
  std::atomic<std::uint32_t> last_counter{0};
  std::vector<std::string> states;  // link state changes, as seen by the receiving thread
  std::thread rx([&] {
    CanFrame f;
    CanLinkState seen = src.link_state();
    states.push_back(to_string(seen));
    for (;;) {
      const SourceStatus s = src.next(f);
      if (src.link_state() != seen) {
        seen = src.link_state();
        states.push_back(std::string(to_string(seen)) + " (" + src.last_error() + ")");
      }
      if (s == SourceStatus::kOk) {
        std::uint32_t c;
        std::memcpy(&c, f.data.data(), 4);
        last_counter.store(c);
        received.fetch_add(1);
      } else if (s != SourceStatus::kWouldBlock) {
        break;
      }
    }
  });
  std::thread tx([&] { sender(ifname, stop, sent); });
  auto wait_more = [&](std::size_t n, const char* phase) {
    const std::size_t target = received.load() + n;
    const auto t0 = Clock::now();
    while (received.load() < target && Clock::now() - t0 < std::chrono::seconds(20)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    check(received.load() >= target, std::string("downup: ") + phase + ": receiving (" +
                                         std::to_string(received.load()) + " frames so far)");
  };
  wait_more(100, "before");
  check(run({"ip", "link", "set", ifname, "down"}) == 0, "downup: ip link set " + ifname + " down");
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const std::size_t while_down = received.load();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  check(received.load() == while_down, "downup: nothing received while down");
  check(run({"ip", "link", "set", ifname, "up"}) == 0, "downup: ip link set " + ifname + " up");
  wait_more(100, "after up");
  const std::uint64_t reopens_before = src.stats().reopens;
  check(run({"ip", "link", "del", ifname}) == 0, "downup: ip link del " + ifname);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  check(run({"ip", "link", "add", "dev", ifname, "type", "vcan"}) == 0 &&
            run({"ip", "link", "set", ifname, "up"}) == 0,
        "downup: re-created " + ifname);
  wait_more(100, "after re-creation");
  stop = true;
  tx.join();
  src.request_stop();
  rx.join();
  for (const auto& s : states) std::printf("info: link state -> %s\n", s.c_str());
  const auto& cs = src.can_stats();
  check(cs.link_losses >= 2,
        "downup: link losses reported: " + std::to_string(cs.link_losses) + " (down, removal)");
  bool saw_down = false, saw_missing = false;
  for (const auto& s : states) {
    saw_down = saw_down || s.rfind("down", 0) == 0;
    saw_missing = saw_missing || s.rfind("missing", 0) == 0;
  }
  check(saw_down && saw_missing, "downup: link state went through 'down' and 'missing'");
  check(src.stats().reopens > reopens_before,
        "downup: socket reopened by name (" + std::to_string(src.stats().reopens) + ")");
  check(src.link_state() == CanLinkState::kUp,
        std::string("downup: final link state ") + to_string(src.link_state()));
  check(src.link_changes() >= 4,
        "downup: " + std::to_string(src.link_changes()) + " link state changes counted");
  std::printf("info: sent %u, received %zu, last counter %u, last error '%s'\n", sent.load(), received.load(),
              last_counter.load(), src.last_error().c_str());
  return vm::failures() == 0 ? 0 : 1;
}

}  // namespace
}  // namespace torqued

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: vm_can_check frames|encoder|downup|compare [options]\n");
    return 2;
  }
  const std::string cmd = argv[1];
  if (cmd == "frames") return torqued::cmd_frames(argc, argv);
  if (cmd == "encoder") return torqued::cmd_encoder(argc, argv);
  if (cmd == "downup") return torqued::cmd_downup(argc, argv);
  if (cmd == "compare") return torqued::cmd_compare(argc, argv);
  std::fprintf(stderr, "vm_can_check: unknown command '%s' (expected frames, encoder, downup or compare)\n",
               cmd.c_str());
  return 2;
}
