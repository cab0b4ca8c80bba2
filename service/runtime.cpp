#include "runtime.hpp"

#include <sys/prctl.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>

#include "angle_stage.hpp"
#include "clocks.hpp"
#include "replay_inputs.hpp"
#include "replay_merger.hpp"
#include "time_stage.hpp"

namespace torqued {

/// Stage output -> SPSC ring towards the publisher (drop newest + count when full), then wake it.
class Runtime::RingSink final : public SampleSink {
 public:
  /// stamps/angle_ns: the stage trace (nullptr: off), CrankState's stamps go first into `stamps`.
  RingSink(SpscRing<dds::AnySample>& r, Wakeup& w, SpscRing<AngleStamps>* stamps = nullptr,
           const std::int64_t* angle_ns = nullptr)
      : r_(r), w_(w), stamps_(stamps), angle_ns_(angle_ns) {}
  void emit(const dds::AnySample& s) noexcept override {
    if (stamps_ && s.topic == dds::Topic::kCrankState)  // one clock read per CrankState, only when tracing
      (void)stamps_->try_push(AngleStamps{s.u.crank.seq, *angle_ns_, realtime_ns()});
    if (r_.try_push(s)) w_.notify();
  }

 private:
  SpscRing<dds::AnySample>& r_;
  Wakeup& w_;
  SpscRing<AngleStamps>* stamps_;
  const std::int64_t* angle_ns_;
};

/// Angle stage tooth samples -> time thread (which polls on its timer; no wake-up needed).
class Runtime::ToothRingSink final : public ToothSink {
 public:
  explicit ToothRingSink(SpscRing<ToothSample>& r) : r_(r) {}
  void tooth(const ToothSample& t) noexcept override { (void)r_.try_push(t); }

 private:
  SpscRing<ToothSample>& r_;
};

Runtime::Runtime(const StageSettings& s, const RuntimeOptions& opt, EdgeSource* edges, CanSource* can,
                 std::int64_t can_offset_ns, const DbcDatabase* dbc, SampleSink& final_out)
    : s_(s),
      opt_(opt),
      edges_(edges),
      can_(can),
      can_offset_ns_(can_offset_ns),
      final_out_(final_out),
      edge_ring_(opt.edge_ring),
      can_angle_ring_(opt.can_ring),
      can_time_ring_(opt.can_ring),
      tooth_ring_(opt.tooth_ring),
      out_angle_ring_(opt.out_ring),
      out_time_ring_(opt.out_ring),
      out_status_ring_(64),
      clock_(opt.speed, !opt.replay),
      stamp_ring_(opt.stage_trace > 0 ? opt.out_ring : 2) {
  edge_timeout_ns_.store(s_.edge_timeout_ns, std::memory_order_relaxed);
  angle_sink_ = opt_.stage_trace > 0
                    ? std::make_unique<RingSink>(out_angle_ring_, pub_wake_, &stamp_ring_, &angle_take_ns_)
                    : std::make_unique<RingSink>(out_angle_ring_, pub_wake_);
  trace_.reserve(opt_.stage_trace);
  time_sink_ = std::make_unique<RingSink>(out_time_ring_, pub_wake_);
  tooth_sink_ = std::make_unique<ToothRingSink>(tooth_ring_);
  time_ = std::make_unique<TimeStage>(s_, dbc, *time_sink_);
  angle_ = std::make_unique<AngleStage>(s_, dbc, *angle_sink_, tooth_sink_.get());
  if (!angle_->ok())
    error_ = angle_->error();
  else if (!time_->ok())
    error_ = time_->error();
}

Runtime::~Runtime() {
  if (pub_thread_.joinable() || angle_thread_.joinable()) stop_and_drain(500'000'000);
}

void Runtime::start_thread(std::thread& t, const ThreadRt& rt, void (Runtime::*fn)(), bool realtime) {
  t = std::thread([this, rt, fn, realtime] {
    const RtOutcome o = apply_to_current_thread(rt);
    if (!o.ok && o.not_permitted) flags_.fetch_or(torque_STATUS_RT_NOT_PERMITTED, std::memory_order_relaxed);
    if (realtime && opt_.rt_thread_hook) opt_.rt_thread_hook(rt.name, false);
    const ThreadUsage u0 = read_thread_usage();
    (this->*fn)();
    const ThreadUsage u1 = read_thread_usage();  // after the loop: not on the real-time path
    if (realtime && opt_.rt_thread_hook) opt_.rt_thread_hook(rt.name, true);
    if (const int slot = usage_n_.fetch_add(1, std::memory_order_acq_rel); slot < kMaxThreads) {
      usage_[static_cast<std::size_t>(slot)] = usage_between(u0, u1);
      std::snprintf(usage_name_[static_cast<std::size_t>(slot)].data(), 16, "%s",
                    rt.name && rt.name[0] ? rt.name : "thread");
    }
  });
}

std::vector<Runtime::ThreadRunUsage> Runtime::thread_usage() const {
  std::vector<ThreadRunUsage> out;
  const int n = std::min(usage_n_.load(std::memory_order_acquire), kMaxThreads);
  for (int i = 0; i < n; ++i)
    out.push_back({usage_name_[static_cast<std::size_t>(i)].data(), usage_[static_cast<std::size_t>(i)]});
  return out;
}

bool Runtime::start() {
  if (!ok()) return false;
  // Our threads (and any created later without attributes) get kThreadStackBytes, not RLIMIT_STACK (8 MiB),
  // which mlockall would make resident. run_daemon sets it before Cyclone's threads exist, too.
  if (const RtOutcome st = set_default_thread_stack(); !st.ok) warnings_.push_back(st.message);
  if (opt_.lock_memory) {
    const RtOutcome o = lock_memory(opt_.lock_on_fault);
    if (!o.ok) {
      flags_.fetch_or(torque_STATUS_MLOCK_FAILED, std::memory_order_relaxed);
      if (opt_.require_rt) {
        error_ = o.message + " (realtime.require_rt is set)";
        return false;
      }
      warnings_.push_back(
          o.message +
          ": running without locked memory (needs CAP_IPC_LOCK or LimitMEMLOCK=infinity, as in "
          "systemd/torqued.service)");
    }
  }
  // Probe SCHED_FIFO once from this thread so a refusal is reported before the threads run.
  if (opt_.angle.fifo) {
    std::thread probe([&] {
      ThreadRt p = opt_.angle;
      p.name = "torqued-probe";
      const RtOutcome o = apply_to_current_thread(p);
      if (!o.ok) {
        flags_.fetch_or(torque_STATUS_RT_NOT_PERMITTED, std::memory_order_relaxed);
        if (!opt_.require_rt)
          warnings_.push_back(
              o.message +
              ": running the pipelines with SCHED_OTHER (needs CAP_SYS_NICE or LimitRTPRIO, as "
              "in systemd/torqued.service)");
        else
          error_ = o.message + " (realtime.require_rt is set)";
      }
    });
    probe.join();
    if (!error_.empty()) return false;
  }
  start_thread(pub_thread_, opt_.publisher, &Runtime::publisher_loop, false);
  start_thread(time_thread_, opt_.time, &Runtime::time_loop, true);
  start_thread(angle_thread_, opt_.angle, &Runtime::angle_loop, true);
  if (opt_.replay) {
    sources_running_.store(1);
    start_thread(src_thread_, opt_.source, &Runtime::replay_source_loop, true);
  } else {
    sources_running_.store((edges_ ? 1 : 0) + (can_ ? 1 : 0));
    if (edges_) start_thread(src_thread_, opt_.source, &Runtime::live_edge_loop, true);
    if (can_) {
      ThreadRt rt = opt_.source;
      rt.name = "torqued-can";
      start_thread(src2_thread_, rt, &Runtime::live_can_loop, true);
    }
  }
  return true;
}

// ---- sources -------------------------------------------------------------------------------------------

// Paced replay: this thread only reads ahead. It keeps the rings filled up to kReadAheadNs (recording time /
// speed) ahead of the wall clock, in batches (one wake-up per ~kReadAheadNs/2, not one per edge), and the
// angle thread does the fine pacing itself: it sleeps until each edge's due time and processes it when it
// wakes. That is one thread wake-up per edge (the timer) instead of two (source timer + futex to the angle
// thread). Items carry ingest_ns = 0; the consumer stamps them with their due time. Fast replay does not use
// this thread.
void Runtime::replay_source_loop() {
  ReplayMerger merger(edges_, can_, can_offset_ns_);
  ReplayMerger::Item item;
  while (!stop_sources_.load(std::memory_order_relaxed)) {
    const SourceStatus st = merger.next(item);
    if (st == SourceStatus::kEnd) break;
    if (st != SourceStatus::kOk) continue;
    const std::int64_t t = item.t_ns();
    clock_.anchor(t, mono_ns() + kReplayStartNs);
    const std::int64_t due = clock_.due_mono_ns(t);
    if (due - mono_ns() > kReadAheadNs) {
      // Far enough ahead: hand what we have to the angle thread, sleep until this item is half a window away.
      angle_wake_.notify();
      const std::int64_t wake = due - kReadAheadNs / 2;
      while (!stop_sources_.load(std::memory_order_relaxed) && mono_ns() < wake) {
        const std::int64_t until = std::min(wake, mono_ns() + 50'000'000);  // bounded: notice a stop request
        timespec ts{static_cast<time_t>(until / 1'000'000'000), static_cast<long>(until % 1'000'000'000)};
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
      }
    }
    if (item.kind == ReplayMerger::Kind::kEdge) {
      (void)edge_ring_.try_push(EdgeIn{item.edge, 0});
    } else {
      (void)can_angle_ring_.try_push(FrameIn{item.frame, 0});
      (void)can_time_ring_.try_push(FrameIn{item.frame, 0});
    }
  }
  std::uint64_t drops = 0;
  if (edges_) drops += edges_->stats().bad_lines + edges_->stats().dropped;
  if (can_) drops += can_->stats().bad_lines + can_->stats().dropped;
  source_drops_.store(drops, std::memory_order_relaxed);
  sources_running_.fetch_sub(1);
  angle_wake_.notify();
}

void Runtime::live_edge_loop() {
  EdgeEvent e{};
  while (!stop_sources_.load(std::memory_order_relaxed)) {
    const SourceStatus st = edges_->next(e);
    if (st == SourceStatus::kEnd || st == SourceStatus::kError) break;
    if (st != SourceStatus::kOk) continue;
    clock_.anchor(e.t_ns, mono_ns());
    (void)edge_ring_.try_push(EdgeIn{e, realtime_ns()});
    angle_wake_.notify();
  }
  sources_running_.fetch_sub(1);
}

void Runtime::live_can_loop() {
  CanFrame f{};
  while (!stop_sources_.load(std::memory_order_relaxed)) {
    const SourceStatus st = can_->next(f);
    if (st == SourceStatus::kEnd || st == SourceStatus::kError) break;
    if (st != SourceStatus::kOk) continue;
    f.t_ns += can_offset_ns_;
    (void)can_angle_ring_.try_push(FrameIn{f, realtime_ns()});
    (void)can_time_ring_.try_push(FrameIn{f, realtime_ns()});
    angle_wake_.notify();
  }
  sources_running_.fetch_sub(1);
}

// ---- pipelines ------------------------------------------------------------------------------------------

void Runtime::angle_loop() {
  auto has_work = [this] { return !edge_ring_.empty() || !can_angle_ring_.empty(); };
  for (;;) {
    hb_angle_.fetch_add(1, std::memory_order_relaxed);
    while (stall_.load(std::memory_order_relaxed) && !stop_pipelines_.load(std::memory_order_relaxed))
      usleep(10'000);  // test hook only: a stalled pipeline makes no progress
    if (angle_tunables_.full.load(std::memory_order_acquire) != 0) {
      angle_->apply(angle_tunables_.value);
      edge_timeout_ns_.store(angle_tunables_.value.edge_timeout_ns, std::memory_order_relaxed);
      angle_tunables_.full.store(0, std::memory_order_release);
    }
    TorqueEstimate te{};
    if (time_estimate_.load_new(te))
      angle_->chain().set_time_estimate(te, /*uses_can=*/true);  // time → fusion
    const DueItem next = angle_process_due();
    angle_check_edge_timeout();
    angle_publish_counters();
    if (stop_pipelines_.load(std::memory_order_acquire) && !has_work()) break;
    // Paced replay: the next item is due at next.due and the timer is this thread's only wake-up. The
    // publisher is told, so it can be awake when this edge's samples come (realtime.publisher_spin_us).
    // Released after this pass's pushes: a publisher that sees the value change also sees their samples.
    next_due_tooth_.store(next.tooth, std::memory_order_relaxed);
    next_due_mono_ns_.store(next.due, std::memory_order_release);
    if (next.due != 0) {
      const std::int64_t now = mono_ns();
      const std::int64_t until = std::min(next.due, now + 50'000'000);
      if (until > now) angle_wakeups_.fetch_add(1, std::memory_order_relaxed);
      timespec ts{static_cast<time_t>(until / 1'000'000'000), static_cast<long>(until % 1'000'000'000)};
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    } else {
      if (!has_work()) angle_wakeups_.fetch_add(1, std::memory_order_relaxed);
      angle_wake_.wait_for(50'000'000, has_work);
    }
  }
}

// Edges in order; CAN frames up to each edge's time first, so the stage sees the replay's order. Read-ahead
// replay items (ingest_ns == 0) are processed at their due time: returns the first item not yet due (0:
// none), and whether it is a crank tooth edge (it may produce samples). Once the sources stop, drains without
// waiting.
Runtime::DueItem Runtime::angle_process_due() noexcept {
  DueItem next;
  while (const EdgeIn* e = edge_ring_.front()) {
    std::int64_t ingest = e->ingest_ns;
    if (ingest == 0) {
      const std::int64_t due = clock_.due_mono_ns(e->e.t_ns);
      if (due - mono_ns() > 0 && !stop_sources_.load(std::memory_order_relaxed)) {
        next = next_wakeup(e->e, due);
        break;
      }
      angle_take_ns_ = realtime_ns();
      ingest = angle_take_ns_ + (due - mono_ns());  // the edge "happens" at its due time (incl. our wake-up)
    } else if (opt_.stage_trace > 0) {
      angle_take_ns_ = realtime_ns();
    }
    while (const FrameIn* f = can_angle_ring_.front()) {
      if (f->f.t_ns > e->e.t_ns) break;
      angle_->on_frame(f->f);
      ++angle_frames_;
      can_angle_ring_.pop_front();
    }
    angle_->on_edge(e->e, ingest);
    if (e->e.channel == s_.decoder.crank_channel)
      last_crank_active_ = (e->e.level != 0) == s_.wheel.rising_edge;
    last_t_ns_.store(e->e.t_ns, std::memory_order_relaxed);
    edge_ring_.pop_front();
  }
  // Frames due now are taken now. A frame not due yet gets a wake-up of its own only when no edge waits in
  // the ring: otherwise it is taken, in order, before the first edge after it, at that edge's (or a later)
  // wake-up.
  while (const FrameIn* f = can_angle_ring_.front()) {
    if (f->ingest_ns == 0 && !stop_sources_.load(std::memory_order_relaxed)) {
      const std::int64_t due = clock_.due_mono_ns(f->f.t_ns);
      if (due > mono_ns()) {
        if (next.due == 0) next = DueItem{due, false};
        break;
      }
    }
    angle_->on_frame(f->f);
    ++angle_frames_;
    can_angle_ring_.pop_front();
  }
  return next;
}

// An edge can make the chain emit samples only if it is a crank edge of the wheel's polarity, or, when the
// decoder debounces (decoder.min_pulse_us > 0), the opposite crank edge, which confirms the held tooth (an
// edge of the wheel's polarity then emits only when the opposite edge before it was missing). Cam edges and
// the other crank edges only change the decoder's state: they need no wake-up at their own due time, as long
// as the decoder sees them, in order, before the next edge that can emit. So the angle thread sleeps until
// the first such edge queued (looking at most kLookahead records ahead) and takes the edges before it at that
// wake-up, each stamped with its own due time. No such edge queued yet: the first edge's due time, as before.
// A wrong guess costs latency only (the samples come at the next wake-up), never order or values.
bool Runtime::edge_may_emit(const EdgeEvent& e, bool& prev_active) const noexcept {
  if (e.channel != s_.decoder.crank_channel) return false;
  const bool active = (e.level != 0) == s_.wheel.rising_edge;
  const bool emits = s_.decoder.min_pulse_us > 0.0 ? !active || prev_active : active;
  prev_active = active;
  return emits;
}

Runtime::DueItem Runtime::next_wakeup(const EdgeEvent& first, std::int64_t first_due) noexcept {
  constexpr std::size_t kLookahead = 64;
  bool prev_active = last_crank_active_;
  if (edge_may_emit(first, prev_active)) return DueItem{first_due, true};
  for (std::size_t i = 1; i < kLookahead; ++i) {
    const EdgeIn* e = edge_ring_.peek(i);
    if (!e || e->ingest_ns != 0) break;
    if (edge_may_emit(e->e, prev_active)) return DueItem{clock_.due_mono_ns(e->e.t_ns), true};
  }
  return DueItem{first_due, false};
}

// No edge for a while: let the decoder time out (stalled) on the edge clock, flag the edge time-out.
void Runtime::angle_check_edge_timeout() noexcept {
  if (!clock_.anchored()) return;
  const std::int64_t now_edge = clock_.rec_at(mono_ns());
  const bool timed_out = now_edge - last_t_ns_.load(std::memory_order_relaxed) >
                         edge_timeout_ns_.load(std::memory_order_relaxed);
  if (timed_out) angle_->poll(now_edge);
  edge_timeout_.store(timed_out, std::memory_order_relaxed);
}

void Runtime::angle_publish_counters() noexcept {
  const AngleChain& chain = angle_->chain();
  const auto& ds = chain.decoder().stats();
  n_edges_.store(ds.edges, std::memory_order_relaxed);
  teeth_.store(ds.teeth, std::memory_order_relaxed);
  sync_losses_.store(ds.sync_losses, std::memory_order_relaxed);
  rejected_edges_.store(ds.rejected_edges, std::memory_order_relaxed);
  cam_phase_errors_.store(ds.cam_phase_errors, std::memory_order_relaxed);
  cycles_.store(chain.cycles(), std::memory_order_relaxed);
  if (const AnglePipeline* p = chain.pipeline()) {
    fuel_refs_.store(p->fuel_model().state().references, std::memory_order_relaxed);
    fuel_cells_.store(p->fuel_model().learned_cells(), std::memory_order_relaxed);
  }
  if (const BurnPhaseLearner* b = chain.burn_phase()) {
    burn_state_.store(static_cast<std::uint8_t>(b->stats().state), std::memory_order_relaxed);
    burn_offset_deg_.store(b->offset_deg(), std::memory_order_relaxed);
  }
  frames_.store(angle_frames_, std::memory_order_relaxed);
  stale_mask_.store(chain.status().stale_mask, std::memory_order_relaxed);
  synced_.store(chain.decoder().state() == SyncState::kSynced, std::memory_order_relaxed);
}

void Runtime::time_loop() {
  const int fd = timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC);
  if (fd < 0) return;
  const std::int64_t step = time_->step_ns();
  itimerspec its{};
  its.it_interval.tv_sec = step / 1'000'000'000;
  its.it_interval.tv_nsec = step % 1'000'000'000;
  its.it_value = its.it_interval;
  timerfd_settime(fd, 0, &its, nullptr);
  ToothSample ts{};
  FrameIn fi{};
  while (!stop_pipelines_.load(std::memory_order_acquire)) {
    std::uint64_t expirations = 0;
    if (read(fd, &expirations, sizeof expirations) != static_cast<ssize_t>(sizeof expirations)) continue;
    hb_time_.fetch_add(1, std::memory_order_relaxed);
    if (time_tunables_.full.load(std::memory_order_acquire) != 0) {
      time_->apply(time_tunables_.value);
      time_tunables_.full.store(0, std::memory_order_release);
    }
    if (expirations > 1) overruns_.fetch_add(expirations - 1, std::memory_order_relaxed);
    while (tooth_ring_.try_pop(ts)) time_->on_tooth(ts);
    if (!clock_.anchored()) {
      while (can_time_ring_.try_pop(fi)) time_->on_frame(fi.f);
      continue;
    }
    const std::int64_t t_edge = clock_.rec_at(mono_ns());  // edge-clock time of this tick
    // Paced replay reads ahead: frames later than this tick wait for their time (live frames are never
    // early).
    while (const FrameIn* f = can_time_ring_.front()) {
      if (f->ingest_ns == 0 && f->f.t_ns > t_edge && !stop_sources_.load(std::memory_order_relaxed)) break;
      time_->on_frame(f->f);
      can_time_ring_.pop_front();
    }
    time_->step(t_edge, realtime_ns());
    time_estimate_.store(time_->pipeline().output().uio);  // → angle thread: fusion's external source
  }
  close(fd);
}

// ---- publisher ------------------------------------------------------------------------------------------

// Latency percentiles over the status period (the supervisor publishes them in DaemonStatus).
void Runtime::take_latency_period() noexcept {
  if (mono_ns() - lat_period_start_ns_ < s_.status_period_ns || latency_.period_count() == 0) return;
  const LatencyFigures f = latency_.take_period();
  lat_p50_.store(f.p50_ns, std::memory_order_relaxed);
  lat_p99_.store(f.p99_ns, std::memory_order_relaxed);
  lat_max_.store(f.max_ns, std::memory_order_relaxed);
  const LatencyFigures r = latency_.run();
  lat_run_p50_.store(r.p50_ns, std::memory_order_relaxed);
  lat_run_p99_.store(r.p99_ns, std::memory_order_relaxed);
  lat_run_max_.store(r.max_ns, std::memory_order_relaxed);
  lat_period_start_ns_ = mono_ns();
}

bool Runtime::drain_out() noexcept {
  bool any = false;
  dds::AnySample s;
  for (SpscRing<dds::AnySample>* r : {&out_status_ring_, &out_angle_ring_, &out_time_ring_}) {
    while (r->try_pop(s)) {
      any = true;
      const bool trace = opt_.stage_trace > 0 && s.topic == dds::Topic::kCrankState;
      const std::int64_t taken = trace ? realtime_ns() : 0;
      final_out_.emit(s);
      const std::int64_t ingest = s.visit([](const auto& v) { return v.ingest_t_ns; });
      const std::int64_t written = realtime_ns();
      if (ingest > 0 && s.topic != dds::Topic::kDaemonStatus) latency_.note(written - ingest);
      if (trace) trace_crank(s, taken, written);
    }
  }
  return any;
}

// Stage trace: this CrankState's stamps, joined with those the angle thread pushed before the sample (older
// ones, of samples the output ring dropped, are skipped). Kept while the reserved vector has room.
void Runtime::trace_crank(const dds::AnySample& s, std::int64_t taken_ns, std::int64_t written_ns) noexcept {
  const std::uint64_t seq = s.u.crank.seq;
  AngleStamps a{};
  while (const AngleStamps* f = stamp_ring_.front()) {
    if (f->seq > seq) break;
    a = *f;
    stamp_ring_.pop_front();
    if (a.seq == seq) break;
  }
  if (a.seq != seq || trace_.size() == trace_.capacity()) return;
  trace_.push_back(StageStamps{seq, s.u.crank.ingest_t_ns, a.angle_ns, a.pushed_ns, taken_ns, written_ns});
}

void Runtime::publisher_loop() {
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL,
        0UL);  // SCHED_OTHER timers have 50 us slack by default: wake on time
  lat_period_start_ns_ = mono_ns();
  auto has_work = [this] {
    return !out_angle_ring_.empty() || !out_time_ring_.empty() || !out_status_ring_.empty();
  };
  for (;;) {
    hb_pub_.fetch_add(1, std::memory_order_relaxed);
    drain_out();
    take_latency_period();
    if (stop_publisher_.load(std::memory_order_acquire) && !has_work()) break;
    const std::int64_t due = next_due_mono_ns_.load(std::memory_order_acquire);
    const std::int64_t t_now = mono_ns();
    // (a due time more than one poll in the past is stale: the angle thread is stalled or stopping)
    if (opt_.publisher_spin_ns > 0 && due != 0 && due - t_now < 100'000'000 &&
        t_now - due < opt_.publisher_spin_ns) {
      // Pre-wake (paced replay): sleep until the edge the angle thread waits for is due (any sample wakes us
      // earlier). If it is a tooth edge, poll for its samples until they come, the angle thread moves on to
      // the next edge (nothing to publish) or publisher_spin_ns passes. The samples then find this thread
      // awake: no futex wake-up between the angle thread and DDS.
      if (due > t_now) pub_wake_.wait_for(due - t_now, has_work);
      if (next_due_tooth_.load(std::memory_order_relaxed) && !has_work()) {
        pub_polls_.fetch_add(1, std::memory_order_relaxed);
        const std::int64_t until = std::max(mono_ns(), due) + opt_.publisher_spin_ns;
        while (!has_work() && next_due_mono_ns_.load(std::memory_order_acquire) == due && mono_ns() < until)
          cpu_relax();
        if (!has_work() && next_due_mono_ns_.load(std::memory_order_acquire) == due)
          pub_poll_misses_.fetch_add(1,
                                     std::memory_order_relaxed);  // the angle thread was later than the poll
      } else if (!has_work() && due <= mono_ns() &&
                 next_due_mono_ns_.load(std::memory_order_acquire) == due) {
        // A non-tooth edge is due: let the angle thread take it before we read the next due time.
        pub_wake_.wait_for(20'000, has_work);
      }
    } else {
      pub_wake_.wait_for(opt_.publisher_spin_ns > 0 ? 10'000'000 : 100'000'000, has_work);
    }
  }
  drain_out();
  lat_period_start_ns_ = 0;  // the figures of the last, partial period and of the whole run
  if (latency_.period_count() > 0) take_latency_period();
}

// ---- supervisor interface --------------------------------------------------------------------------------

bool Runtime::request_tunables(const RuntimeTunables& t, std::int64_t timeout_ns) {
  const std::int64_t deadline = mono_ns() + timeout_ns;
  bool ok = true;
  for (TunablesMailbox* mb : {&angle_tunables_, &time_tunables_}) {
    while (mb->full.load(std::memory_order_acquire) != 0 && mono_ns() < deadline) usleep(1000);
    if (mb->full.load(std::memory_order_acquire) != 0) {
      ok = false;
      continue;
    }
    mb->value = t;
    mb->full.store(1, std::memory_order_release);
  }
  angle_wake_.notify();
  return ok;
}

void Runtime::push_status(const dds::AnySample& s) noexcept {
  if (out_status_ring_.try_push(s)) pub_wake_.notify();
}

std::vector<std::string> Runtime::input_problems() const { return torqued::input_problems(edges_, can_); }

bool Runtime::input_done() const noexcept {
  return sources_running_.load() == 0 && edge_ring_.empty() && can_angle_ring_.empty();
}

RuntimeCounters Runtime::counters() const noexcept {
  RuntimeCounters c;
  c.edges = n_edges_.load(std::memory_order_relaxed);
  c.teeth = teeth_.load(std::memory_order_relaxed);
  c.cycles = cycles_.load(std::memory_order_relaxed);
  c.can_frames = frames_.load(std::memory_order_relaxed);
  c.sync_losses = sync_losses_.load(std::memory_order_relaxed);
  c.rejected_edges = rejected_edges_.load(std::memory_order_relaxed);
  c.cam_phase_errors = cam_phase_errors_.load(std::memory_order_relaxed);
  c.fuel_references = fuel_refs_.load(std::memory_order_relaxed);
  c.fuel_cells = fuel_cells_.load(std::memory_order_relaxed);
  c.burn_phase_state = burn_state_.load(std::memory_order_relaxed);
  c.burn_phase_offset_deg = burn_offset_deg_.load(std::memory_order_relaxed);
  c.ring_drops_edge = edge_ring_.drops() + tooth_ring_.drops();
  c.ring_drops_can = can_angle_ring_.drops() + can_time_ring_.drops();
  c.ring_drops_out = out_angle_ring_.drops() + out_time_ring_.drops() + out_status_ring_.drops();
  c.source_drops = source_drops_.load(std::memory_order_relaxed);
  c.overruns = overruns_.load(std::memory_order_relaxed);
  c.latency_p50_ns = lat_p50_.load(std::memory_order_relaxed);
  c.latency_p99_ns = lat_p99_.load(std::memory_order_relaxed);
  c.latency_max_ns = lat_max_.load(std::memory_order_relaxed);
  c.run_latency_p50_ns = lat_run_p50_.load(std::memory_order_relaxed);
  c.run_latency_p99_ns = lat_run_p99_.load(std::memory_order_relaxed);
  c.run_latency_max_ns = lat_run_max_.load(std::memory_order_relaxed);
  c.angle_wakeups = angle_wakeups_.load(std::memory_order_relaxed);
  c.publisher_polls = pub_polls_.load(std::memory_order_relaxed);
  c.publisher_poll_misses = pub_poll_misses_.load(std::memory_order_relaxed);
  c.flags = flags_.load(std::memory_order_relaxed);
  if (edge_timeout_.load(std::memory_order_relaxed)) c.flags |= torque_STATUS_EDGE_TIMEOUT;
  c.sensor_timeouts = static_cast<std::uint32_t>(stale_mask_.load(std::memory_order_relaxed));
  c.synced = synced_.load(std::memory_order_relaxed);
  return c;
}

Heartbeats Runtime::heartbeats() const noexcept {
  return {hb_angle_.load(std::memory_order_relaxed), hb_time_.load(std::memory_order_relaxed),
          hb_pub_.load(std::memory_order_relaxed)};
}

bool Runtime::stop_and_drain(std::int64_t timeout_ns) {
  const std::int64_t deadline = mono_ns() + timeout_ns;
  stop_sources_.store(true);
  if (edges_) edges_->request_stop();
  if (can_) can_->request_stop();
  if (src_thread_.joinable()) src_thread_.join();
  if (src2_thread_.joinable()) src2_thread_.join();
  // Let the pipelines empty their input rings, bounded in time.
  while ((!edge_ring_.empty() || !can_angle_ring_.empty()) && mono_ns() < deadline) {
    angle_wake_.notify();
    usleep(1000);
  }
  const bool drained = edge_ring_.empty() && can_angle_ring_.empty();
  stop_pipelines_.store(true, std::memory_order_release);
  stall_.store(false);
  angle_wake_.notify();
  if (angle_thread_.joinable()) angle_thread_.join();
  if (time_thread_.joinable()) time_thread_.join();
  stop_publisher_.store(true, std::memory_order_release);
  pub_wake_.notify();
  if (pub_thread_.joinable()) pub_thread_.join();
  return drained;
}

}  // namespace torqued
