#include "daemon_run.hpp"

#include <signal.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <memory>
#include <thread>

#include "angle_stage.hpp"
#include "backend_factory.hpp"
#include "clocks.hpp"
#include "config.hpp"
#include "config_loader.hpp"
#include "dds_publisher.hpp"
#include "fast_replay.hpp"
#include "replay_inputs.hpp"
#include "logging.hpp"
#include "metrics.hpp"
#include "output_fanout.hpp"
#include "rt_setup.hpp"
#include "runtime.hpp"
#include "sample_recorder.hpp"
#include "stage_settings.hpp"
#include "state_store.hpp"

namespace torqued {
namespace {

volatile bool g_fast_stop = false;
void on_fast_signal(int) { g_fast_stop = true; }

std::string state_path(const Config& cfg, const RunOptions& opt) {
  const std::string dir = opt.state_dir ? *opt.state_dir : cfg.output.state_dir;
  return dir.empty() ? std::string() : dir + "/learned_state.txt";
}

/// The checked learned state of the previous run, as every mode loads it: identity, checksum and physical
/// bounds checked, rejected files set aside (state_store.hpp); nothing with --fresh-state. Logs what happened.
RestoreResult restore_for_run(const std::string& spath, const StateContext& ctx, const RunOptions& opt) {
  RestoreResult rs;
  if (opt.fresh_state)
    rs.infos.push_back("learned state not loaded (--fresh-state): learning from the prior; saved to " + spath);
  else
    rs = restore_learned_state(spath, ctx);
  for (const auto& w : rs.warnings) spdlog::warn("{}", w);
  for (const auto& i : rs.infos) spdlog::info("{}", i);
  return rs;
}

ThreadRt thread_rt(const ThreadConfig& t, const char* name) {
  return ThreadRt{t.policy == SchedPolicy::kFifo, t.priority, t.cpus, name};
}

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

/// SIGHUP: reload the file; apply what is safe to change at run time, report the rest.
/// Applied live: logging.level; dds.crank_state_decimation, dds.time_estimator_decimation,
/// dds.tooth_estimator_decimation; inputs.edges.timeout_s; every can.signals.<q>.timeout_s (the real-time
/// threads take them between two events). Everything else (inputs, engine, wheel, DDS domain/QoS, estimator
/// tuning, realtime) needs a restart: reported, not applied.
void reload(const std::string& path, Config& current, StageSettings& settings, Runtime& rt) {
  const LoadResult r = load_config(path);
  if (!r.ok()) {
    for (const auto& e : r.errors) spdlog::error("SIGHUP: {}", e);
    spdlog::error("SIGHUP: configuration {} refused; keeping the running one", path);
    return;
  }
  const Config& n = *r.config;
  if (n.logging.level != current.logging.level) {
    spdlog::info("SIGHUP: logging.level {} -> {}", static_cast<int>(current.logging.level),
                 static_cast<int>(n.logging.level));
    logging::set_level(n.logging.level);
    current.logging = n.logging;
  }
  const RuntimeTunables was = tunables_of(settings);
  const RuntimeTunables now = tunables_of(stage_settings_from(n));
  if (now != was) {
    if (rt.request_tunables(now)) {
      apply_tunables(settings, now);
      spdlog::info(
          "SIGHUP: applied decimation crank/time/tooth {}/{}/{} -> {}/{}/{}, edge time-out {} -> {} ms, "
          "sensor time-outs {}",
          was.crank_decimation, was.time_decimation, was.tooth_estimator_decimation, now.crank_decimation,
          now.time_decimation, now.tooth_estimator_decimation, was.edge_timeout_ns / 1'000'000,
          now.edge_timeout_ns / 1'000'000,
          now.signal_timeout_ns == was.signal_timeout_ns ? "unchanged" : "changed");
    } else {
      spdlog::error(
          "SIGHUP: the pipelines did not take the new decimations/time-outs within 0.5 s; not applied");
    }
  }
  if (n.inputs.edges.path != current.inputs.edges.path || n.inputs.can.path != current.inputs.can.path ||
      n.dds.domain_id != current.dds.domain_id || n.dds.topic_prefix != current.dds.topic_prefix ||
      n.wheel.geometry.positions != current.wheel.geometry.positions ||
      n.engine.cylinders != current.engine.cylinders)
    spdlog::warn("SIGHUP: inputs/dds/engine/wheel changes need a restart; they are not applied");
  spdlog::info("SIGHUP: configuration {} reloaded", path);
}

void notify_status(const RuntimeCounters& c, double uptime_s) {
  sd_notifyf(
      0, "STATUS=%s; uptime %.0f s; edges %" PRIu64 " cycles %" PRIu64 " drops %" PRIu64 " overruns %" PRIu64,
      c.synced ? "synced" : "not synced", uptime_s, c.edges, c.cycles,
      c.ring_drops_edge + c.ring_drops_can + c.ring_drops_out, c.overruns);
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
  sd_notify(0, "READY=1\nSTATUS=fast replay running");
  // Learned state as in the service: loaded at start, saved at the end (--state-dir / output.state_dir).
  const std::string spath = state_path(cfg, opt);
  const StateContext sctx = state_context_from(cfg);
  RestoreResult rs;
  if (!spath.empty()) rs = restore_for_run(spath, sctx, opt);
  LearnedState st = rs.state ? *rs.state : LearnedState{};
  const ReplayResult r =
      run_fast_replay(s, edges, can, can_time_offset_ns(cfg), dbc, out, &g_fast_stop, spath.empty() ? nullptr : &st);
  if (!r.error.empty()) spdlog::error("replay: {}", r.error);
  if (!spath.empty()) {
    spdlog::info("learned state applied at start: {}", r.imported.empty() ? "nothing" : r.imported);
    std::string serr;
    st.saved_at_t_ns = r.last_t_ns;
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

int run_daemon(const Config& cfg_in, const RunOptions& opt) {
  Config cfg = cfg_in;
  if (opt.record_dir) cfg.output.record_dir = *opt.record_dir;
  const bool fast = opt.mode ? *opt.mode == "fast" : cfg.replay.mode == ReplayMode::kFast;
  const bool file_inputs = cfg.inputs.edges.backend == EdgeBackend::kFile;
  RunInputs in = open_inputs(cfg);
  constexpr std::size_t kMaxDbcWarnings = 20;  // then counted
  for (std::size_t i = 0; i < in.dbc_warnings.size() && i < kMaxDbcWarnings; ++i)
    spdlog::warn("{}", in.dbc_warnings[i]);
  if (in.dbc_warnings.size() > kMaxDbcWarnings)
    spdlog::warn("can.dbc: {} more warnings not shown", in.dbc_warnings.size() - kMaxDbcWarnings);
  if (!in.ok()) {
    spdlog::critical("{}", in.error);
    return 1;
  }
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
  if (!opt.no_dds) {
    {
      // Cyclone's threads inherit the publisher thread's scheduling (see ScopedThreadRt); refused: as before.
      const ScopedThreadRt as_publisher(fast ? ThreadRt{} : thread_rt(cfg.realtime.publisher, ""));
      publisher = std::make_unique<DdsPublisher>(s.dds, /*stamp_times=*/!fast);
    }
    if (!publisher->ok()) {
      spdlog::critical("dds: {}", publisher->error());
      return 1;
    }
    spdlog::info("DDS domain {} topics {}/* engine_id {}", s.dds.domain_id, s.dds.topic_prefix,
                 s.dds.engine_id);
    wait_for_subscribers(*publisher, opt);
  }
  OutputFanout fanout(recorder.get(), publisher.get(), s.dds.engine_id);
  // Metrics (metrics.enabled): a tap in front of the output, served by the endpoint's own threads.
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
    const int rc = run_fast(s, cfg, opt, edges.get(), can.get(), dbc ? &*dbc : nullptr, out);
    if (recorder) recorder->flush(true);
    return recording_failed(recorder.get()) ? std::max(rc, 3) : rc;
  }

  // ---- paced replay / live ----
  // Signals are handled synchronously by this (supervisor) thread; block them before any thread starts so
  // every thread inherits the mask.
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGTERM);
  sigaddset(&sigs, SIGINT);
  sigaddset(&sigs, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);

  RuntimeOptions ro;
  ro.replay = file_inputs && cfg.inputs.can.backend == CanBackend::kFile;
  ro.speed = opt.speed ? *opt.speed : cfg.replay.speed;
  ro.lock_memory = cfg.realtime.lock_memory;
  ro.require_rt = cfg.realtime.require_rt;
  ro.angle = thread_rt(cfg.realtime.angle, "torqued-angle");
  ro.time = thread_rt(cfg.realtime.time, "torqued-time");
  ro.source = thread_rt(cfg.realtime.source, "torqued-source");
  ro.publisher = thread_rt(cfg.realtime.publisher, "torqued-pub");
  ro.publisher_spin_ns = static_cast<std::int64_t>(cfg.realtime.publisher_spin_us) * 1000;
  Runtime rt(s, ro, edges.get(), can.get(), can_time_offset_ns(cfg), dbc ? &*dbc : nullptr, out);
  if (!rt.ok()) {
    spdlog::critical("{}", rt.error());
    return 1;
  }

  // Learned state from the previous run: checked (identity, checksum, bounds); rejected files are set aside.
  const std::string spath = state_path(cfg, opt);
  std::unique_ptr<StateSaver> saver;
  if (!spath.empty()) {
    const StateContext sctx = state_context_from(cfg);
    const RestoreResult rs = restore_for_run(spath, sctx, opt);
    if (rs.state) {
      const std::string what = rt.angle_stage().import_state(*rs.state);
      if (!what.empty()) spdlog::info("learned state loaded from {}: {}", spath, what);
    }
    if (rs.may_save) saver = std::make_unique<StateSaver>(spath, sctx);
  }

  if (!rt.start()) {
    spdlog::critical("start: {}", rt.error());
    return 1;
  }
  for (const auto& w : rt.warnings()) spdlog::warn("{}", w);
  const char* test_stall = std::getenv("TORQUED_TEST_STALL_AFTER_S");  // test-only hook (watchdog test)
  const double stall_after_s = test_stall ? std::atof(test_stall) : -1.0;

  std::uint64_t wd_usec = 0;
  const bool watchdog = sd_watchdog_enabled(0, &wd_usec) > 0 && wd_usec > 0;
  sd_notifyf(0, "READY=1\nSTATUS=running (%s)", ro.replay ? "paced replay" : "live");
  spdlog::info("running ({}), watchdog {}", ro.replay ? "paced replay" : "live",
               watchdog ? std::to_string(wd_usec / 1000) + " ms" : std::string("off"));

  const std::int64_t t0 = mono_ns();
  std::int64_t next_status = t0 + s.status_period_ns, next_ping = t0, next_save = t0;
  const std::int64_t ping_period = watchdog ? static_cast<std::int64_t>(wd_usec) * 1000 / 2 : 0;
  const std::int64_t save_period = static_cast<std::int64_t>(opt.state_save_period_s * 1e9);
  Heartbeats last_hb = rt.heartbeats();
  std::uint64_t status_seq = 0;
  bool done_reported = false;
  bool record_error_reported = false;
  int exit_code = 0;
  auto save = [&] {  // queued: the saver's thread writes (a slow disk never holds up this loop)
    if (!saver) return;
    for (const auto& e : saver->take_errors()) spdlog::warn("learned state not saved: {}", e);
    LearnedState st;
    if (!rt.angle_stage().export_state(st)) return;  // nothing learned yet
    st.saved_at_t_ns = rt.last_source_t_ns();
    saver->submit(std::move(st));
  };

  for (;;) {
    timespec tick{0, 50'000'000};
    siginfo_t si{};
    const int sig = sigtimedwait(&sigs, &si, &tick);
    if (sig == SIGTERM || sig == SIGINT) {
      spdlog::info("{}: draining and stopping", sig == SIGTERM ? "SIGTERM" : "SIGINT");
      break;
    }
    if (sig == SIGHUP) {
      sd_notify(0, "RELOADING=1");
      reload(opt.config_path, cfg, s, rt);
      sd_notify(0, "READY=1");
    }
    const std::int64_t now = mono_ns();
    if (stall_after_s >= 0 && now - t0 >= static_cast<std::int64_t>(stall_after_s * 1e9)) rt.test_stall(true);
    const bool done = rt.input_done();
    if (now >= next_status) {
      RuntimeCounters c = rt.counters();
      if (done && !done_reported) {
        c.flags |= torque_STATUS_REPLAY_DONE;
        done_reported = true;
      }
      const dds::AnySample status = make_status(c, ++status_seq, rt.last_source_t_ns(), now - t0);
      rt.push_status(status);
      if (metrics) metrics->on_status(status.u.status);
      notify_status(c, static_cast<double>(now - t0) * 1e-9);
      next_status += s.status_period_ns;
      if (done && c.flags & torque_STATUS_REPLAY_DONE) {  // once, at the end of a paced replay
        if (opt.exit_when_done || cfg.replay.exit_when_done) {
          spdlog::info("replay finished: input consumed; stopping (--exit-when-done / replay.exit_when_done)");
          break;
        }
        spdlog::info("replay finished: input consumed; still running (DaemonStatus flags REPLAY_DONE) until "
                     "SIGTERM/Ctrl-C, or set replay.exit_when_done / --exit-when-done to exit here");
      }
    }
    // Watchdog: ping only while every pipeline thread made progress since the last ping.
    if (watchdog && now >= next_ping) {
      const Heartbeats hb = rt.heartbeats();
      if (hb.angle != last_hb.angle && hb.time != last_hb.time && hb.publisher != last_hb.publisher) {
        sd_notify(0, "WATCHDOG=1");
        last_hb = hb;
      }
      next_ping = now + ping_period;
    }
    if (recorder && !record_error_reported && recorder->write_failed()) {  // at once; estimation goes on
      spdlog::error("recording: {}; estimation and DDS publishing continue", recorder->error());
      record_error_reported = true;
    }
    if (save_period > 0 && now >= next_save) {
      save();
      next_save = now + save_period;
    }
  }

  sd_notify(0, "STOPPING=1\nSTATUS=draining");
  const bool drained = rt.stop_and_drain(static_cast<std::int64_t>(opt.drain_timeout_s * 1e9));
  if (!drained) {
    spdlog::warn("drain did not finish within {} s", opt.drain_timeout_s);
    exit_code = 1;
  }
  save();
  if (saver && !saver->finish(opt.drain_timeout_s))
    spdlog::warn("learned state: the last save did not finish");
  if (saver)
    for (const auto& e : saver->take_errors()) spdlog::warn("learned state not saved: {}", e);
  if (recorder) recorder->flush(true);
  if (recording_failed(recorder.get())) exit_code = 3;
  const RuntimeCounters c = rt.counters();
  spdlog::info(
      "stopped: {} edges, {} teeth, {} cycles, drops edge/can/out {}/{}/{}, overruns {}, latency p50/p99/max "
      "{:.1f}/{:.1f}/{:.1f} us, publisher pre-wakes {} (timed out {})",
      c.edges, c.teeth, c.cycles, c.ring_drops_edge, c.ring_drops_can, c.ring_drops_out, c.overruns,
      c.latency_p50_ns * 1e-3, c.latency_p99_ns * 1e-3, c.latency_max_ns * 1e-3, c.publisher_polls,
      c.publisher_poll_misses);
  return exit_code;
}

}  // namespace torqued
