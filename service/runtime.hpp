#pragma once
// Paced replay / live runtime: the threads of docs/architecture.md.
//   source thread(s)  replay: merger + pacer (one thread keeps edge/CAN order); live: one per source.
//                     -> edge ring -> angle thread;  CAN -> one ring per consumer (angle, time)
//   angle thread      SCHED_FIFO: AngleStage per edge; tooth samples -> tooth ring -> time thread
//   time thread       SCHED_FIFO, timerfd at the time pipeline rate: TimeStage::step
//   publisher thread  SCHED_OTHER: the only DDS caller; drains the output rings into the OutputFanout
// The supervisor is the caller's thread (daemon_run.cpp): it polls counters(), pushes status samples with
// push_status(), pings the watchdog while heartbeats() advance, and stops/drains on signals.
// Every buffer is allocated in the constructor; the real-time threads never allocate, lock or wait for DDS.
#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "dbc.hpp"
#include "estimate.hpp"
#include "latency_histogram.hpp"
#include "latest_value.hpp"
#include "replay_clock.hpp"
#include "rt_setup.hpp"
#include "sample_sink.hpp"
#include "source.hpp"
#include "spsc_ring.hpp"
#include "stage_settings.hpp"
#include "status.hpp"
#include "wakeup.hpp"

namespace torqued {

class AngleStage;
class TimeStage;

struct RuntimeOptions {
  double speed = 1.0;  ///< replay speed factor (paced replay); ignored for live sources
  bool replay = true;  ///< file sources paced by their timestamps (false: live sources)
  bool lock_memory = true;
  bool lock_on_fault = false;  ///< mlockall(... | MCL_ONFAULT): lock pages when first touched
  bool require_rt = false;     ///< start() fails when SCHED_FIFO/mlockall are not permitted
  ThreadRt angle{true, 80, {}, "torqued-angle"};
  ThreadRt time{true, 70, {}, "torqued-time"};
  ThreadRt source{true, 85, {}, "torqued-source"};
  ThreadRt publisher{true, 60, {}, "torqued-pub"};
  /// Paced replay: the publisher sleeps until the next edge's due time (which the angle thread announces) and
  /// then polls its rings for up to this long, so the samples of that edge find it awake (0 = always futex
  /// wake-ups).
  std::int64_t publisher_spin_ns = 0;
  std::size_t edge_ring = 1 << 16, can_ring = 1 << 12, tooth_ring = 1 << 13, out_ring = 1 << 13;
  /// `torqued --stage-trace`: keep the stamps (StageStamps) of up to this many CrankState samples (0: off;
  /// then no stamp is taken and nothing is allocated for them).
  std::size_t stage_trace = 0;
  /// Test hook: called on each real-time thread right after its set-up and right before it exits.
  std::function<void(const char* thread, bool exiting)> rt_thread_hook;
};

/// One CrankState sample's way through the daemon (CLOCK_REALTIME ns), kept for `torqued --stage-trace` so
/// `torque-latency` can split edge -> dds_write into its stages for the samples of its tail (joined on seq).
struct StageStamps {
  std::uint64_t seq = 0;        ///< CrankState seq (the subscriber's sample has it too)
  std::int64_t ingest_ns = 0;   ///< the edge's due time (ingest_t_ns)
  std::int64_t angle_ns = 0;    ///< the angle thread takes the edge (after its wake-up)
  std::int64_t pushed_ns = 0;   ///< the sample pushed into the output ring
  std::int64_t taken_ns = 0;    ///< the publisher takes it from the ring
  std::int64_t written_ns = 0;  ///< dds_write (and the recorder, if any) returned
};

/// Liveness counters of the threads (monotonic; the supervisor pings the watchdog only while they move).
struct Heartbeats {
  std::uint64_t angle = 0, time = 0, publisher = 0;
};

class Runtime {
 public:
  Runtime(const StageSettings& s, const RuntimeOptions& opt, EdgeSource* edges, CanSource* can,
          std::int64_t can_offset_ns, const DbcDatabase* dbc, SampleSink& final_out);
  ~Runtime();
  Runtime(const Runtime&) = delete;
  Runtime& operator=(const Runtime&) = delete;

  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }

  /// Locks memory and starts the threads. Returns false (error()) only when RT is required but refused, or
  /// a thread could not start. Warnings (RT refused, running anyway) in warnings(); flags in counters().
  bool start();
  [[nodiscard]] const std::vector<std::string>& warnings() const noexcept { return warnings_; }

  /// Stops the sources, lets the pipelines drain the rings and the publisher write everything, joins.
  /// Returns false when the drain did not finish within timeout_ns (threads are stopped anyway).
  bool stop_and_drain(std::int64_t timeout_ns);

  /// SIGHUP (supervisor thread): hand new tunables to the angle and time threads, which apply them before
  /// their next event. Waits (up to timeout_ns) for a previous request to be taken; false if it was not.
  bool request_tunables(const RuntimeTunables& t, std::int64_t timeout_ns = 500'000'000);

  /// All input consumed (replay reached the end of its files and the rings are empty).
  [[nodiscard]] bool input_done() const noexcept;
  /// The sources' own messages about their input (input_problems()); only once input_done() or after
  /// stop_and_drain() (the source threads have finished writing them).
  [[nodiscard]] std::vector<std::string> input_problems() const;
  [[nodiscard]] RuntimeCounters counters() const noexcept;
  /// Page faults and context switches of each runtime thread between its start (after its scheduling and
  /// stack pre-fault) and its end; complete once the threads have ended (stop_and_drain()).
  struct ThreadRunUsage {
    std::string name;
    ThreadUsage use;
  };
  [[nodiscard]] std::vector<ThreadRunUsage> thread_usage() const;
  [[nodiscard]] Heartbeats heartbeats() const noexcept;
  /// Newest edge-clock time processed by the angle stage.
  [[nodiscard]] std::int64_t last_source_t_ns() const noexcept {
    return last_t_ns_.load(std::memory_order_relaxed);
  }
  /// Supervisor -> publisher (status samples). Non-blocking.
  void push_status(const dds::AnySample& s) noexcept;
  /// The stamps kept with RuntimeOptions::stage_trace, in publishing order; complete after stop_and_drain().
  [[nodiscard]] const std::vector<StageStamps>& stage_trace() const noexcept { return trace_; }
  /// Test-only: freeze the angle thread (it stops making progress) to check the watchdog stops pinging.
  void test_stall(bool on) noexcept { stall_.store(on, std::memory_order_relaxed); }
  /// Applies learned tooth corrections in the angle thread at its next wake-up (copied; not real-time).
  [[nodiscard]] AngleStage& angle_stage() noexcept { return *angle_; }

 private:
  struct EdgeIn {
    EdgeEvent e;
    std::int64_t ingest_ns;
  };
  struct FrameIn {
    CanFrame f;
    std::int64_t ingest_ns;
  };
  /// Angle thread -> publisher (stage trace only): a CrankState's stamps taken before it was pushed.
  struct AngleStamps {
    std::uint64_t seq;
    std::int64_t angle_ns, pushed_ns;
  };
  class RingSink;
  class ToothRingSink;

  void replay_source_loop();
  void live_edge_loop();
  void live_can_loop();
  /// One-slot mailbox from the supervisor to one real-time thread: the writer fills `value` only while `full`
  /// is 0 and then publishes it (release); the reader copies it (acquire) and clears `full`. No lock, no
  /// allocation.
  struct TunablesMailbox {
    RuntimeTunables value;
    std::atomic<int> full{0};
  };
  void angle_loop();
  struct DueItem {
    std::int64_t due = 0;  ///< CLOCK_MONOTONIC due time of the first item not processed yet (0: none)
    bool tooth = false;    ///< it is a crank tooth edge
  };
  DueItem angle_process_due() noexcept;
  DueItem next_wakeup(const EdgeEvent& first, std::int64_t first_due) noexcept;
  bool edge_may_emit(const EdgeEvent& e, bool& prev_active) const noexcept;
  bool last_crank_active_ = false;  ///< angle thread: the last crank edge processed had the wheel's polarity
  void angle_check_edge_timeout() noexcept;
  void angle_publish_counters() noexcept;
  static constexpr std::int64_t kReadAheadNs =
      20'000'000;  ///< paced replay: source reads this far ahead (wall)
  static constexpr std::int64_t kReplayStartNs =
      2'000'000;  ///< paced replay: first item due this long after start
  void time_loop();
  void publisher_loop();
  bool drain_out() noexcept;
  void trace_crank(const dds::AnySample& s, std::int64_t taken_ns, std::int64_t written_ns) noexcept;
  void take_latency_period() noexcept;
  void start_thread(std::thread& t, const ThreadRt& rt, void (Runtime::*fn)(), bool realtime);

  StageSettings s_;
  RuntimeOptions opt_;
  EdgeSource* edges_;
  CanSource* can_;
  std::int64_t can_offset_ns_;
  SampleSink& final_out_;
  std::string error_;
  std::vector<std::string> warnings_;

  SpscRing<EdgeIn> edge_ring_;
  SpscRing<FrameIn> can_angle_ring_, can_time_ring_;
  SpscRing<ToothSample> tooth_ring_;
  SpscRing<dds::AnySample> out_angle_ring_, out_time_ring_, out_status_ring_;
  Wakeup angle_wake_, pub_wake_;
  std::unique_ptr<RingSink> angle_sink_, time_sink_;
  std::unique_ptr<ToothRingSink> tooth_sink_;
  std::unique_ptr<AngleStage> angle_;
  std::unique_ptr<TimeStage> time_;

  std::thread src_thread_, src2_thread_, angle_thread_, time_thread_, pub_thread_;
  static constexpr int kMaxThreads = 8;
  std::array<ThreadUsage, kMaxThreads> usage_{};  ///< written once by each thread as it ends
  std::array<std::array<char, 16>, kMaxThreads> usage_name_{};
  std::atomic<int> usage_n_{0};
  std::atomic<bool> stop_sources_{false}, stop_pipelines_{false}, stop_publisher_{false}, stall_{false};
  std::atomic<int> sources_running_{0};
  TunablesMailbox angle_tunables_, time_tunables_;
  std::atomic<std::int64_t> edge_timeout_ns_{0};
  std::atomic<std::int64_t> next_due_mono_ns_{
      0};  ///< paced replay: due time of the edge the angle thread waits for
  std::atomic<bool> next_due_tooth_{false};      ///< ... and whether it is a crank tooth edge
  std::atomic<std::uint64_t> angle_wakeups_{0};  ///< times the angle thread went to sleep (timer or futex)
  std::atomic<std::uint64_t> pub_polls_{0}, pub_poll_misses_{0};  ///< pre-wakes, and those that saw no sample
  ReplayClock clock_;  ///< recording time ↔ monotonic time (replay and live edge clock)
  LatestValue<TorqueEstimate> time_estimate_;  ///< time thread → angle thread: UIO brake estimate (fusion)
  std::atomic<std::uint32_t> flags_{0};

  // Counters published by the threads (relaxed atomics; read by the supervisor).
  std::atomic<std::uint64_t> hb_angle_{0}, hb_time_{0}, hb_pub_{0};
  std::atomic<std::uint64_t> n_edges_{0}, teeth_{0}, frames_{0}, cycles_{0}, sync_losses_{0}, overruns_{0};
  std::uint64_t angle_frames_ = 0;  ///< CAN frames given to the angle chain (angle thread only)
  std::atomic<std::uint64_t> source_drops_{0}, stale_mask_{0}, rejected_edges_{0}, cam_phase_errors_{0};
  std::atomic<std::uint32_t> fuel_refs_{0};   ///< fuel-model references (DaemonStatus.fuel_references)
  std::atomic<std::uint16_t> fuel_cells_{0};  ///< its learned speed × MAP cells (DaemonStatus.fuel_cells)
  std::atomic<std::uint8_t> burn_state_{0};   ///< burn-phasing learner state (DaemonStatus.burn_phase_state)
  std::atomic<double> burn_offset_deg_{0.0};  ///< its offset (DaemonStatus.burn_phase_offset_deg)
  std::atomic<bool> synced_{false}, edge_timeout_{false};
  std::atomic<std::int64_t> last_t_ns_{0};
  std::atomic<std::int64_t> lat_p50_{0}, lat_p99_{0}, lat_max_{0};
  std::atomic<std::int64_t> lat_run_p50_{0}, lat_run_p99_{0}, lat_run_max_{0};
  LatencyHistogram latency_;          ///< publisher thread only
  std::int64_t angle_take_ns_ = 0;    ///< stage trace: when the angle thread took the edge it is processing
  SpscRing<AngleStamps> stamp_ring_;  ///< stage trace: angle thread -> publisher (2 slots when off)
  std::vector<StageStamps> trace_;    ///< stage trace: publisher thread only, reserved in the constructor
  std::int64_t lat_period_start_ns_ = 0;
};

}  // namespace torqued
