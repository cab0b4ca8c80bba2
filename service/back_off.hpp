#pragma once
// The two waits of the fast replay's threads (sink_thread.hpp, read_ahead_merger.hpp). back_off(): the replay
// (the chain's thread) waiting for a helper that is behind: spin first, 4096 `pause` instructions
// (cpu_relax(), rt/clocks.hpp) (tens of µs: the helper runs on the other core), then give the core away 64
// times, then sleep 20 µs at a time. The spin is long because a thread that sleeps lets its virtual CPU halt,
// and waking it in this VM costs more than the wait: spinning 64 times only, the recording thread alone made
// the 20 s steady_3000_mid replay slower under SCHED_FIFO (loop 23.0 -> 30.1 ms, best of 20). rest(): a
// helper with nothing to do sleeps, never spins (with both waits: 23.6 -> 17.7 ms). No lock, no allocation.
#include <time.h>

#include <thread>

#include "clocks.hpp"  // cpu_relax()

namespace torqued {

/// One step of the wait; `round` counts the steps (0 at the start of each wait).
/// Out of line (rarely called) so that a profile shows the waits apart (callgrind runs one thread at a time,
/// and the spin of a thread waiting for a descheduled one is counted as its instructions).
[[gnu::noinline]] inline void back_off(unsigned& round) noexcept {
  if (round < 4096) {
    cpu_relax();
  } else if (round < 4160) {
    std::this_thread::yield();
  } else {
    const timespec ts{0, 20'000};
    nanosleep(&ts, nullptr);
  }
  ++round;
}

/// The helper threads' own wait (nothing to do: the reader's ring full, the writer's empty): sleep 50 µs, no
/// spin. Their rings hold milliseconds of the replay, so a late wake-up costs nothing, while a spinning
/// helper takes the CPU from the replay whenever both share a core.
inline void rest() noexcept {
  const timespec ts{0, 50'000};
  nanosleep(&ts, nullptr);
}

}  // namespace torqued
