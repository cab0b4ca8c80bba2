#include "fast_replay.hpp"

#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "angle_stage.hpp"
#include "read_ahead_merger.hpp"
#include "replay_inputs.hpp"
#include "time_stage.hpp"

namespace torqued {
namespace {

/// Counts samples on their way to the real sink.
class CountingSink final : public SampleSink {
 public:
  explicit CountingSink(SampleSink& inner) : inner_(inner) {}
  void emit(const dds::AnySample& s) noexcept override {
    ++n_;
    inner_.emit(s);
  }
  void flush() noexcept override { inner_.flush(); }
  std::uint64_t n_ = 0;

 private:
  SampleSink& inner_;
};

class TimeFeed final : public ToothSink {
 public:
  explicit TimeFeed(TimeStage& t) : t_(t) {}
  void tooth(const ToothSample& s) noexcept override { t_.on_tooth(s); }
  std::uint64_t teeth_ = 0;

 private:
  TimeStage& t_;
};

/// Keeps the first kMaxTransitions decoder transitions for the caller's debug log (the rest are counted).
void drain_transitions(DecoderEventLog& log, ReplayResult::Transitions& out) noexcept {
  DecoderEvent e{};
  while (log.pop(e)) {
    if (out.events.size() < out.events.capacity()) {
      out.events.push_back(e);  // capacity reserved before the loop: no allocation here
    } else {
      ++out.not_kept;
    }
  }
}

/// The one-thread input (replay.fast_threads 1): the merger on the chain's thread, read like ReadAheadMerger.
class InlineInput {
 public:
  InlineInput(EdgeSource* edges, CanSource* can, std::int64_t can_offset_ns)
      : edges_(edges), can_(can), merger_(edges, can, can_offset_ns) {}
  [[nodiscard]] SourceStatus next(ReplayMerger::Item& out) noexcept {
    const SourceStatus st = merger_.next(out);
    if (st == SourceStatus::kError && first_error_.empty()) first_error_ = source_error_message(edges_, can_);
    return st;
  }
  void stop() noexcept {}
  [[nodiscard]] std::uint64_t frames_out() const noexcept { return merger_.frames_out(); }
  [[nodiscard]] std::uint64_t source_drops() const noexcept {
    return (edges_ ? edges_->stats().bad_lines + edges_->stats().dropped : 0) +
           (can_ ? can_->stats().bad_lines + can_->stats().dropped : 0);
  }
  [[nodiscard]] const std::string& first_error() const noexcept { return first_error_; }
  [[nodiscard]] static std::uint64_t waits() noexcept { return 0; }

 private:
  EdgeSource* edges_;
  CanSource* can_;
  ReplayMerger merger_;
  std::string first_error_;
};

/// DaemonStatus counters of the replay so far (the input's counts as of the last record taken).
template <class Input>
RuntimeCounters replay_counters(const AngleChain& chain, const Input& input) noexcept {
  RuntimeCounters c;
  const auto& ds = chain.decoder().stats();
  c.edges = ds.edges;
  c.teeth = ds.teeth;
  c.sync_losses = ds.sync_losses;
  c.rejected_edges = ds.rejected_edges;
  c.cam_phase_errors = ds.cam_phase_errors;
  c.cycles = chain.cycles();
  c.tooth_tables_distrusted = chain.tooth_tables_distrusted();
  if (const AnglePipeline* p = chain.pipeline()) {
    c.fuel_references = p->fuel_model().state().references;
    c.fuel_cells = p->fuel_model().learned_cells();
  }
  if (const BurnPhaseLearner* b = chain.burn_phase()) {
    c.burn_phase_state = static_cast<std::uint8_t>(b->stats().state);
    c.burn_phase_offset_deg = b->offset_deg();
  }
  c.can_frames = input.frames_out();
  c.source_drops = input.source_drops();
  c.sensor_timeouts = chain.status().stale_mask;
  c.synced = chain.decoder().state() == SyncState::kSynced;
  return c;
}

/// Moves a periodic due time `next` (period `period`) forward by whole periods so that at most `max_gap` of
/// recording time lies between it and t.
void skip_gap(std::int64_t& next, std::int64_t t, std::int64_t max_gap, std::int64_t period) noexcept {
  if (period <= 0 || max_gap <= 0 || t - next <= max_gap) return;
  next += (t - max_gap - next) / period * period;
}

/// The stages of one fast replay, built from the settings (allocates here, not in the loop).
struct Stages {
  Stages(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out, AngleChainSink* tap)
      : sink(out), time(s, dbc, sink), feed(time), angle(s, dbc, sink, &feed, tap) {}
  CountingSink sink;
  TimeStage time;
  TimeFeed feed;
  AngleStage angle;
};

/// The replay loop, from the first record to the last DaemonStatus; the same code for both inputs
/// (InlineInput, ReadAheadMerger), so one thread and three give the same bytes.
template <class Input>
void replay_loop(const StageSettings& s, Stages& g, Input& input, const std::atomic<bool>* stop,
                 ReplayResult& r, std::chrono::steady_clock::time_point& t0) {
  t0 = std::chrono::steady_clock::now();  // the input built (a reader thread started)
  TimeStage& time = g.time;
  AngleStage& angle = g.angle;
  bool first = true;
  std::int64_t next_tick = 0, next_status = 0;
  StatusTracker status;
  ReplayMerger::Item item;
  bool source_failed = false;
  auto counters = [&] { return replay_counters(angle.chain(), input); };
  for (;;) {
    if (stop && stop->load(std::memory_order_relaxed)) break;
    const SourceStatus st = input.next(item);
    if (st == SourceStatus::kEnd) break;
    if (st == SourceStatus::kError) {
      source_failed = true;  // its message: input.first_error(), once the reader has ended
      continue;
    }
    if (st != SourceStatus::kOk) continue;
    const std::int64_t t = item.t_ns();
    if (first) {
      first = false;
      r.first_t_ns = t;
      next_tick = t + time.step_ns();
      next_status = t + s.status_period_ns;
    }
    // Output is bounded by what the input can produce: across a silent stretch longer than
    // max_input_gap_ns (a re-based clock jump) only its last max_input_gap_ns is stepped and reported.
    skip_gap(next_tick, t, s.max_input_gap_ns, time.step_ns());
    skip_gap(next_status, t, s.max_input_gap_ns, s.status_period_ns);
    // Time-triggered steps that are due before this record (the 1 kHz timer of the paced mode).
    while (next_tick <= t) {
      time.step(next_tick, 0);
      angle.chain().set_time_estimate(time.pipeline().output().uio, /*uses_can=*/true);  // time → fusion
      next_tick += time.step_ns();
    }
    if (item.kind == ReplayMerger::Kind::kEdge) {
      angle.on_edge(item.edge, 0);
    } else {
      angle.on_frame(item.frame);
      time.on_frame(item.frame);
    }
    while (next_status <= t) {
      drain_transitions(angle.chain().transitions(), r.transitions);
      g.sink.emit(status.next(counters(), next_status, next_status - r.first_t_ns));
      next_status += s.status_period_ns;
    }
    r.last_t_ns = t;
  }
  input.stop();  // the sources are this thread's again: their stats, errors and problems below
  if (source_failed) r.error = input.first_error();
  r.input_waits = input.waits();
  drain_transitions(angle.chain().transitions(), r.transitions);
  r.transitions.not_kept += angle.chain().transitions().dropped();  // ring full between two drains
  RuntimeCounters c = counters();
  c.flags |= torque_STATUS_REPLAY_DONE;
  g.sink.emit(status.next(c, r.last_t_ns, r.last_t_ns - r.first_t_ns));
  r.counters = c;
}

}  // namespace

namespace {

// The quota of one cgroup directory in whole CPUs (floor, at least 1), 0 if none or unreadable.
int quota_cpus_in(const std::string& dir, bool v2) {
  double quota = -1, period = 0;
  if (v2) {
    std::ifstream f(dir + "/cpu.max");
    std::string q;
    if (!(f >> q >> period) || q == "max") return 0;
    quota = std::strtod(q.c_str(), nullptr);
  } else {
    std::ifstream fq(dir + "/cpu.cfs_quota_us"), fp(dir + "/cpu.cfs_period_us");
    if (!(fq >> quota) || !(fp >> period)) return 0;
  }
  if (!(quota > 0) || !(period > 0)) return 0;
  return std::max(1, static_cast<int>(quota / period));
}

}  // namespace

int cgroup_quota_cpus(const std::string& proc_self_cgroup, const std::string& root) {
  int cpus = 0;
  std::istringstream lines(proc_self_cgroup);
  for (std::string line; std::getline(lines, line);) {
    // "0::/path" (v2) or "N:cpu,cpuacct:/path" (v1 with the cpu controller)
    const auto a = line.find(':'), b = line.find(':', a == std::string::npos ? a : a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string ctrl = line.substr(a + 1, b - a - 1), path = line.substr(b + 1);
    const bool v2 = ctrl.empty();
    bool has_cpu = v2;
    for (std::size_t p = 0; !v2 && p <= ctrl.size();) {
      const auto e = std::min(ctrl.find(',', p), ctrl.size());
      has_cpu = has_cpu || ctrl.compare(p, e - p, "cpu") == 0;
      p = e + 1;
    }
    if (!has_cpu || path.empty() || path[0] != '/') continue;
    const std::string base = v2 ? root : root + "/" + ctrl;
    for (std::string p = path;;) {  // the cgroup and each parent up to the root: the smallest quota holds
      const int c = quota_cpus_in(base + (p == "/" ? "" : p), v2);
      if (c > 0) cpus = cpus == 0 ? c : std::min(cpus, c);
      if (p == "/" || p.empty()) break;
      const auto slash = p.rfind('/');
      p = slash == 0 ? "/" : p.substr(0, slash);
    }
  }
  return cpus;
}

int usable_cpus() noexcept {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) != 0) return 1;
  int cpus = std::max(1, CPU_COUNT(&set));
  try {
    std::ifstream f("/proc/self/cgroup");
    std::stringstream text;
    text << f.rdbuf();
    const int quota = cgroup_quota_cpus(text.str(), "/sys/fs/cgroup");
    if (quota > 0) cpus = std::min(cpus, quota);
  } catch (...) {  // start-up only (allocation): an unreadable cgroup leaves the affinity's count
  }
  return cpus;
}

FastThreadsChoice resolve_fast_threads(int setting, int cpus) {
  FastThreadsChoice c;
  if (setting == 1 || setting == 3) {
    c.threads = setting;
    c.why = "replay.fast_threads " + std::to_string(setting);
    return c;
  }
  c.threads = cpus >= 2 ? 3 : 1;  // one CPU: a helper thread could only take turns with the chain's
  c.why = "replay.fast_threads auto, " + std::to_string(cpus) + (cpus == 1 ? " CPU" : " CPUs") + " usable";
  return c;
}

ReplayResult run_fast_replay(const StageSettings& s, EdgeSource* edges, CanSource* can,
                             std::int64_t can_offset_ns, const DbcDatabase* dbc, SampleSink& out,
                             const std::atomic<bool>* stop, LearnedState* state, AngleChainSink* tap) {
  ReplayResult r;
  r.threads = resolve_fast_threads(s.fast_threads, usable_cpus());
  r.transitions.events.reserve(ReplayResult::Transitions::kMaxKept);
  Stages g(s, dbc, out, tap);
  if (!g.angle.ok()) {
    r.error = g.angle.error();
    return r;
  }
  if (!g.time.ok()) {
    r.error = g.time.error();
    return r;
  }
  if (state) r.imported = g.angle.import_state(*state);

  std::chrono::steady_clock::time_point t0;
  if (r.threads.threads == 3) {
    // The inputs are read, parsed and merged on a second thread (read_ahead_merger.hpp), in the same order.
    ReadAheadMerger input(edges, can, can_offset_ns);
    replay_loop(s, g, input, stop, r, t0);
  } else {
    InlineInput input(edges, can, can_offset_ns);
    replay_loop(s, g, input, stop, r, t0);
  }
  if (state) r.learned = g.angle.chain().snapshot(*state);
  r.bad_frames = g.angle.chain().describe_bad_frames();
  r.input_problems = input_problems(edges, can);
  r.samples = g.sink.n_;
  g.sink.flush();  // the recording's last buffers are written inside the timed loop
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace torqued
