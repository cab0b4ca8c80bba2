#include "daemon_run.hpp"

#include <signal.h>
#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <memory>
#include <optional>
#include <thread>

#include "angle_stage.hpp"
#include "backend_factory.hpp"
#include "clocks.hpp"
#include "config.hpp"
#include "config_loader.hpp"
#include "dds_publisher.hpp"
#include "fast_replay.hpp"
#include "logging.hpp"
#include "looping_source.hpp"
#include "metrics.hpp"
#include "output_fanout.hpp"
#include "replay_inputs.hpp"
#include "rt_setup.hpp"
#include "runtime.hpp"
#include "sample_recorder.hpp"
#include "sd_notify.hpp"
#include "sink_thread.hpp"
#include "stage_settings.hpp"
#include "state_store.hpp"
#include "supervisor.hpp"
#include "table_store.hpp"

namespace torqued {
namespace {

// Set by SIGINT/SIGTERM during a fast replay. An atomic, not a volatile: with the read-ahead and writer
// threads the handler may run on another thread than the chain's, which reads it (lock-free, so safe in a
// handler).
std::atomic<bool> g_fast_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free);
void on_fast_signal(int) { g_fast_stop.store(true, std::memory_order_relaxed); }

void wait_for_subscribers(DdsPublisher& pub, const RunOptions& opt) {
  if (opt.wait_subscribers <= 0) return;
  const auto until =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(opt.wait_subscribers_timeout_s);
  while (pub.matched_readers(dds::Topic::kEngineTorque) < opt.wait_subscribers &&
         std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const int n = pub.matched_readers(dds::Topic::kEngineTorque);
  if (n < opt.wait_subscribers)
    spdlog::warn("only {} of {} subscribers matched after {} s; starting anyway", n, opt.wait_subscribers,
                 opt.wait_subscribers_timeout_s);
  else
    spdlog::info("{} subscriber(s) matched", n);
  // Readers matched on one topic; give discovery a moment to finish matching the others.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
}

/// Logs a failed recording (once per call site) and returns whether it failed.
bool recording_failed(const dds::SampleRecorder* rec) {
  if (!rec || !rec->write_failed()) return false;
  spdlog::error("recording: {}; {} rows not recorded", rec->error(), rec->rows_dropped());
  return true;
}

int run_fast(const StageSettings& s, const Config& cfg, const RunOptions& opt, EdgeSource* edges,
             CanSource* can, const DbcDatabase* dbc, SampleSink& out) {
  struct sigaction sa {};
  sa.sa_handler = on_fast_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  sd_notify_state("READY=1\nSTATUS=fast replay running");
  // Learned state as in the service: loaded at start, saved at the end (--state-dir / output.state_dir).
  const std::string spath = state_path(cfg, opt);
  const StateContext sctx = state_context_from(cfg);
  RestoreResult rs;
  if (!spath.empty()) rs = restore_for_run(spath, sctx, opt);
  LearnedState st = rs.state ? *rs.state : LearnedState{};
  const ReplayResult r = run_fast_replay(s, edges, can, can_time_offset_ns(cfg), dbc, out, &g_fast_stop,
                                         spath.empty() ? nullptr : &st);
  if (!r.error.empty()) spdlog::error("replay: {}", r.error);
  if (r.threads.threads == 3)
    spdlog::debug("reader thread: the replay waited for it {} times", r.input_waits);
  for (const auto& p : r.input_problems) spdlog::warn("{}", p);
  for (const auto& b : r.bad_frames) spdlog::warn("can: {}", b);
  for (const DecoderEvent& e : r.transitions.events) log_transition(e);
  if (r.transitions.not_kept > 0)
    spdlog::debug("decoder: {} more transitions not logged", r.transitions.not_kept);
  if (!spath.empty()) {
    spdlog::info("learned state applied at start: {}", r.imported.empty() ? "nothing" : r.imported);
    if (r.counters.tooth_tables_distrusted > 0)
      spdlog::warn(
          "learned state: the imported tooth table disagreed with this engine's teeth and was "
          "discarded (relearned from this run)");
    std::string serr;
    st.saved_at_t_ns = r.last_t_ns;
    st.identity = sctx.identity;  // the chain's state is this configuration's engine and wheel
    if (r.learned && rs.may_save) {
      if (check_state(st, sctx, spath, &serr) && save_state_atomic(spath, st, sctx.identity, &serr))
        spdlog::info("learned state saved to {}", spath);
      else
        spdlog::warn("learned state not saved: {}", serr);
    }
  }
  const double rec_s = static_cast<double>(r.last_t_ns - r.first_t_ns) * 1e-9;
  spdlog::info(
      "fast replay: {:.3f} s of recording in {:.3f} s ({:.0f}x real time), {} edges, {} teeth, {} cycles, "
      "{} CAN frames, {} samples, {} sync losses, {} source drops",
      rec_s, r.wall_s, r.speedup(), r.counters.edges, r.counters.teeth, r.counters.cycles,
      r.counters.can_frames, r.samples, r.counters.sync_losses, r.counters.source_drops);
  return r.error.empty() ? 0 : 1;
}

}  // namespace

namespace {
// replay.loop (paced replay of files): the sources restart at their end, shifted by one common period.
bool loop_inputs(const Config& cfg, RunInputs& in) {
  const bool files = cfg.inputs.edges.backend == EdgeBackend::kFile &&
                     (!in.can || cfg.inputs.can.backend == CanBackend::kFile);
  if (!files) {
    spdlog::warn("replay.loop: ignored (only file inputs can be looped)");
    return true;
  }
  const std::int64_t period_ns = loop_period_ns(*in.edges, in.can.get(), in.can_offset_ns);
  if (period_ns <= 0) {
    spdlog::warn("replay.loop: ignored (fewer than two edges in {})", cfg.inputs.edges.path);
    return true;
  }
  const auto open_edges = [cfg] {
    std::string e;
    return make_edge_source(cfg, &e);
  };
  in.edges = std::make_unique<LoopingEdgeSource>(open_edges, period_ns);
  if (in.can) {
    const auto open_can = [cfg] {
      std::string e;
      return make_can_source(cfg, &e);
    };
    in.can = std::make_unique<LoopingCanSource>(open_can, period_ns);
  }
  spdlog::info("replay.loop: the recording restarts every {:.3f} s of recording time",
               static_cast<double>(period_ns) * 1e-9);
  return true;
}
/// The DBC file's warnings, the first kMaxDbcWarnings of them logged and the rest counted.
void log_dbc_warnings(const std::vector<std::string>& warnings) {
  constexpr std::size_t kMaxDbcWarnings = 20;  // then counted
  for (std::size_t i = 0; i < warnings.size() && i < kMaxDbcWarnings; ++i) spdlog::warn("{}", warnings[i]);
  if (warnings.size() > kMaxDbcWarnings)
    spdlog::warn("can.dbc: {} more warnings not shown", warnings.size() - kMaxDbcWarnings);
}

/// The DDS publisher, created on a thread with the publisher's scheduling (Cyclone's threads inherit it: see
/// ScopedThreadRt; refused: as before), then waiting for --wait-subscribers; nullptr (logged) when DDS
/// failed.
std::unique_ptr<DdsPublisher> open_publisher(const Config& cfg, const StageSettings& s, const RunOptions& opt,
                                             bool fast) {
  std::unique_ptr<DdsPublisher> publisher;
  {
    const ScopedThreadRt as_publisher(fast ? ThreadRt{} : thread_rt(cfg.realtime.publisher, ""));
    publisher = std::make_unique<DdsPublisher>(s.dds, /*stamp_times=*/!fast);
  }
  if (!publisher->ok()) {
    spdlog::critical("dds: {}", publisher->error());
    return nullptr;
  }
  spdlog::info("DDS domain {} topics {}/* engine_id {}", s.dds.domain_id, s.dds.topic_prefix,
               s.dds.engine_id);
  if (const std::string shm = publisher->shared_memory_topics(); !shm.empty())
    spdlog::info("DDS shared memory (iceoryx) for: {}", shm);
  wait_for_subscribers(*publisher, opt);
  return publisher;
}
}  // namespace

int run_daemon(const Config& cfg_in, const RunOptions& opt) {
  Config cfg = cfg_in;
  // Before any thread exists (Cyclone's included): stacks of kThreadStackBytes, not 8 MiB each made resident
  // by mlockall.
  if (const RtOutcome st = set_default_thread_stack(); !st.ok) spdlog::warn("thread stacks: {}", st.message);
  if (opt.record_dir) cfg.output.record_dir = *opt.record_dir;
  // Start-up tables (Kalman gains, load RLS integrals) from the previous run when they match
  // (table_store.hpp).
  TableStore tables(
      table_dir_for(cfg.output.table_dir, opt.state_dir ? *opt.state_dir : cfg.output.state_dir), 0,
      [](const std::string& m, bool warning) {
        if (warning)
          spdlog::warn("{}", m);
        else
          spdlog::info("{}", m);
      });
  const ScopedTableCache tables_in_use(tables.dir().empty() ? nullptr : &tables);
  const bool fast = opt.mode ? *opt.mode == "fast" : cfg.replay.mode == ReplayMode::kFast;
  RunInputs in = open_inputs(cfg);
  log_dbc_warnings(in.dbc_warnings);
  if (!in.ok()) {
    spdlog::critical("{}", in.error);
    return 1;
  }
  if (!fast && cfg.replay.loop && !loop_inputs(cfg, in)) return 1;
  StageSettings& s = in.settings;
  std::unique_ptr<EdgeSource>& edges = in.edges;
  std::unique_ptr<CanSource>& can = in.can;
  std::optional<DbcDatabase>& dbc = in.dbc;
  spdlog::info("edges: {}", edges->describe());
  if (can) spdlog::info("can: {}", can->describe());

  std::unique_ptr<dds::SampleRecorder> recorder;
  if (!cfg.output.record_dir.empty()) {
    recorder = std::make_unique<dds::SampleRecorder>(cfg.output.record_dir);
    if (!recorder->ok()) {
      spdlog::critical("output.record_dir: {}", recorder->error());
      return 1;
    }
    spdlog::info("recording CSV to {}", cfg.output.record_dir);
  }
  std::unique_ptr<DdsPublisher> publisher;
  if (!opt.no_dds && !(publisher = open_publisher(cfg, s, opt, fast))) return 1;
  OutputFanout fanout(recorder.get(), publisher.get(), s.dds.engine_id);
  // Metrics (metrics.enabled, service/metrics.hpp): a tap in front of the output, served by its own threads.
  std::unique_ptr<metrics::MetricsServer> metrics;
  if (cfg.metrics.enabled) {
    std::string merr;
    metrics = metrics::MetricsServer::start(cfg.metrics, fanout, state_path(cfg, opt), &merr);
    if (!metrics) {
      spdlog::critical("{}", merr);
      return 1;
    }
    spdlog::info("metrics: http://{}/metrics", cfg.metrics.address);
  }
  SampleSink& out = metrics ? metrics->sink() : static_cast<SampleSink&>(fanout);

  if (fast) {
    const FastThreadsChoice threads = resolve_fast_threads(s.fast_threads, usable_cpus());
    s.fast_threads = threads.threads;  // run_fast_replay uses what is logged here
    spdlog::info("fast replay threads: {} ({})",
                 threads.threads == 1 ? "one (inputs, chain and recording on one thread)"
                 : recorder           ? "reader, chain, recording writer"
                                      : "reader, chain (no recording to write)",
                 threads.why);
    // With three threads the recording is formatted and written on a thread of its own (sink_thread.hpp: same
    // samples, same order, the replay waits when that thread falls behind); the replay's timed loop ends once
    // it has written all.
    std::optional<SinkThread> writer;
    if (recorder && threads.threads == 3) writer.emplace(out);
    const int rc = run_fast(s, cfg, opt, edges.get(), can.get(), dbc ? &*dbc : nullptr,
                            writer ? static_cast<SampleSink&>(*writer) : out);
    if (writer) {
      writer->flush();
      spdlog::debug("recording thread: {} samples, the replay waited for it {} times, {} dropped",
                    writer->written(), writer->waits(), writer->drops());
    }
    if (recorder) recorder->flush(true);
    return recording_failed(recorder.get()) ? std::max(rc, 3) : rc;
  }

  const int rc = run_supervised(cfg, opt, in, recorder.get(), out);
  if (publisher)
    spdlog::info("dds: {} samples written ({} through shared-memory loans), {} write errors",
                 publisher->written(), publisher->loaned_writes(), publisher->write_errors());
  return rc;
}

}  // namespace torqued
