#pragma once
// Prometheus metrics of the daemon (config metrics.*; docs/daemon.md "Metrics"). Off by default.
//
// Who writes what:
//   - MetricsTap (a SampleSink in front of the final output) sees every sample on the publisher thread
//   (paced/
//     live) or the fast replay loop: per-method last value/uncertainty/health, engine torque, crank sync
//     state and the ingest -> publish latency histogram. Relaxed atomics only: no allocation, no lock, no
//     blocking.
//   - the DaemonStatus samples the supervisor builds pass through the same tap (on their way to DDS): the
//   newest
//     is kept in a seqlock slot (LatestValue), so the supervisor needs no hook of its own.
//   - the HTTP threads of prometheus-cpp (civetweb) build the exposition on each scrape from those, plus the
//     age of the learned-state file (its mtime). The real-time threads never see this module.
// Values of one method (value, uncertainty, health) are read one by one: a scrape may mix two consecutive
// samples of that method, never a torn number.
#include <prometheus/metric_family.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "config.hpp"
#include "latest_value.hpp"
#include "methods.hpp"
#include "sample_sink.hpp"
#include "topics.hpp"

namespace prometheus {
class Exposer;
}  // namespace prometheus

namespace torqued::metrics {

/// Upper bounds (s) of the latency histogram buckets (+Inf implied).
inline constexpr std::array<double, 12> kLatencyBuckets = {25e-6,  50e-6, 100e-6, 250e-6, 500e-6, 1e-3,
                                                           2.5e-3, 5e-3,  10e-3,  25e-3,  50e-3,  100e-3};
inline constexpr int kEngineKinds = 2;  ///< KIND_SEGMENT, KIND_CYCLE
/// A torque gauge without a new sample for this long (wall clock) reads NaN (stale), as does every torque
/// gauge while the daemon's health is failed: a scrape never shows a frozen last value as current. Two status
/// periods: the slowest per-cycle output (cranking, ~150 rpm: 0.8 s per cycle) refreshes well within it.
inline constexpr std::int64_t kStaleAfterNs = 2'000'000'000;

class MetricsTap final : public SampleSink {
 public:
  explicit MetricsTap(SampleSink& next) noexcept : next_(next) {}
  void emit(const dds::AnySample& s) noexcept override;
  void flush() noexcept override { next_.flush(); }

  struct Method {
    std::atomic<double> value{0.0}, uncertainty{0.0};
    std::atomic<std::uint32_t> health{0};
    std::atomic<std::uint64_t> samples{0};
    std::atomic<std::int64_t> at_ns{0};  ///< CLOCK_REALTIME of the newest sample (staleness)
  };
  struct Engine {
    std::atomic<double> brake{0.0}, indicated{0.0}, friction{0.0}, load{0.0}, fused{0.0};
    std::atomic<std::uint32_t> quality{0};
    std::atomic<std::uint64_t> samples{0};
    std::atomic<std::int64_t> at_ns{0};  ///< CLOCK_REALTIME of the newest sample (staleness)
  };
  std::array<Method, dds::kMethodCount> method;
  std::array<Engine, kEngineKinds> engine;
  std::atomic<bool> failed{false};  ///< the newest DaemonStatus says health failed
  std::atomic<bool> replay_done{
      false};  ///< a DaemonStatus said REPLAY_DONE (stays set: a state, not an event)
  std::atomic<std::int32_t> sync_state{-1};  ///< CrankState.sync of the newest sample (-1: none yet)
  std::atomic<std::uint64_t> crank_samples{0};
  std::array<std::atomic<std::uint64_t>, kLatencyBuckets.size() + 1> latency_bucket{};  ///< not cumulative
  std::atomic<std::uint64_t> latency_count{0};
  std::atomic<std::int64_t> latency_sum_ns{0};
  LatestValue<torque_DaemonStatus>
      status;  ///< newest DaemonStatus (single reader: MetricsServer, under its mutex)

 private:
  SampleSink& next_;
};

/// The endpoint: owns the tap and the HTTP server.
class MetricsServer {
 public:
  /// Starts serving on cfg.address. nullptr and *error set when the address cannot be bound.
  static std::unique_ptr<MetricsServer> start(const MetricsConfig& cfg, SampleSink& next,
                                              std::string state_file, std::string* error);
  ~MetricsServer();
  MetricsServer(const MetricsServer&) = delete;
  MetricsServer& operator=(const MetricsServer&) = delete;

  /// Put this sink where `next` was: it records and forwards every sample.
  [[nodiscard]] SampleSink& sink() noexcept { return tap_; }
  /// The families a scrape returns (also used by the unit test, without HTTP).
  [[nodiscard]] std::vector<prometheus::MetricFamily> collect() const;
  /// The port actually bound (address ...:0 picks a free one).
  [[nodiscard]] int port() const;

  /// Not started: for tests of collect() without a listening socket.
  MetricsServer(SampleSink& next, std::string state_file);

 private:
  class Collector;
  mutable MetricsTap tap_;  // mutable: reading its status slot advances the reader's sequence
  std::string state_file_;
  mutable std::mutex mu_;                 ///< the HTTP threads' side: one reader of tap_.status at a time
  mutable torque_DaemonStatus status_{};  ///< newest DaemonStatus seen by a scrape
  mutable bool have_status_ = false;
  std::shared_ptr<Collector> collector_;
  std::unique_ptr<prometheus::Exposer> exposer_;
};

/// Text exposition of families (what GET /metrics returns).
[[nodiscard]] std::string to_text(const std::vector<prometheus::MetricFamily>& families);

}  // namespace torqued::metrics
