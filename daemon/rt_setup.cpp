#include "rt_setup.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
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

RtOutcome lock_memory() noexcept {
  RtOutcome o;
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) fail(o, "mlockall(MCL_CURRENT|MCL_FUTURE)", errno);
  return o;
}

void prefault_stack(std::size_t bytes) noexcept {
  // A volatile buffer the compiler cannot drop; alloca-free and bounded.
  constexpr std::size_t kChunk = 4096;
  volatile unsigned char buf[256 * 1024];
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
