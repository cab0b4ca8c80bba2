#include "rt_setup.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace torqued {
namespace {
void fail(RtOutcome& o, const char* what, int err) {
  o.ok = false;
  if (err == EPERM || err == EACCES) o.not_permitted = true;
  if (!o.message.empty()) o.message += "; ";
  o.message += what;
  o.message += ": ";
  o.message += std::strerror(err);
}
}  // namespace

RtOutcome lock_memory(bool on_fault) noexcept {
  RtOutcome o;
  if (mlockall(MCL_CURRENT | MCL_FUTURE | (on_fault ? MCL_ONFAULT : 0)) != 0)
    fail(o, on_fault ? "mlockall(MCL_CURRENT|MCL_FUTURE|MCL_ONFAULT)" : "mlockall(MCL_CURRENT|MCL_FUTURE)",
         errno);
  return o;
}

RtOutcome set_default_thread_stack(std::size_t bytes) noexcept {
  RtOutcome o;
#if defined(__SANITIZE_THREAD__)
  // ThreadSanitizer's pthread_create refuses (EINVAL) a default stack this small: it needs its own room per
  // thread. Stack sizing is a memory target of the release build, not something the TSan tier checks.
  (void)bytes;
  return o;
#endif
  pthread_attr_t attr;
  if (const int err = pthread_getattr_default_np(&attr)) {
    fail(o, "pthread_getattr_default_np", err);
    return o;
  }
  if (const int err = pthread_attr_setstacksize(&attr, bytes))
    fail(o, "pthread_attr_setstacksize", err);
  else if (const int err2 = pthread_setattr_default_np(&attr))
    fail(o, "pthread_setattr_default_np", err2);
  pthread_attr_destroy(&attr);
  return o;
}

std::size_t current_thread_stack_size() noexcept {
  pthread_attr_t attr;
  if (pthread_getattr_np(pthread_self(), &attr) != 0) return 0;
  std::size_t size = 0;
  if (pthread_attr_getstacksize(&attr, &size) != 0) size = 0;
  pthread_attr_destroy(&attr);
  return size;
}

MemoryUse read_memory_use() noexcept {
  MemoryUse m;
  std::FILE* f = std::fopen("/proc/self/status", "re");
  if (!f) return m;
  char line[256];
  while (std::fgets(line, sizeof line, f)) {
    unsigned long long kb = 0;
    if (std::sscanf(line, "VmRSS: %llu kB", &kb) == 1)
      m.rss = static_cast<std::size_t>(kb) * 1024;
    else if (std::sscanf(line, "VmHWM: %llu kB", &kb) == 1)
      m.peak = static_cast<std::size_t>(kb) * 1024;
    else if (std::sscanf(line, "VmLck: %llu kB", &kb) == 1)
      m.locked = static_cast<std::size_t>(kb) * 1024;
  }
  std::fclose(f);
  // Resident memory of the locked mappings (Linux ≥ 4.14); VmLck alone counts reserved address space.
  if (std::FILE* r = std::fopen("/proc/self/smaps_rollup", "re")) {
    while (std::fgets(line, sizeof line, r)) {
      unsigned long long kb = 0;
      if (std::sscanf(line, "Locked: %llu kB", &kb) == 1)
        m.locked_resident = static_cast<std::size_t>(kb) * 1024;
    }
    std::fclose(r);
  }
  return m;
}

ThreadUsage read_thread_usage() noexcept {
  ThreadUsage u;
  rusage r{};
  if (getrusage(RUSAGE_THREAD, &r) != 0) return u;
  u.minor_faults = r.ru_minflt;
  u.major_faults = r.ru_majflt;
  u.voluntary_switches = r.ru_nvcsw;
  u.forced_switches = r.ru_nivcsw;
  return u;
}

ThreadUsage usage_between(const ThreadUsage& from, const ThreadUsage& to) noexcept {
  return {to.minor_faults - from.minor_faults, to.major_faults - from.major_faults,
          to.voluntary_switches - from.voluntary_switches, to.forced_switches - from.forced_switches};
}

void prefault_stack(std::size_t bytes) noexcept {
  // A volatile buffer the compiler cannot drop; alloca-free and bounded.
  constexpr std::size_t kChunk = 4096;
  volatile unsigned char buf[kPrefaultStackBytes];
  const std::size_t n = bytes < sizeof buf ? bytes : sizeof buf;
  for (std::size_t i = 0; i < n; i += kChunk) buf[i] = 0;
}

RtOutcome apply_to_current_thread(const ThreadRt& rt) noexcept {
  RtOutcome o;
  if (rt.name && rt.name[0]) pthread_setname_np(pthread_self(), rt.name);
  if (!rt.cpus.empty()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (int c : rt.cpus)
      if (c >= 0 && c < CPU_SETSIZE) CPU_SET(c, &set);
    if (const int err = pthread_setaffinity_np(pthread_self(), sizeof set, &set))
      fail(o, "pthread_setaffinity_np", err);
  }
  sched_param sp{};
  sp.sched_priority = rt.fifo ? rt.priority : 0;
  if (const int err = pthread_setschedparam(pthread_self(), rt.fifo ? SCHED_FIFO : SCHED_OTHER, &sp))
    fail(o, rt.fifo ? "pthread_setschedparam(SCHED_FIFO)" : "pthread_setschedparam(SCHED_OTHER)", err);
  prefault_stack();
  return o;
}

ScopedThreadRt::ScopedThreadRt(const ThreadRt& rt) noexcept {
  sched_param sp{};
  have_policy_ = pthread_getschedparam(pthread_self(), &policy_, &sp) == 0;
  priority_ = sp.sched_priority;
  have_affinity_ = pthread_getaffinity_np(pthread_self(), sizeof affinity_, &affinity_) == 0;
  ThreadRt unnamed = rt;
  unnamed.name = "";
  if (!rt.cpus.empty() || rt.fifo) outcome_ = apply_to_current_thread(unnamed);
}

ScopedThreadRt::~ScopedThreadRt() {
  if (have_affinity_) pthread_setaffinity_np(pthread_self(), sizeof affinity_, &affinity_);
  if (have_policy_) {
    sched_param sp{};
    sp.sched_priority = priority_;
    pthread_setschedparam(pthread_self(), policy_, &sp);
  }
}

}  // namespace torqued
