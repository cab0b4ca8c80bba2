#pragma once
// Real-time start-up steps, in the fixed order of ros2_control/realtime_tools (docs/conventions.md): lock
// memory (mlockall), then per thread: CPU affinity, scheduling policy/priority, prefault the stack. Each
// failure is reported with errno; "not permitted" (EPERM) is separated so the daemon can start anyway with a
// warning and a status flag unless the config requires real-time.
#include <sched.h>

#include <cstddef>
#include <string>
#include <vector>

namespace torqued {

struct ThreadRt {
  bool fifo = false;      ///< SCHED_FIFO (true) or SCHED_OTHER
  int priority = 0;       ///< 1..99 for SCHED_FIFO
  std::vector<int> cpus;  ///< affinity (empty = any)
  const char* name = "";  ///< thread name (pthread_setname_np, max 15 chars)
};

struct RtOutcome {
  bool ok = true;              ///< everything requested was applied
  bool not_permitted = false;  ///< at least one step failed with EPERM/EACCES
  std::string message;         ///< what failed and why (errno text)
};

/// mlockall(MCL_CURRENT | MCL_FUTURE), with MCL_ONFAULT when on_fault (pages locked when first touched:
/// mapped pages never touched, such as the unused part of a shared-memory segment, stay out of RSS).
RtOutcome lock_memory(bool on_fault = false) noexcept;
/// Applies affinity, policy/priority and the name to the CALLING thread, then prefaults its stack.
RtOutcome apply_to_current_thread(const ThreadRt& rt) noexcept;
/// Gives the calling thread `rt`'s policy, priority and affinity (not its name) until destroyed, then
/// restores what it had. Threads created meanwhile inherit them: used around dds_create_participant so
/// Cyclone's own threads (receive, timed events, gc) run with the publisher's scheduling. Otherwise a
/// SCHED_OTHER Cyclone thread holding a writer lock can be preempted by ordinary load for a whole CFS slice
/// while the real-time publisher waits on that lock (a priority inversion of several milliseconds).
class ScopedThreadRt {
 public:
  explicit ScopedThreadRt(const ThreadRt& rt) noexcept;
  ~ScopedThreadRt();
  ScopedThreadRt(const ScopedThreadRt&) = delete;
  ScopedThreadRt& operator=(const ScopedThreadRt&) = delete;
  [[nodiscard]] const RtOutcome& outcome() const noexcept { return outcome_; }

 private:
  int policy_ = 0;
  int priority_ = 0;
  bool have_policy_ = false;
  bool have_affinity_ = false;
  cpu_set_t affinity_{};
  RtOutcome outcome_;
};

/// Stack size of every thread of the daemon (ours and Cyclone's): with mlockall(MCL_FUTURE) a thread's whole
/// stack mapping becomes resident, and glibc's default (RLIMIT_STACK, 8 MiB) made ten threads 80 MiB of RSS.
/// The deepest of our threads uses a few tens of KiB (the prefault below is the largest frame); Cyclone's are
/// set in config/cyclonedds-*.xml (Threads/Thread/StackSize) to the same size.
inline constexpr std::size_t kThreadStackBytes = 512 * 1024;
/// Prefaulted part of each real-time thread's stack (what prefault_stack touches).
inline constexpr std::size_t kPrefaultStackBytes = 256 * 1024;

static_assert(kPrefaultStackBytes + 128 * 1024 <= kThreadStackBytes, "room above the prefaulted part");

/// Default stack size of the threads created afterwards without attributes (std::thread, Cyclone's threads
/// without a configured StackSize): pthread_setattr_default_np. Call before creating any thread.
RtOutcome set_default_thread_stack(std::size_t bytes = kThreadStackBytes) noexcept;
/// Stack size of the calling thread (pthread_getattr_np), 0 when unknown.
std::size_t current_thread_stack_size() noexcept;

/// The process's memory as the kernel counts it (/proc/self/status, /proc/self/smaps_rollup), in bytes; 0
/// when not readable.
struct MemoryUse {
  std::size_t rss = 0;              ///< VmRSS: resident now
  std::size_t peak = 0;             ///< VmHWM: peak resident
  std::size_t locked = 0;           ///< VmLck: address space under mlockall, resident or not (glibc's
                                    ///< reserved malloc arenas count here in full and are not memory)
  std::size_t locked_resident = 0;  ///< smaps_rollup "Locked:": resident pages of the locked mappings
};
/// Reads /proc/self/status and /proc/self/smaps_rollup (not real-time: opens files).
MemoryUse read_memory_use() noexcept;

/// Page faults and context switches of the calling thread (getrusage RUSAGE_THREAD); not real-time.
struct ThreadUsage {
  long minor_faults = 0, major_faults = 0;           ///< ru_minflt, ru_majflt
  long voluntary_switches = 0, forced_switches = 0;  ///< ru_nvcsw (it waited), ru_nivcsw (preempted)
};
ThreadUsage read_thread_usage() noexcept;
/// What happened between two readings of the same thread.
ThreadUsage usage_between(const ThreadUsage& from, const ThreadUsage& to) noexcept;

/// Touches `bytes` of the calling thread's stack so later use does not page-fault.
void prefault_stack(std::size_t bytes = kPrefaultStackBytes) noexcept;

}  // namespace torqued
