#include "metrics.hpp"

#include <prometheus/collectable.h>
#include <prometheus/exposer.h>
#include <prometheus/metric_family.h>
#include <prometheus/text_serializer.h>
#include <sys/stat.h>

#include <cmath>
#include <exception>
#include <limits>

#include "clocks.hpp"
#include "signal_store.hpp"

#ifndef TORQUED_VERSION
#define TORQUED_VERSION "0.0.0"
#endif

namespace torqued::metrics {
namespace {

using prometheus::ClientMetric;
using prometheus::MetricFamily;
using prometheus::MetricType;
using Labels = std::vector<ClientMetric::Label>;

constexpr std::memory_order kRelaxed = std::memory_order_relaxed;

MetricFamily& family(std::vector<MetricFamily>& out, std::string name, std::string help, MetricType type) {
  out.push_back(MetricFamily{std::move(name), std::move(help), type, {}});
  return out.back();
}
void add(MetricFamily& f, double v, Labels labels = {}) {
  ClientMetric m;
  m.label = std::move(labels);
  if (f.type == MetricType::Counter)
    m.counter.value = v;
  else
    m.gauge.value = v;
  f.metric.push_back(std::move(m));
}
void single(std::vector<MetricFamily>& out, const char* name, const char* help, MetricType type, double v) {
  add(family(out, name, help, type), v);
}

/// DaemonStatus.flags bits (idl/torque.idl STATUS_*).
constexpr std::pair<std::uint32_t, const char*> kFlags[] = {
    {torque_STATUS_RT_NOT_PERMITTED, "rt_not_permitted"},
    {torque_STATUS_MLOCK_FAILED, "mlock_failed"},
    {torque_STATUS_EDGE_TIMEOUT, "edge_timeout"},
    {torque_STATUS_CAN_TIMEOUT, "can_timeout"},
    {torque_STATUS_NO_SYNC, "no_sync"},
    {torque_STATUS_DROPS, "drops"},
    {torque_STATUS_REPLAY_DONE, "replay_done"},
    {torque_STATUS_DRAINING, "draining"},
    {torque_STATUS_OVERRUNS, "overruns"},
    {torque_STATUS_RECORD_ERROR, "record_error"}};

void status_families(const torque_DaemonStatus& s, bool have, std::vector<MetricFamily>& out) {
  const auto C = MetricType::Counter;
  const auto G = MetricType::Gauge;
  single(out, "torqued_status_received",
         "1 once a DaemonStatus was published (0: the figures below are not filled yet)", G, have ? 1 : 0);
  single(out, "torqued_edges_total", "edges consumed by the crank decoder", C, static_cast<double>(s.edges));
  single(out, "torqued_teeth_total", "teeth produced by the decoder", C, static_cast<double>(s.teeth));
  single(out, "torqued_can_frames_total", "CAN frames consumed", C, static_cast<double>(s.can_frames));
  single(out, "torqued_cycles_total", "720 degree cycles completed", C, static_cast<double>(s.cycles));
  single(out, "torqued_sync_losses_total", "crank sync losses", C, static_cast<double>(s.sync_losses));
  single(out, "torqued_rejected_edges_total", "crank edges rejected by the decoder as noise or debounced", C,
         static_cast<double>(s.rejected_edges));
  single(out, "torqued_cam_phase_errors_total",
         "cam edges outside their window or disagreeing with the phase", C,
         static_cast<double>(s.cam_phase_errors));
  single(out, "torqued_fuel_model_references",
         "references the fuel model (indicated torque from fuel) rests on; 0: prior only", G,
         static_cast<double>(s.fuel_references));
  auto& cells = family(out, "torqued_fuel_model_cell_learned",
                       "1: the fuel model's speed x MAP cell has >= fuel.cell_min_references references", G);
  static constexpr const char* kSpeed[] = {"lt1500", "lt2500", "lt3500", "ge3500"};
  static constexpr const char* kMap[] = {"lt40kPa", "lt60kPa", "lt80kPa", "ge80kPa"};
  for (int i = 0; i < 16; ++i)
    add(cells, (s.fuel_cells >> i) & 1u, {{"speed", kSpeed[i / 4]}, {"map", kMap[i % 4]}});
  single(
      out, "torqued_burn_phase_state",
      "the burn-phasing learner of the in-cycle gas model: 0 not used (off, or no cycle used yet and "
      "nothing imported), 1 learning, 2 converged, 3 imported (the learned state's offset, no cycle of this "
      "run used yet)",
      G, s.burn_phase_state);
  single(out, "torqued_burn_phase_offset_degrees", "its learned offset of the gas model's burn centroid", G,
         s.burn_phase_offset_deg);
  auto& drops = family(out, "torqued_ring_drops_total", "records dropped because a ring was full", C);
  add(drops, static_cast<double>(s.ring_drops_edge), {{"ring", "edge"}});
  add(drops, static_cast<double>(s.ring_drops_can), {{"ring", "can"}});
  add(drops, static_cast<double>(s.ring_drops_out), {{"ring", "out"}});
  single(out, "torqued_source_drops_total", "dropped/bad records reported by the sources", C,
         static_cast<double>(s.source_drops));
  single(out, "torqued_overruns_total", "time pipeline deadline misses", C, static_cast<double>(s.overruns));
  single(out, "torqued_publisher_polls_total", "publisher pre-wakes for a tooth edge (paced replay)", C,
         static_cast<double>(s.publisher_polls));
  single(out, "torqued_publisher_poll_misses_total", "pre-wakes that ended without the edge's samples", C,
         static_cast<double>(s.publisher_poll_misses));
  // A gauge per statistic (label stat, not quantile: a quantile label belongs to a summary, whose _sum and
  // _count a status period does not carry; promtool check metrics refuses it on a gauge).
  auto& lat = family(out, "torqued_latency_period_seconds",
                     "ingest -> publish latency over the last status period (DaemonStatus p50/p99/max)", G);
  add(lat, static_cast<double>(s.latency_p50_ns) * 1e-9, {{"stat", "p50"}});
  add(lat, static_cast<double>(s.latency_p99_ns) * 1e-9, {{"stat", "p99"}});
  add(lat, static_cast<double>(s.latency_max_ns) * 1e-9, {{"stat", "max"}});
  single(out, "torqued_uptime_seconds", "time since the pipelines started", G,
         static_cast<double>(s.uptime_ns) * 1e-9);
  single(out, "torqued_source_time_seconds", "newest edge-clock time processed", G,
         static_cast<double>(s.source_t_ns) * 1e-9);
  single(out, "torqued_health", "DaemonStatus.health: 0 ok, 1 degraded, 2 failed", G, s.health);
  single(out, "torqued_synced", "1 when the crank decoder is synced", G,
         have && !(s.flags & torque_STATUS_NO_SYNC) ? 1 : 0);
  auto& flags = family(out, "torqued_status_flag", "DaemonStatus.flags, one series per bit (1 = set)", G);
  for (const auto& [bit, name] : kFlags) add(flags, (s.flags & bit) ? 1 : 0, {{"flag", name}});
  single(out, "torqued_replay_done",
         "1 once a replay has consumed its recording (stays 1 until the daemon stops; 0 live or still "
         "replaying)",
         G, (s.flags & torque_STATUS_REPLAY_DONE) ? 1 : 0);
  auto& st = family(out, "torqued_sensor_timeout",
                    "1 while that CAN quantity is stale (DaemonStatus.sensor_timeouts)", G);
  for (int q = 0; q < kQuantityCount; ++q)
    add(st, (s.sensor_timeouts >> q) & 1u, {{"signal", quantity_name(static_cast<Quantity>(q))}});
}

/// Per method: the in-cycle methods (registry flag in_cycle: Kalman, Fourier) are instantaneous torques
/// within the cycle (hundreds of N m either way of the mean), so they have a family of their own next to the
/// means.
template <class Current>
void estimator_families(const MetricsTap& t, const Current& current, std::vector<MetricFamily>& out) {
  const auto G = MetricType::Gauge;
  auto& val =
      family(out, "torqued_estimator_torque_nm",
             "last EstimatorTorque.value_nm of the methods giving a mean torque (per cycle, segment or "
             "time-filtered); NaN: none for 2 s, or health failed",
             G);
  auto& inst =
      family(out, "torqued_estimator_in_cycle_torque_nm",
             "last EstimatorTorque.value_nm of the in-cycle methods: the instantaneous torque at one "
             "tooth, not a mean; NaN: none for 2 s, or health failed",
             G);
  auto& unc = family(
      out, "torqued_estimator_uncertainty",
      "last EstimatorTorque.uncertainty per method (1-sigma N m, or excitation level for adaptive)", G);
  auto& hl =
      family(out, "torqued_estimator_health",
             "last EstimatorTorque.health per method: 0 valid, 1 not "
             "converged, 2 not excited, 3 stale input, 4 invalid input, 5 no sync, 6 numerical, 7 disabled",
             G);
  auto& n = family(out, "torqued_estimator_samples_total", "EstimatorTorque samples per method",
                   MetricType::Counter);
  for (int m = 0; m < dds::kMethodCount; ++m) {
    const auto& x = t.method[static_cast<std::size_t>(m)];
    const std::uint64_t k = x.samples.load(kRelaxed);
    if (k == 0) continue;  // method disabled or not producing: no series (absent, not a stale 0)
    const Labels l{{"method", std::string(dds::kMethods[m].name)}};
    add(dds::kMethods[m].in_cycle ? inst : val, current(x.value, x.at_ns), l);
    add(unc, current(x.uncertainty, x.at_ns), l);
    add(hl, x.health.load(kRelaxed), l);
    add(n, static_cast<double>(k), l);
  }
}

void tap_families(const MetricsTap& t, std::vector<MetricFamily>& out) {
  auto& hist =
      family(out, "torqued_publish_latency_seconds",
             "ingest -> publish latency of every published sample since start", MetricType::Histogram);
  ClientMetric h;
  std::uint64_t cum = 0;
  for (std::size_t b = 0; b < kLatencyBuckets.size(); ++b) {
    cum += t.latency_bucket[b].load(kRelaxed);
    h.histogram.bucket.push_back({cum, kLatencyBuckets[b]});
  }
  cum += t.latency_bucket[kLatencyBuckets.size()].load(kRelaxed);
  h.histogram.bucket.push_back({cum, std::numeric_limits<double>::infinity()});
  h.histogram.sample_count = cum;
  h.histogram.sample_sum = static_cast<double>(t.latency_sum_ns.load(kRelaxed)) * 1e-9;
  hist.metric.push_back(std::move(h));

  const std::int64_t now = realtime_ns();
  const bool failed = t.failed.load(kRelaxed);
  // The newest value, or NaN when it is stale or the daemon's health is failed (not a frozen last value).
  const auto current = [&](const std::atomic<double>& v, const std::atomic<std::int64_t>& at) {
    return failed || now - at.load(kRelaxed) > kStaleAfterNs ? std::numeric_limits<double>::quiet_NaN()
                                                             : v.load(kRelaxed);
  };
  estimator_families(t, current, out);
  auto& et = family(out, "torqued_engine_torque_nm",
                    "last EngineTorque per kind (segment|cycle) and quantity; NaN: none for 2 s, or health "
                    "failed",
                    MetricType::Gauge);
  auto& eq = family(out, "torqued_engine_quality",
                    "last EngineTorque.quality (Health code of the fused estimate)", MetricType::Gauge);
  for (int k = 0; k < kEngineKinds; ++k) {
    const auto& e = t.engine[static_cast<std::size_t>(k)];
    if (e.samples.load(kRelaxed) == 0) continue;
    const std::string kind = k == torque_KIND_CYCLE ? "cycle" : "segment";
    add(et, current(e.brake, e.at_ns), {{"kind", kind}, {"quantity", "brake"}});
    add(et, current(e.indicated, e.at_ns), {{"kind", kind}, {"quantity", "indicated"}});
    add(et, current(e.friction, e.at_ns), {{"kind", kind}, {"quantity", "friction"}});
    add(et, current(e.load, e.at_ns), {{"kind", kind}, {"quantity", "load"}});
    add(et, current(e.fused, e.at_ns), {{"kind", kind}, {"quantity", "fused"}});
    add(eq, e.quality.load(kRelaxed), {{"kind", kind}});
  }
  single(out, "torqued_crank_sync_state",
         "CrankState.sync of the newest sample: 0 no signal, 1 syncing, 2 synced, "
         "3 lost sync, 4 stalled (-1: no CrankState yet)",
         MetricType::Gauge, t.sync_state.load(kRelaxed));
}

void state_families(const std::string& file, std::vector<MetricFamily>& out) {
  struct stat st {};
  const bool have = !file.empty() && ::stat(file.c_str(), &st) == 0;
  single(out, "torqued_learned_state_present", "1 when the learned-state file exists (output.state_dir)",
         MetricType::Gauge, have ? 1 : 0);
  if (!have) return;
  const double mtime =
      static_cast<double>(st.st_mtim.tv_sec) + static_cast<double>(st.st_mtim.tv_nsec) * 1e-9;
  single(out, "torqued_learned_state_age_seconds", "time since the learned state was last saved (file mtime)",
         MetricType::Gauge, static_cast<double>(realtime_ns()) * 1e-9 - mtime);
}

}  // namespace

void MetricsTap::emit(const dds::AnySample& s) noexcept {
  const std::int64_t ingest = s.visit([](const auto& v) { return v.ingest_t_ns; });
  const std::int64_t now = realtime_ns();
  if (ingest > 0 && s.topic != dds::Topic::kDaemonStatus) {
    const std::int64_t lat = now - ingest;
    const double sec = static_cast<double>(lat) * 1e-9;
    std::size_t b = 0;
    while (b < kLatencyBuckets.size() && sec > kLatencyBuckets[b]) ++b;
    latency_bucket[b].fetch_add(1, kRelaxed);
    latency_count.fetch_add(1, kRelaxed);
    latency_sum_ns.fetch_add(lat, kRelaxed);
  }
  switch (s.topic) {
    case dds::Topic::kEstimatorTorque: {
      const auto& e = s.u.estimator;
      if (e.method < dds::kMethodCount) {
        auto& m = method[e.method];
        m.value.store(e.value_nm, kRelaxed);
        m.uncertainty.store(e.uncertainty, kRelaxed);
        m.health.store(e.health, kRelaxed);
        m.at_ns.store(now, kRelaxed);
        m.samples.fetch_add(1, kRelaxed);
      }
      break;
    }
    case dds::Topic::kEngineTorque: {
      const auto& e = s.u.engine;
      auto& x = engine[e.kind == torque_KIND_CYCLE ? 1 : 0];
      x.brake.store(e.brake_nm, kRelaxed);
      x.indicated.store(e.indicated_nm, kRelaxed);
      x.friction.store(e.friction_nm, kRelaxed);
      x.load.store(e.load_nm, kRelaxed);
      x.fused.store(e.fused_nm, kRelaxed);
      x.quality.store(e.quality, kRelaxed);
      x.at_ns.store(now, kRelaxed);
      x.samples.fetch_add(1, kRelaxed);
      break;
    }
    case dds::Topic::kDaemonStatus:
      status.store(s.u.status);
      failed.store(s.u.status.health == torque_DAEMON_FAILED, kRelaxed);
      if (s.u.status.flags & torque_STATUS_REPLAY_DONE) replay_done.store(true, kRelaxed);
      break;
    case dds::Topic::kCrankState:
      sync_state.store(s.u.crank.sync, kRelaxed);
      crank_samples.fetch_add(1, kRelaxed);
      break;
    default:
      break;
  }
  next_.emit(s);
}

class MetricsServer::Collector final : public prometheus::Collectable {
 public:
  explicit Collector(const MetricsServer& m) : m_(m) {}
  std::vector<MetricFamily> Collect() const override { return m_.collect(); }

 private:
  const MetricsServer& m_;
};

MetricsServer::MetricsServer(SampleSink& next, std::string state_file)
    : tap_(next), state_file_(std::move(state_file)) {}

MetricsServer::~MetricsServer() {
  exposer_.reset();  // stops the HTTP threads before the collector and the tap go
}

namespace {
/// CivetWeb options of the endpoint. A peer that holds a connection (silent, or trickling header lines) holds
/// one worker only until request_timeout_ms; kWorkers of them keep scrapes served while a few are held (the
/// finding: 2 workers without time-outs served 0 of 4 scrapes while two connections were held). Keep-alive
/// is off: a scraper reconnects, an idle connection holds no worker.
std::vector<std::string> server_options(const std::string& address) {
  constexpr int kWorkers = 8;
  constexpr int kRequestTimeoutMs = 2000;  // whole request head, and each write to a peer that does not read
  return {"listening_ports",    address,
          "num_threads",        std::to_string(kWorkers),
          "request_timeout_ms", std::to_string(kRequestTimeoutMs),
          "enable_keep_alive",  "no"};
}
}  // namespace

std::unique_ptr<MetricsServer> MetricsServer::start(const MetricsConfig& cfg, SampleSink& next,
                                                    std::string state_file, std::string* error) {
  auto m = std::make_unique<MetricsServer>(next, std::move(state_file));
  try {
    m->exposer_ = std::make_unique<prometheus::Exposer>(server_options(cfg.address));
  } catch (const std::exception& e) {
    if (error) *error = "metrics.address " + cfg.address + ": cannot listen (" + e.what() + ")";
    return nullptr;
  }
  m->collector_ = std::make_shared<Collector>(*m);
  m->exposer_->RegisterCollectable(m->collector_);
  return m;
}

int MetricsServer::port() const {
  if (!exposer_) return 0;
  const auto ports = exposer_->GetListeningPorts();
  return ports.empty() ? 0 : ports.front();
}

std::vector<MetricFamily> MetricsServer::collect() const {
  std::vector<MetricFamily> out;
  single(out, "torqued_up", "1 while the daemon serves metrics (labels: version)", MetricType::Gauge, 1);
  out.back().metric.back().label = {{"version", TORQUED_VERSION}};
  torque_DaemonStatus s{};
  bool have = false;
  {
    const std::lock_guard<std::mutex> lock(mu_);
    torque_DaemonStatus fresh;
    if (tap_.status.load_new(fresh)) {
      status_ = fresh;
      have_status_ = true;
    }
    s = status_;
    have = have_status_;
  }
  if (tap_.replay_done.load(kRelaxed)) s.flags |= torque_STATUS_REPLAY_DONE;  // a state: kept once seen
  status_families(s, have, out);
  tap_families(tap_, out);
  state_families(state_file_, out);
  return out;
}

std::string to_text(const std::vector<MetricFamily>& families) {
  return prometheus::TextSerializer().Serialize(families);
}

}  // namespace torqued::metrics
