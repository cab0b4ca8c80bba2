#pragma once
// The wait of the fast replay's helper threads (sink_thread.hpp, read_ahead_merger.hpp) and of the replay
// when one of them is behind: spin first (the other side runs on the other core and is done within a few
// hundred ns), then give the core away, then sleep 20 µs at a time (the other side is not running). No lock,
// no allocation.
#include <time.h>

#include <thread>

namespace torqued {

/// One step of the wait; `round` counts the steps (0 at the start of each wait).
inline void back_off(unsigned& round) noexcept {
  if (round < 64) {
    __builtin_ia32_pause();
  } else if (round < 128) {
    std::this_thread::yield();
  } else {
    const timespec ts{0, 20'000};
    nanosleep(&ts, nullptr);
  }
  ++round;
}

}  // namespace torqued
