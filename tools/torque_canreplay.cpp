// torque-canreplay: produce and send CAN traffic for live-backend tests and bench set-ups.
//   torque-canreplay encode --edges edges.csv -o encoder.log [--id 0x300] [--classic] [--tick-ns 10]
//       turns an edge capture into the encoder-over-CAN frames an encoder interface would send
//       (layout: io/can_encoder.hpp, docs/live.md), written as a `candump -l` log (replay it with canplayer
//       or `torque-canreplay send`).
//   torque-canreplay send --iface vcan0 [--fd] [--speed 1.0 | --fast] log...
//       sends a candump log onto a SocketCAN interface, paced by the log's timestamps (scaled) or as fast as
//       the socket accepts (write blocks when the queue is full: nothing is dropped).
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "can_encoder.hpp"
#include "candump_source.hpp"
#include "cli_exit.hpp"
#include "edge_file_source.hpp"

namespace {

using namespace torqued;

void write_candump_line(std::FILE* f, const CanFrame& fr, const char* iface, std::int64_t time_base_s) {
  const std::int64_t us = fr.t_ns / 1000;
  std::fprintf(f, "(%" PRId64 ".%06" PRId64 ") %s ", time_base_s + us / 1'000'000, us % 1'000'000, iface);
  if (fr.extended) {
    std::fprintf(f, "%08X", fr.id);
  } else {
    std::fprintf(f, "%03X", fr.id);
  }
  std::fputs(fr.fd ? "##0" : "#", f);
  for (int i = 0; i < fr.len; ++i) std::fprintf(f, "%02X", fr.data[static_cast<std::size_t>(i)]);
  std::fputc('\n', f);
}

int encode(const std::string& edges_path, const std::string& out_path, const CanEncoderConfig& cfg,
           double latency_us, const std::string& iface, std::int64_t time_base_s, const EdgeCsvOptions& csv) {
  if (const char* why = validate(cfg)) {
    std::fprintf(stderr, "torque-canreplay: %s\n", why);
    return 2;
  }
  EdgeCsvSource src(edges_path, csv);
  if (!src.ok()) {
    std::fprintf(stderr, "torque-canreplay: %s\n", src.last_error().c_str());
    return 1;
  }
  std::FILE* out = out_path == "-" ? stdout : std::fopen(out_path.c_str(), "w");
  if (out == nullptr) {
    std::fprintf(stderr, "torque-canreplay: cannot write %s: %s\n", out_path.c_str(), std::strerror(errno));
    return 1;
  }
  can_encoder::Batcher batcher(cfg, static_cast<std::int64_t>(latency_us * 1000.0));
  EdgeEvent e;
  CanFrame f;
  std::uint64_t edges = 0;
  while (src.next(e) == SourceStatus::kOk) {
    ++edges;
    if (e.t_ns < 0) continue;
    if (batcher.push(e, f)) write_candump_line(out, f, iface.c_str(), time_base_s);
  }
  while (batcher.flush(f)) write_candump_line(out, f, iface.c_str(), time_base_s);
  if (out != stdout) std::fclose(out);
  for (const auto& m : src.bad_line_messages()) std::fprintf(stderr, "torque-canreplay: %s\n", m.c_str());
  std::fprintf(stderr,
               "torque-canreplay: %" PRIu64 " edges -> %" PRIu64 " frames (%s, id 0x%X, tick %" PRId64
               " ns), %" PRIu64 " bad lines\n",
               edges, batcher.frames(), cfg.fd ? "CAN FD" : "classic", cfg.id, cfg.tick_ns,
               src.stats().bad_lines);
  return 0;
}

int send(const std::vector<std::string>& logs, const std::string& iface, bool fd_frames, double speed,
         bool fast) {
  const int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (s < 0) {
    std::fprintf(stderr, "torque-canreplay: socket(PF_CAN): %s\n", std::strerror(errno));
    return 1;
  }
  const int on = 1;
  if (fd_frames && setsockopt(s, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
    std::fprintf(stderr, "torque-canreplay: CAN_RAW_FD_FRAMES: %s\n", std::strerror(errno));
    return 1;
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(if_nametoindex(iface.c_str()));
  if (addr.can_ifindex == 0 || bind(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) {
    std::fprintf(stderr, "torque-canreplay: cannot bind to %s: %s\n", iface.c_str(), std::strerror(errno));
    return 1;
  }
  std::uint64_t sent = 0, skipped = 0;
  for (const auto& path : logs) {
    CandumpSource log(path);
    if (!log.ok()) {
      std::fprintf(stderr, "torque-canreplay: %s\n", log.last_error().c_str());
      return 1;
    }
    CanFrame f;
    std::int64_t t0_log = -1;
    const auto t0 = std::chrono::steady_clock::now();
    while (log.next(f) == SourceStatus::kOk) {
      if (t0_log < 0) t0_log = f.t_ns;
      if (!fast) {
        const auto due = t0 + std::chrono::nanoseconds(
                                  static_cast<std::int64_t>(static_cast<double>(f.t_ns - t0_log) / speed));
        std::this_thread::sleep_until(due);
      }
      canfd_frame k{};
      k.can_id = f.id | (f.extended ? CAN_EFF_FLAG : 0u);
      k.len = f.len;
      std::memcpy(k.data, f.data.data(), f.len);
      if (f.fd && !fd_frames) {
        ++skipped;
        continue;
      }
      const std::size_t size = f.fd ? CANFD_MTU : CAN_MTU;
      for (;;) {
        if (write(s, &k, size) == static_cast<ssize_t>(size)) break;
        if (errno != ENOBUFS && errno != EAGAIN) {
          std::fprintf(stderr, "torque-canreplay: write to %s: %s (frame %" PRIu64 ")\n", iface.c_str(),
                       std::strerror(errno), sent + 1);
          return 1;
        }
        std::this_thread::sleep_for(std::chrono::microseconds(200));  // queue full: wait, never drop
      }
      ++sent;
    }
    for (const auto& m : log.bad_line_messages()) std::fprintf(stderr, "torque-canreplay: %s\n", m.c_str());
  }
  close(s);
  std::fprintf(stderr, "torque-canreplay: sent %" PRIu64 " frames on %s", sent, iface.c_str());
  if (skipped) std::fprintf(stderr, ", skipped %" PRIu64 " CAN FD frames (use --fd)", skipped);
  std::fputc('\n', stderr);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "torque-canreplay: encoder-over-CAN frames from edge captures; send candump logs onto SocketCAN"};
  app.require_subcommand(1);

  auto* enc = app.add_subcommand("encode", "edge CSV -> candump log of encoder frames (docs/live.md)");
  std::string edges_path, out_path = "-", iface = "can0", id_text = "0x300";
  torqued::CanEncoderConfig cfg;
  torqued::EdgeCsvOptions csv;
  bool classic = false;
  double latency_us = 1000.0;
  std::int64_t time_base_s = 1'700'000'000;
  enc->add_option("--edges", edges_path, "edge CSV (Time [s],crank,cam)")->required();
  enc->add_option("-o,--output", out_path, "candump log to write ('-' = stdout)");
  enc->add_option("--id", id_text, "CAN id of the encoder frames (hex with 0x, or decimal)");
  enc->add_flag("--extended", cfg.extended, "29-bit identifier");
  enc->add_flag("--classic", classic,
                "classic CAN frames (1 edge per frame) instead of CAN FD (15 per frame)");
  enc->add_option("--tick-ns", cfg.tick_ns, "encoder counter tick (ns)")->check(CLI::Range(1, 1'000'000));
  enc->add_option("--latency-us", latency_us, "longest time an edge waits for its frame (µs)")
      ->check(CLI::Range(0.0, 1e6));
  enc->add_option("--iface", iface, "interface name written in the log");
  enc->add_option("--time-base", time_base_s, "seconds added to the edge clock for the log's timestamps");
  enc->add_option("--crank-column", csv.crank_column, "crank column name");
  enc->add_option("--cam-column", csv.cam_column, "cam column name ('' = none)");

  auto* snd = app.add_subcommand("send", "send candump logs onto a SocketCAN interface");
  std::vector<std::string> logs;
  std::string send_iface = "vcan0";
  bool fd_frames = false, fast = false;
  double speed = 1.0;
  snd->add_option("logs", logs, "candump -l logs")->required();
  snd->add_option("--iface", send_iface, "interface to send on");
  snd->add_flag("--fd", fd_frames, "enable CAN FD frames");
  snd->add_option("--speed", speed, "replay speed factor (2 = twice as fast)")->check(CLI::Range(1e-3, 1e3));
  snd->add_flag("--fast", fast, "ignore timestamps: as fast as the socket accepts");

  app.footer(
      "Exit status: 0 done; 1 an input could not be read or parsed, the output not written, or SocketCAN "
      "refused; 2 command-line error (unknown option, bad value, file that does not exist).");
  TORQUED_CLI_PARSE(app, argc, argv);
  if (enc->parsed()) {
    try {
      cfg.id = static_cast<std::uint32_t>(std::stoul(id_text, nullptr, 0));
    } catch (const std::exception&) {
      std::fprintf(stderr, "torque-canreplay: --id '%s' is not a number\n", id_text.c_str());
      return 2;
    }
    cfg.fd = !classic;
    return encode(edges_path, out_path, cfg, latency_us, iface, time_base_s, csv);
  }
  return send(logs, send_iface, fd_frames, speed, fast);
}
