#include "fast_replay.hpp"

#include <chrono>

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

/// DaemonStatus counters of the replay so far (the input's counts as of the last record taken).
RuntimeCounters replay_counters(const AngleChain& chain, const ReadAheadMerger& input) noexcept {
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

}  // namespace

ReplayResult run_fast_replay(const StageSettings& s, EdgeSource* edges, CanSource* can,
                             std::int64_t can_offset_ns, const DbcDatabase* dbc, SampleSink& out,
                             const volatile bool* stop, LearnedState* state, AngleChainSink* tap) {
  ReplayResult r;
  r.transitions.events.reserve(ReplayResult::Transitions::kMaxKept);
  CountingSink sink(out);
  TimeStage time(s, dbc, sink);
  TimeFeed feed(time);
  AngleStage angle(s, dbc, sink, &feed, tap);
  if (!angle.ok()) {
    r.error = angle.error();
    return r;
  }
  if (!time.ok()) {
    r.error = time.error();
    return r;
  }
  if (state) r.imported = angle.import_state(*state);

  // The inputs are read, parsed and merged on a second thread (read_ahead_merger.hpp), in the same order.
  ReadAheadMerger input(edges, can, can_offset_ns);
  const auto t0 = std::chrono::steady_clock::now();
  bool first = true;
  std::int64_t next_tick = 0, next_status = 0;
  std::uint64_t n = 0;
  StatusTracker status;
  ReplayMerger::Item item;
  bool source_failed = false;
  auto counters = [&] { return replay_counters(angle.chain(), input); };
  for (;;) {
    if (stop && *stop) break;
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
      sink.emit(status.next(counters(), next_status, next_status - r.first_t_ns));
      next_status += s.status_period_ns;
    }
    r.last_t_ns = t;
    ++n;
  }
  input.stop();  // the sources are this thread's again: their stats, errors and problems below
  if (source_failed) r.error = input.first_error();
  r.input_waits = input.waits();
  drain_transitions(angle.chain().transitions(), r.transitions);
  r.transitions.not_kept += angle.chain().transitions().dropped();  // ring full between two drains
  RuntimeCounters c = counters();
  c.flags |= torque_STATUS_REPLAY_DONE;
  sink.emit(status.next(c, r.last_t_ns, r.last_t_ns - r.first_t_ns));
  r.counters = c;
  if (state) r.learned = angle.chain().snapshot(*state);
  r.bad_frames = angle.chain().describe_bad_frames();
  r.input_problems = input_problems(edges, can);
  r.samples = sink.n_;
  sink.flush();  // the recording's last buffers are written inside the timed loop
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace torqued
