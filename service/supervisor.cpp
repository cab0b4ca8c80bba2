#include "supervisor.hpp"

#include <signal.h>
#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "angle_stage.hpp"
#include "clocks.hpp"
#include "config.hpp"
#include "config_loader.hpp"
#include "crank_decoder.hpp"
#include "logging.hpp"
#include "rt_setup.hpp"
#include "runtime.hpp"
#include "sd_notify.hpp"
#include "stage_settings_from.hpp"
#include "status.hpp"

namespace torqued {

std::string state_path(const Config& cfg, const RunOptions& opt) {
  const std::string dir = opt.state_dir ? *opt.state_dir : cfg.output.state_dir;
  return dir.empty() ? std::string() : dir + "/learned_state.txt";
}

RestoreResult restore_for_run(const std::string& spath, const StateContext& ctx, const RunOptions& opt) {
  RestoreResult rs;
  if (opt.fresh_state)
    rs.infos.push_back("learned state not loaded (--fresh-state): learning from the prior; saved to " +
                       spath);
  else
    rs = restore_learned_state(spath, ctx);
  for (const auto& w : rs.warnings) spdlog::warn("{}", w);
  for (const auto& i : rs.infos) spdlog::info("{}", i);
  return rs;
}

ThreadRt thread_rt(const ThreadConfig& t, const char* name) {
  return ThreadRt{t.policy == SchedPolicy::kFifo, t.priority, t.cpus, name};
}

void log_transition(const DecoderEvent& e) {
  if (e.kind == DecoderEventKind::kLost)
    spdlog::debug("decoder: {} at t={:.6f} s, {} -> {} ({})", to_string(e.kind),
                  static_cast<double>(e.t_ns) * 1e-9, to_string(e.from), to_string(e.to),
                  to_string(static_cast<SyncLossReason>(e.reason)));
  else
    spdlog::debug("decoder: {} at t={:.6f} s, {} -> {}{}", to_string(e.kind),
                  static_cast<double>(e.t_ns) * 1e-9, to_string(e.from), to_string(e.to),
                  e.tooth >= 0 ? " at tooth " + std::to_string(e.tooth) : "");
}

namespace {

RuntimeOptions runtime_options(const Config& cfg, const RunOptions& opt) {
  RuntimeOptions ro;
  ro.replay = cfg.inputs.edges.backend == EdgeBackend::kFile && cfg.inputs.can.backend == CanBackend::kFile;
  ro.speed = opt.speed ? *opt.speed : cfg.replay.speed;
  ro.lock_memory = cfg.realtime.lock_memory;
  ro.lock_on_fault = cfg.realtime.lock_on_fault;
  ro.require_rt = cfg.realtime.require_rt;
  ro.angle = thread_rt(cfg.realtime.angle, "torqued-angle");
  ro.time = thread_rt(cfg.realtime.time, "torqued-time");
  ro.source = thread_rt(cfg.realtime.source, "torqued-source");
  ro.publisher = thread_rt(cfg.realtime.publisher, "torqued-pub");
  ro.publisher_spin_ns = static_cast<std::int64_t>(cfg.realtime.publisher_spin_us) * 1000;
  ro.stage_trace = opt.stage_trace.empty() ? 0 : std::size_t{1} << 17;
  return ro;
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

/// `torqued --stage-trace FILE`: the CrankState samples' stamps in the daemon, one CSV row each (not
/// real-time: after the threads have ended). False (logged) when the file cannot be written.
bool write_stage_trace(const std::string& path, const std::vector<StageStamps>& trace) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) {
    spdlog::error("stage trace: cannot write {}: {}", path, std::strerror(errno));
    return false;
  }
  std::fprintf(f, "seq,ingest_ns,angle_ns,pushed_ns,taken_ns,written_ns\n");
  for (const StageStamps& t : trace)
    std::fprintf(f, "%llu,%lld,%lld,%lld,%lld,%lld\n", static_cast<unsigned long long>(t.seq),
                 static_cast<long long>(t.ingest_ns), static_cast<long long>(t.angle_ns),
                 static_cast<long long>(t.pushed_ns), static_cast<long long>(t.taken_ns),
                 static_cast<long long>(t.written_ns));
  if (std::fclose(f) != 0) {
    spdlog::error("stage trace: cannot write {}: {}", path, std::strerror(errno));
    return false;
  }
  spdlog::info("stage trace: {} CrankState samples written to {}", trace.size(), path);
  return true;
}

void notify_status(const RuntimeCounters& c, double uptime_s) {
  sd_notify_statef("STATUS=%s; uptime %.0f s; edges %" PRIu64 " cycles %" PRIu64 " drops %" PRIu64
                   " overruns %" PRIu64,
                   c.synced ? "synced" : "not synced", uptime_s, c.edges, c.cycles,
                   c.ring_drops_edge + c.ring_drops_can + c.ring_drops_out, c.overruns);
}

class Supervisor {
 public:
  Supervisor(Config& cfg, const RunOptions& opt, RunInputs& in, dds::SampleRecorder* recorder,
             SampleSink& out)
      : cfg_(cfg),
        opt_(opt),
        s_(in.settings),
        ro_(runtime_options(cfg, opt)),
        rt_(s_, ro_, in.edges.get(), in.can.get(), in.can_offset_ns, in.dbc_ptr(), out),
        recorder_(recorder) {}

  int run() {
    if (!start()) return 1;
    for (;;) {
      timespec tick{0, 50'000'000};
      siginfo_t si{};
      const int sig = sigtimedwait(&sigs_, &si, &tick);
      if (sig == SIGTERM || sig == SIGINT) {
        spdlog::info("{}: draining and stopping", sig == SIGTERM ? "SIGTERM" : "SIGINT");
        break;
      }
      if (sig == SIGHUP) {
        sd_notify_state("RELOADING=1");
        reload(opt_.config_path, cfg_, s_, rt_);
        sd_notify_state("READY=1");
      }
      if (!tick_once(mono_ns())) break;
    }
    return shutdown();
  }

 private:
  bool start();
  bool tick_once(std::int64_t now);  ///< false: stop (input consumed with --exit-when-done)
  void ping_watchdog(std::int64_t now);
  void save();
  int shutdown();
  void log_input_problems() {  // once: at the end of the input, else at stop (source threads joined)
    if (input_problems_logged_) return;
    input_problems_logged_ = true;
    for (const auto& p : rt_.input_problems()) spdlog::warn("{}", p);
  }

  Config& cfg_;
  const RunOptions& opt_;
  StageSettings& s_;
  RuntimeOptions ro_;
  Runtime rt_;
  dds::SampleRecorder* recorder_;
  std::unique_ptr<StateSaver> saver_;
  LearnedState learned_;  ///< newest learned state read from the angle stage (this thread is its one reader)
  bool have_learned_ = false;
  sigset_t sigs_{};
  StatusTracker status_;
  Heartbeats last_hb_{};
  bool watchdog_ = false, done_reported_ = false, record_error_reported_ = false,
       input_problems_logged_ = false;
  double stall_after_s_ = -1.0;
  std::int64_t t0_ = 0, next_status_ = 0, next_ping_ = 0, next_save_ = 0, ping_period_ = 0, save_period_ = 0;
};

bool Supervisor::start() {
  // Signals are handled synchronously by this thread; blocked before any thread starts so all inherit the
  // mask.
  sigemptyset(&sigs_);
  sigaddset(&sigs_, SIGTERM);
  sigaddset(&sigs_, SIGINT);
  sigaddset(&sigs_, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &sigs_, nullptr);
  if (!rt_.ok()) {
    spdlog::critical("{}", rt_.error());
    return false;
  }
  // Learned state from the previous run: checked (identity, checksum, bounds); rejected files are set aside.
  const std::string spath = state_path(cfg_, opt_);
  if (!spath.empty()) {
    const StateContext sctx = state_context_from(cfg_);
    const RestoreResult rs = restore_for_run(spath, sctx, opt_);
    if (rs.state) {
      const std::string what = rt_.angle_stage().import_state(*rs.state);
      if (!what.empty()) spdlog::info("learned state loaded from {}: {}", spath, what);
    }
    if (rs.may_save) saver_ = std::make_unique<StateSaver>(spath, sctx);
  }
  if (!rt_.start()) {
    spdlog::critical("start: {}", rt_.error());
    return false;
  }
  for (const auto& w : rt_.warnings()) spdlog::warn("{}", w);
  const char* test_stall = std::getenv("TORQUED_TEST_STALL_AFTER_S");  // test-only hook (watchdog test)
  stall_after_s_ = test_stall ? std::atof(test_stall) : -1.0;
  std::uint64_t wd_usec = 0;
  watchdog_ = sd_watchdog_usec(&wd_usec) > 0 && wd_usec > 0;
  sd_notify_statef("READY=1\nSTATUS=running (%s)", ro_.replay ? "paced replay" : "live");
  spdlog::info("running ({}), watchdog {}", ro_.replay ? "paced replay" : "live",
               watchdog_ ? std::to_string(wd_usec / 1000) + " ms" : std::string("off"));
  t0_ = mono_ns();
  next_status_ = t0_ + s_.status_period_ns;
  next_ping_ = next_save_ = t0_;
  ping_period_ = watchdog_ ? static_cast<std::int64_t>(wd_usec) * 1000 / 2 : 0;
  save_period_ = static_cast<std::int64_t>(opt_.state_save_period_s * 1e9);
  last_hb_ = rt_.heartbeats();
  return true;
}

bool Supervisor::tick_once(std::int64_t now) {
  DecoderEvent ev{};
  while (rt_.angle_stage().chain().transitions().pop(ev)) log_transition(ev);
  if (stall_after_s_ >= 0 && now - t0_ >= static_cast<std::int64_t>(stall_after_s_ * 1e9))
    rt_.test_stall(true);
  const bool record_failed = recorder_ && recorder_->write_failed();
  if (record_failed && !record_error_reported_) {  // at once; estimation goes on
    spdlog::error("recording: {}; estimation and DDS publishing continue", recorder_->error());
    record_error_reported_ = true;
  }
  if (now >= next_status_) {
    RuntimeCounters c = rt_.counters();
    const bool done = rt_.input_done();
    if (done) c.flags |= torque_STATUS_REPLAY_DONE;  // a state: on every status from now on
    if (done && !done_reported_) {
      done_reported_ = true;
      log_input_problems();
      spdlog::info("replay: end of the recording reached{}", opt_.exit_when_done
                                                                 ? "; stopping (--exit-when-done)"
                                                                 : "; still running (stop with SIGTERM)");
    }
    if (record_failed) c.flags |= torque_STATUS_RECORD_ERROR;
    rt_.push_status(status_.next(c, rt_.last_source_t_ns(), now - t0_));
    notify_status(c, static_cast<double>(now - t0_) * 1e-9);
    next_status_ += s_.status_period_ns;
    if (done_reported_ && opt_.exit_when_done) return false;
  }
  ping_watchdog(now);
  if (save_period_ > 0 && now >= next_save_) {
    save();
    next_save_ = now + save_period_;
  }
  return true;
}

// Ping only while every pipeline thread made progress since the last ping.
void Supervisor::ping_watchdog(std::int64_t now) {
  if (!watchdog_ || now < next_ping_) return;
  const Heartbeats hb = rt_.heartbeats();
  if (hb.angle != last_hb_.angle && hb.time != last_hb_.time && hb.publisher != last_hb_.publisher) {
    sd_notify_state("WATCHDOG=1");
    last_hb_ = hb;
  }
  next_ping_ = now + ping_period_;
}

// Queued: the saver's thread writes (a slow disk never holds up this loop).
void Supervisor::save() {
  if (!saver_) return;
  for (const auto& e : saver_->take_errors()) spdlog::warn("learned state not saved: {}", e);
  if (rt_.angle_stage().learned().load_new(learned_)) have_learned_ = true;  // else: unchanged since
  if (!have_learned_) return;                                                // nothing learned yet
  LearnedState st = learned_;
  st.saved_at_t_ns = rt_.last_source_t_ns();
  saver_->submit(st);
}

int Supervisor::shutdown() {
  int exit_code = 0;
  sd_notify_state("STOPPING=1\nSTATUS=draining");
  // One budget for the whole stop (drain, last state save, recording fsyncs), three quarters of
  // drain_timeout_s: the rest is left for the logs and the exit (systemd's stop timeout must not kill the
  // daemon mid-write). The recording's fsyncs run in parallel with the state save.
  const auto t0 = std::chrono::steady_clock::now();
  const double budget_s = 0.75 * opt_.drain_timeout_s;
  const auto left_s = [&] {
    return std::max(0.0,
                    budget_s - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  };
  if (!rt_.stop_and_drain(static_cast<std::int64_t>(budget_s * 1e9))) {
    spdlog::warn("drain did not finish within {} s", budget_s);
    exit_code = 1;
  }
  log_input_problems();
  for (const auto& b : rt_.angle_stage().chain().describe_bad_frames()) spdlog::warn("can: {}", b);
  save();
  bool saved = true;
  std::vector<std::string> unsynced;
  if (saver_) {
    std::thread rec_sync;
    if (recorder_)
      rec_sync =
          std::thread([this, &unsynced, &left_s] { unsynced = recorder_->flush_sync_within(left_s()); });
    saved = saver_->finish(left_s());
    if (rec_sync.joinable()) rec_sync.join();
  } else if (recorder_) {
    unsynced = recorder_->flush_sync_within(left_s());
  }
  if (!saved)
    spdlog::warn(
        "learned state: the last save did not finish within the stop budget ({:.2f} s): the file on "
        "disk is the previous complete one",
        budget_s);
  if (saver_)
    for (const auto& e : saver_->take_errors()) spdlog::warn("learned state not saved: {}", e);
  if (!unsynced.empty()) {
    std::string names;
    for (const auto& n : unsynced) names += (names.empty() ? "" : ", ") + n;
    spdlog::warn(
        "recording: fsync of {} not finished within the stop budget ({:.2f} s): their last rows are "
        "written but may not be on disk",
        names, budget_s);
  }
  if (recorder_ && recorder_->write_failed()) {
    spdlog::error("recording: {}; {} rows not recorded", recorder_->error(), recorder_->rows_dropped());
    exit_code = 3;
  }
  const RuntimeCounters c = rt_.counters();
  const MemoryUse mem = read_memory_use();
  spdlog::info(
      "stopped: {} edges, {} teeth, {} cycles, {} CAN frames, drops edge/can/out/source {}/{}/{}/{}, "
      "overruns {}, "
      "latency over the run p50/p99/max {:.1f}/{:.1f}/{:.1f} us, publisher pre-wakes {} (timed out {}), "
      "angle thread wake-ups {}, memory RSS {:.1f} MiB (peak {:.1f}), locked and resident {:.1f} MiB "
      "(mlockall address space {:.0f} MiB, mostly reserved malloc arenas, not resident)",
      c.edges, c.teeth, c.cycles, c.can_frames, c.ring_drops_edge, c.ring_drops_can, c.ring_drops_out,
      c.source_drops, c.overruns, c.run_latency_p50_ns * 1e-3, c.run_latency_p99_ns * 1e-3,
      c.run_latency_max_ns * 1e-3, c.publisher_polls, c.publisher_poll_misses, c.angle_wakeups,
      static_cast<double>(mem.rss) / 1048576.0, static_cast<double>(mem.peak) / 1048576.0,
      static_cast<double>(mem.locked_resident) / 1048576.0, static_cast<double>(mem.locked) / 1048576.0);
  std::string threads;
  for (const auto& t : rt_.thread_usage())
    threads += fmt::format("{}{} {}/{} {}/{}", threads.empty() ? "" : ", ", t.name, t.use.minor_faults,
                           t.use.major_faults, t.use.voluntary_switches, t.use.forced_switches);
  spdlog::info("threads over the run (page faults minor/major, context switches voluntary/preempted): {}",
               threads.empty() ? "none" : threads);
  if (!opt_.stage_trace.empty() && !write_stage_trace(opt_.stage_trace, rt_.stage_trace())) exit_code = 1;
  return exit_code;
}

}  // namespace

int run_supervised(Config& cfg, const RunOptions& opt, RunInputs& in, dds::SampleRecorder* recorder,
                   SampleSink& out) {
  Supervisor sup(cfg, opt, in, recorder, out);
  return sup.run();
}

}  // namespace torqued
