#pragma once
// As-fast-as-possible replay: sources -> merger -> angle stage (decoder, angle estimators) and time stage
// (ticks every step on the edge clock, interleaved by time), on the calling thread -> sink (recorder and/or
// publisher). With three threads (replay.fast_threads, StageSettings::fast_threads) the sources and the
// merger run on a reader thread (read_ahead_merger.hpp, handing the records over in order) and daemon_run.cpp
// gives the recorder a thread of its own (sink_thread.hpp); with one, everything runs on the calling thread.
// Deterministic: no wall-clock time enters the outputs (ingest/publish times are 0), ties are broken by the
// merger (edges first), so the same input gives byte-identical CSV output, on one thread or three.
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "angle_chain.hpp"
#include "dbc.hpp"
#include "sample_sink.hpp"
#include "source.hpp"
#include "stage_settings.hpp"
#include "state_store.hpp"
#include "status.hpp"

namespace torqued {

/// The fast replay's threads as resolved from replay.fast_threads, and why (for the daemon's log line).
struct FastThreadsChoice {
  int threads = 1;  ///< 1: all on the calling thread; 3: a reader thread, and the caller's recording writer
  std::string why;  ///< e.g. "replay.fast_threads auto, 2 CPUs usable"
};

/// replay.fast_threads (`setting`: 0 = auto, 1 or 3) for a process that may run on `cpus` CPUs: 1 and 3 as
/// given; auto is 3 with at least 2 CPUs, else 1 (on one CPU a helper only takes turns with the chain).
[[nodiscard]] FastThreadsChoice resolve_fast_threads(int setting, int cpus);
/// CPUs this process may use: the CPUs it may run on (sched_getaffinity: taskset's or a cpuset's limit; 1 if
/// unknown), and no more than its cgroup's CPU quota allows (cgroup_quota_cpus: a container started with
/// `--cpus=1` may run on every CPU but only one CPU's time in total).
[[nodiscard]] int usable_cpus() noexcept;
/// Whole CPUs of run time the cgroup CPU quota allows, floor(quota / period) and at least 1, the smallest
/// along the process's cgroup and its parents; 0 if there is no quota. `proc_self_cgroup`: the text of
/// /proc/self/cgroup; `root`: the cgroup mount (/sys/fs/cgroup). cgroup v2: `<root><path>/cpu.max` ("QUOTA
/// PERIOD" or "max PERIOD"); v1: `<root>/<controllers>/<path>/cpu.cfs_quota_us` and `cpu.cfs_period_us`
/// (quota -1: none). Not real-time.
[[nodiscard]] int cgroup_quota_cpus(const std::string& proc_self_cgroup, const std::string& root);

struct ReplayResult {
  FastThreadsChoice threads;  ///< the threads this replay used (StageSettings::fast_threads resolved)
  RuntimeCounters counters;
  std::uint64_t samples = 0;  ///< samples emitted
  std::int64_t first_t_ns = 0, last_t_ns = 0;
  double wall_s = 0.0;            ///< wall time of the loop (s), up to the sink flushed (recording written)
  std::uint64_t input_waits = 0;  ///< times the replay found the reader thread behind (read_ahead_merger.hpp)
  std::string error;              ///< a source failed (the replay kept going with the other)
  std::string imported;           ///< what of the initial learned state was applied ("" = nothing)
  bool learned = false;           ///< `state` holds what the chain learned (or was given) by the end
  std::vector<std::string> bad_frames;  ///< CAN frames too short for their signals (one line per signal)
  std::vector<std::string>
      input_problems;  ///< bad lines (file:line), inputs with no record (input_problems())
  struct Transitions {
    static constexpr std::size_t kMaxKept = 1000;
    std::vector<DecoderEvent> events;  ///< the decoder's sync-state transitions, in order (first kMaxKept)
    std::uint64_t not_kept = 0;
  } transitions;
  [[nodiscard]] double speedup() const noexcept {
    return wall_s > 0.0 ? static_cast<double>(last_t_ns - first_t_ns) * 1e-9 / wall_s : 0.0;
  }
};

/// Runs the replay to the end of both sources. `out` receives every sample (in emission order).
/// stop (optional): checked every 4096 records; set it from a signal handler to end early.
/// state (optional): in: learned state imported before the first edge (as the service does at start); out:
/// the state at the end (ReplayResult::learned says whether there is one), for the caller to save. tap
/// (optional): receives the angle chain's records too (torque-accuracy reads the full CycleOutput there).
ReplayResult run_fast_replay(const StageSettings& s, EdgeSource* edges, CanSource* can,
                             std::int64_t can_offset_ns, const DbcDatabase* dbc, SampleSink& out,
                             const std::atomic<bool>* stop = nullptr, LearnedState* state = nullptr,
                             AngleChainSink* tap = nullptr);

}  // namespace torqued
