#pragma once
// Replay pacing: as fast as possible (speed 0: never waits, deterministic) or real time keeping the
// recording's timing, optionally scaled (speed 2 = twice as fast). The first record's time is anchored to
// the wall clock at the first call; waits use clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME), so pacing
// does not drift. Used only by source threads (it blocks by design), never by the real-time pipelines.
#include <cstdint>

namespace torqued {

class ReplayPacer {
 public:
  /// speed <= 0: as fast as possible; otherwise the replay speed factor (1 = real time).
  explicit ReplayPacer(double speed = 0.0) noexcept : speed_(speed) {}

  /// Block until the wall-clock moment that corresponds to recording time `t_ns`. Returns how late we
  /// already were (ns, >= 0) — 0 if we had to wait. No-op (returns 0) when as fast as possible.
  std::int64_t wait_until(std::int64_t t_ns) noexcept;
  /// Monotonic time (ns) at which recording time `t_ns` is due (after the anchor is set).
  [[nodiscard]] std::int64_t due_ns(std::int64_t t_ns) const noexcept;

  [[nodiscard]] bool paced() const noexcept { return speed_ > 0.0; }
  [[nodiscard]] double speed() const noexcept { return speed_; }
  /// Forget the anchor (next wait_until re-anchors), e.g. after a seek or a pause.
  void reset() noexcept { anchored_ = false; }

  /// CLOCK_MONOTONIC now (ns).
  [[nodiscard]] static std::int64_t monotonic_ns() noexcept;

 private:
  double speed_;
  bool anchored_ = false;
  std::int64_t rec0_ns_ = 0;   ///< recording time of the anchor
  std::int64_t wall0_ns_ = 0;  ///< monotonic time of the anchor
};

}  // namespace torqued
