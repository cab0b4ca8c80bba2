// torque-dash: a live web dashboard, a Foxglove WebSocket server and an MCAP recorder for torqued's DDS
// topics, in a subscriber process of its own (the daemon's real-time path is untouched: its writers keep only
// the last samples, a slow dashboard loses its own samples, never the daemon's time).
//   torque-dash --config config/demo.yaml                 page at http://127.0.0.1:8080/, Foxglove at
//   ws://127.0.0.1:8080/ torque-dash --config config/demo.yaml --record-mcap run.mcap --until-done
// See docs/dashboard.md. Network hygiene: it listens on 127.0.0.1 unless told otherwise (--listen), and its
// DDS participant follows CYCLONEDDS_URI (use config/cyclonedds-loopback.xml for local use).
#include <signal.h>

#include <CLI/CLI.hpp>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "cli_exit.hpp"
#include "config_loader.hpp"
#include "dash/hub.hpp"
#include "dash/mcap_writer.hpp"
#include "dds/dds.h"
#include "qos.hpp"
#include "sample.hpp"
#include "sample_recorder.hpp"
#include "share_dir.hpp"

namespace {
volatile sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

using namespace torqued;

struct Options {
  std::string config;
  std::optional<std::uint32_t> domain;
  std::optional<std::string> prefix;
  std::string listen = "127.0.0.1:8080";
  std::string www = torqued::tools::share_path("www");  // PREFIX/share/torqued/www
  std::string js_dir = "/usr/share/javascript";
  std::string mcap, record_dir, port_file;
  int period_ms = 100;
  double duration_s = 0, idle_exit_s = 0;
  bool until_done = false;
  dash::HubOptions hub;  ///< caps and time-outs (--max-clients, --max-subscriptions, --engine-expiry)
};

dds::TopicQos to_qos(const TopicQos& q) {
  return {q.reliability == Reliability::kReliable, q.history_depth, q.deadline_ms, q.lease_ms};
}

/// DDS settings and TDC geometry from the daemon's configuration (if given) and the command line.
std::pair<dds::DdsSettings, dash::Geometry> settings_from(const Options& o) {
  dds::DdsSettings s;
  dash::Geometry g;
  if (!o.config.empty()) {
    LoadOptions lo;
    lo.check_files = false;
    const LoadResult r = load_config(o.config, lo);
    if (!r.ok()) {
      std::string msg = "configuration " + o.config + " is not valid:";
      for (const auto& e : r.errors) msg += "\n  " + e;
      throw std::runtime_error(msg);
    }
    const Config& c = *r.config;
    s.domain_id = static_cast<std::uint32_t>(c.dds.domain_id);
    s.topic_prefix = c.dds.topic_prefix;
    s.qos = {to_qos(c.dds.engine_torque), to_qos(c.dds.estimator_torque), to_qos(c.dds.cylinder_torque),
             to_qos(c.dds.crank_state), to_qos(c.dds.status)};
    g.cylinders = c.engine.cylinders;
    for (int k = 0; k < c.engine.cylinders && k < 8; ++k)
      g.firing_order[static_cast<std::size_t>(k)] = c.engine.firing_order[static_cast<std::size_t>(k)];
    g.tdc_offset_deg = c.engine.tdc_offset_rad * 180.0 / 3.14159265358979323846;
    g.range = dds::torque_range(c.engine.cylinders, c.engine.bore_m, c.engine.stroke_m);
  }
  if (o.domain) s.domain_id = *o.domain;
  if (o.prefix) s.topic_prefix = *o.prefix;
  return {s, g};
}

std::uint64_t realtime_ns() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000'000ull + static_cast<std::uint64_t>(ts.tv_nsec);
}

class Subscriber {
 public:
  Subscriber(const Options& o, const dds::DdsSettings& s, dash::Hub& hub) : o_(o), s_(s), hub_(hub) {
    if (!o.mcap.empty()) {
      mcap_ = std::make_unique<dash::McapWriter>(o.mcap, s);
      if (!mcap_->ok()) throw std::runtime_error(mcap_->error());
    }
    if (!o.record_dir.empty()) {
      csv_ = std::make_unique<dds::SampleRecorder>(o.record_dir);
      if (!csv_->ok()) throw std::runtime_error(csv_->error());
    }
    participant_ = dds_create_participant(s.domain_id, nullptr, nullptr);
    if (participant_ < 0)
      throw std::runtime_error(std::string("dds_create_participant: ") + dds_strretcode(participant_));
    waitset_ = dds_create_waitset(participant_);
    for (int i = 0; i < dds::kTopicCount; ++i) make(static_cast<dds::Topic>(i));
  }
  ~Subscriber() {
    if (mcap_) mcap_->close();
    if (csv_) csv_->flush(true);
    dds_delete(participant_);
  }
  int run();

 private:
  void make(dds::Topic t) {
    const dds_entity_t topic = dds::create_topic(participant_, s_, t);
    if (topic < 0)
      throw std::runtime_error("dds_create_topic " + s_.topic_name(t) + ": " + dds_strretcode(topic));
    dds_qos_t* qos = dds::make_qos(s_.qos[static_cast<std::size_t>(t)]);
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 4096);  // more than the writer's depth: bursts are kept
    readers_[static_cast<std::size_t>(t)] = dds_create_reader(participant_, topic, qos, nullptr);
    dds_delete_qos(qos);
    if (readers_[static_cast<std::size_t>(t)] < 0)
      throw std::runtime_error("dds_create_reader " + s_.topic_name(t));
    const dds_entity_t rc = dds_create_readcondition(readers_[static_cast<std::size_t>(t)], DDS_ANY_STATE);
    dds_waitset_attach(waitset_, rc, readers_[static_cast<std::size_t>(t)]);
  }
  std::uint64_t take(dds::Topic t);
  void summary() const;
  std::string mcap_stats() const {
    char b[128];
    std::snprintf(b, sizeof b, "%llu (%llu chunks, %.3f s CPU writing them)",
                  static_cast<unsigned long long>(mcap_->messages()),
                  static_cast<unsigned long long>(mcap_->chunks()),
                  static_cast<double>(mcap_->chunk_cpu_ns()) / 1e9);
    return b;
  }

  static constexpr int kBatch = 64;
  const Options& o_;
  const dds::DdsSettings& s_;
  dash::Hub& hub_;
  std::unique_ptr<dash::McapWriter> mcap_;
  std::unique_ptr<dds::SampleRecorder> csv_;
  dds_entity_t participant_ = 0, waitset_ = 0;
  std::array<dds_entity_t, dds::kTopicCount> readers_{};
  std::array<dds::AnySample, kBatch> buf_{};
  std::array<std::uint64_t, dds::kTopicCount> received_{}, gaps_{};
  std::map<std::pair<int, std::uint16_t>, std::uint64_t> last_seq_;  ///< (topic*256+method, engine) -> seq
  bool done_ = false;
  std::optional<std::chrono::steady_clock::time_point> done_seen_;
};

std::uint64_t Subscriber::take(dds::Topic t) {
  std::array<void*, kBatch> ptrs{};
  std::array<dds_sample_info_t, kBatch> info{};
  std::uint64_t n_total = 0;
  for (;;) {
    for (int i = 0; i < kBatch; ++i) {
      buf_[static_cast<std::size_t>(i)].topic = t;
      ptrs[static_cast<std::size_t>(i)] = &buf_[static_cast<std::size_t>(i)].u;
    }
    const int n = dds_take(readers_[static_cast<std::size_t>(t)], ptrs.data(), info.data(), kBatch, kBatch);
    if (n <= 0) return n_total;
    const std::uint64_t now = realtime_ns();
    for (int i = 0; i < n; ++i) {
      if (!info[static_cast<std::size_t>(i)].valid_data) continue;
      const dds::AnySample& a = buf_[static_cast<std::size_t>(i)];
      const auto [engine, seq] = a.visit([](const auto& v) { return std::pair{v.engine_id, v.seq}; });
      // seq counts per instance: (engine) and, for EstimatorTorque, (engine, method).
      const int instance = t == dds::Topic::kEstimatorTorque ? a.u.estimator.method : 0;
      auto& last = last_seq_[{static_cast<int>(t) * 256 + instance, engine}];
      if (last != 0 && seq > last + 1) gaps_[static_cast<std::size_t>(t)] += seq - last - 1;
      if (seq > last) last = seq;
      if (t == dds::Topic::kDaemonStatus && (a.u.status.flags & torque_STATUS_REPLAY_DONE)) done_ = true;
      ++received_[static_cast<std::size_t>(t)];
      ++n_total;
      hub_.on_sample(a, now);
      if (mcap_) mcap_->write(a, now);
      if (csv_) csv_->record(a);
    }
  }
}

int Subscriber::run() {
  const auto t0 = std::chrono::steady_clock::now();
  auto last_data = t0;
  std::uint64_t total = 0;
  while (!g_stop) {
    dds_waitset_wait(waitset_, nullptr, 0, DDS_MSECS(100));
    std::uint64_t got = 0;
    // CrankState first: the in-cycle samples taken after it find their crank-angle anchors already there.
    got += take(dds::Topic::kCrankState);
    for (int i = 0; i < dds::kTopicCount; ++i)
      if (static_cast<dds::Topic>(i) != dds::Topic::kCrankState) got += take(static_cast<dds::Topic>(i));
    total += got;
    const auto now = std::chrono::steady_clock::now();
    if (got) last_data = now;
    if (mcap_) mcap_->tick(realtime_ns());  // a chunk older than its period goes to the file (kill -9 safe)
    if (mcap_ && !mcap_->ok()) {
      std::fprintf(stderr, "torque-dash: %s: MCAP recording stopped\n", mcap_->error().c_str());
      mcap_.reset();
    }
    // The end-of-replay status may overtake the last samples of the other topics: take them for 0.5 s more.
    if (done_ && !done_seen_) done_seen_ = now;
    if (o_.until_done && done_seen_ && now - *done_seen_ > std::chrono::milliseconds(500)) break;
    if (o_.duration_s > 0 && std::chrono::duration<double>(now - t0).count() >= o_.duration_s) break;
    if (o_.idle_exit_s > 0 && total > 0 &&
        std::chrono::duration<double>(now - last_data).count() >= o_.idle_exit_s)
      break;
  }
  summary();
  return mcap_ && !mcap_->ok() ? 1 : 0;
}

void Subscriber::summary() const {
  const dash::Hub::Stats h = hub_.stats();
  std::fprintf(stderr, "torque-dash: received");
  for (int i = 0; i < dds::kTopicCount; ++i)
    std::fprintf(stderr, " %s %llu (seq gaps %llu)%s", std::string(dds::kTopicNames[i]).c_str(),
                 static_cast<unsigned long long>(received_[static_cast<std::size_t>(i)]),
                 static_cast<unsigned long long>(gaps_[static_cast<std::size_t>(i)]),
                 i + 1 < dds::kTopicCount ? "," : "\n");
  std::fprintf(
      stderr,
      "torque-dash: web clients %llu (refused %llu), websocket messages sent %llu, dropped (slow clients) "
      "%llu, subscriptions refused %llu, silent engines expired %llu; in-cycle samples without a crank angle "
      "%llu%s%s\n",
      static_cast<unsigned long long>(h.clients_total), static_cast<unsigned long long>(h.clients_refused),
      static_cast<unsigned long long>(h.messages_sent), static_cast<unsigned long long>(h.messages_dropped),
      static_cast<unsigned long long>(h.subscriptions_refused),
      static_cast<unsigned long long>(h.engines_expired), static_cast<unsigned long long>(h.unplaced),
      mcap_ ? "; MCAP messages " : "", mcap_ ? mcap_stats().c_str() : "");
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "torque-dash: live web dashboard, Foxglove WebSocket server (JSON) and MCAP recorder for torqued's "
      "DDS topics. Set CYCLONEDDS_URI to a loopback-only configuration for local use."};
  app.add_option("--config,-c", o.config,
                 "the daemon's YAML configuration (DDS domain, prefix, QoS; TDC marks)")
      ->check(CLI::ExistingFile);
  app.add_option("--domain", o.domain, "DDS domain id (overrides the configuration)");
  app.add_option("--prefix", o.prefix, "topic prefix (overrides the configuration)");
  app.add_option("--listen", o.listen, "HTTP/WebSocket address:port (loopback by default; port 0 = any free)")
      ->capture_default_str();
  app.add_option("--www", o.www,
                 "directory of the page (index.html, dash.js, dash.css); default: PREFIX/share/torqued/www "
                 "next to this executable's PREFIX/bin")
      ->capture_default_str();
  app.add_option("--js-dir", o.js_dir, "Debian's JavaScript directory (chart.js/chart.min.js)")
      ->capture_default_str();
  app.add_option("--period-ms", o.period_ms, "dashboard update period (ms)")
      ->capture_default_str()
      ->check(CLI::Range(10, 5000));
  app.add_option("--record-mcap", o.mcap,
                 "record every topic to this MCAP file (JSON messages, JSON Schema; zstd chunks of at most "
                 "0.5 s, indexed; after a kill -9: torque-mcap-recover)");
  app.add_option("--record", o.record_dir,
                 "also record CSV files (torque-echo's format) into this directory");
  app.add_option("--port-file", o.port_file, "write the bound HTTP port to this file once listening");
  app.add_option("--duration", o.duration_s, "exit after this many seconds (0 = until signalled)")
      ->capture_default_str();
  app.add_option("--idle-exit", o.idle_exit_s,
                 "exit when no sample arrived for this many seconds (after the first; 0 = never)")
      ->capture_default_str();
  app.add_flag("--until-done", o.until_done, "exit when the daemon's status reports the end of its replay");
  app.add_option("--max-clients", o.hub.max_clients, "WebSocket clients at once (more are refused)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--max-subscriptions", o.hub.max_subscriptions, "Foxglove subscriptions per client")
      ->check(CLI::Range(1, 10000));
  app.add_option("--engine-expiry-ms", o.hub.engine_expiry_ms,
                 "an engine id silent this long leaves the dashboard (ms)")
      ->check(CLI::Range(100, 3600000));
  app.footer(
      "Exit status: 0 done (signal, --duration, --idle-exit or --until-done); 1 the configuration could not "
      "be "
      "read, the address could not be bound, a DDS call failed or the MCAP/CSV recording failed (message on "
      "stderr); 2 command-line error (unknown option, bad value, file that does not exist).");
  TORQUED_CLI_PARSE(app, argc, argv);

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);
  try {
    const auto [settings, geometry] = settings_from(o);
    dash::HubOptions ho = o.hub;
    ho.listen = o.listen;
    ho.www_dir = o.www;
    ho.js_dir = o.js_dir;
    ho.period_ms = o.period_ms;
    dash::Hub hub(ho, settings, dash::Model({}, geometry));
    if (!hub.start()) throw std::runtime_error(hub.error());
    std::fprintf(stderr,
                 "torque-dash: dashboard http://127.0.0.1:%d/ , Foxglove ws://127.0.0.1:%d/ (DDS domain %u, "
                 "topics %s/*)\n",
                 hub.port(), hub.port(), settings.domain_id, settings.topic_prefix.c_str());
    if (!o.port_file.empty()) std::ofstream(o.port_file) << hub.port() << "\n";
    Subscriber sub(o, settings, hub);
    const int rc = sub.run();
    hub.stop();
    return rc;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "torque-dash: %s\n", e.what());
    return 1;
  }
}
