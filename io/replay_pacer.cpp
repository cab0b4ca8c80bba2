#include "replay_pacer.hpp"

#include <cerrno>
#include <ctime>

namespace torqued {

std::int64_t ReplayPacer::monotonic_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

std::int64_t ReplayPacer::due_ns(std::int64_t t_ns) const noexcept {
  return wall0_ns_ + static_cast<std::int64_t>(static_cast<double>(t_ns - rec0_ns_) / speed_);
}

std::int64_t ReplayPacer::wait_until(std::int64_t t_ns) noexcept {
  if (speed_ <= 0.0) return 0;
  if (!anchored_) {
    anchored_ = true;
    rec0_ns_ = t_ns;
    wall0_ns_ = monotonic_ns();
    return 0;
  }
  const std::int64_t due = due_ns(t_ns);
  const std::int64_t now = monotonic_ns();
  if (now >= due) return now - due;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(due / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(due % 1'000'000'000);
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
  return 0;
}

}  // namespace torqued
