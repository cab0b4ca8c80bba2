#pragma once
// Recording time ↔ CLOCK_MONOTONIC: the one formula of the paced replay and the live edge clock.
//   due_mono(t_rec) = anchor_mono + (t_rec − anchor_rec) / speed + paused_total
//   rec_at(mono)    = anchor_rec + (mono − anchor_mono − paused_total) · speed   (frozen while paused)
// One rule for the speed: a replay runs at `speed` (> 0; +inf = as fast as possible: everything is due at the
// anchor); live input and a speed <= 0 run at 1. The anchor is set once, by the source thread, at the first
// item; the angle and time threads read it (atomics, no lock). Pause/resume come from one controlling thread.
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>

namespace torqued {

class ReplayClock {
 public:
  explicit ReplayClock(double speed = 1.0, bool live = false) noexcept
      : speed_(live || !(speed > 0.0) ? 1.0 : speed), fast_(std::isinf(speed_)) {}

  [[nodiscard]] double speed() const noexcept { return speed_; }
  [[nodiscard]] bool fast() const noexcept { return fast_; }
  [[nodiscard]] bool anchored() const noexcept { return anchored_.load(std::memory_order_acquire); }

  /// First item: recording time rec_ns happens at monotonic time mono_ns. Later calls are ignored.
  void anchor(std::int64_t rec_ns, std::int64_t mono_ns) noexcept {
    if (anchored()) return;
    anchor_rec_.store(rec_ns, std::memory_order_relaxed);
    anchor_mono_.store(mono_ns, std::memory_order_relaxed);
    anchored_.store(true, std::memory_order_release);
  }

  /// Monotonic time (ns) at which recording time rec_ns is due. While paused: never (max).
  [[nodiscard]] std::int64_t due_mono_ns(std::int64_t rec_ns) const noexcept {
    if (paused_.load(std::memory_order_acquire)) return std::numeric_limits<std::int64_t>::max();
    const std::int64_t base =
        anchor_mono_.load(std::memory_order_relaxed) + shift_.load(std::memory_order_relaxed);
    if (fast_) return base;
    return sat_add(base,
                   to_ns(static_cast<double>(rec_ns - anchor_rec_.load(std::memory_order_relaxed)) / speed_));
  }

  /// Recording time (ns) that is due at monotonic time mono_ns (frozen at the pause while paused).
  [[nodiscard]] std::int64_t rec_at(std::int64_t mono_ns) const noexcept {
    if (paused_.load(std::memory_order_acquire)) mono_ns = paused_at_.load(std::memory_order_relaxed);
    if (fast_) return std::numeric_limits<std::int64_t>::max() / 2;
    const std::int64_t el =
        mono_ns - anchor_mono_.load(std::memory_order_relaxed) - shift_.load(std::memory_order_relaxed);
    return sat_add(anchor_rec_.load(std::memory_order_relaxed), to_ns(static_cast<double>(el) * speed_));
  }

  void pause(std::int64_t mono_ns) noexcept {
    if (paused_.load(std::memory_order_relaxed)) return;
    paused_at_.store(mono_ns, std::memory_order_relaxed);
    paused_.store(true, std::memory_order_release);
  }
  /// Due times move later by the time spent paused.
  void resume(std::int64_t mono_ns) noexcept {
    if (!paused_.load(std::memory_order_relaxed)) return;
    shift_.fetch_add(mono_ns - paused_at_.load(std::memory_order_relaxed), std::memory_order_relaxed);
    paused_.store(false, std::memory_order_release);
  }
  [[nodiscard]] bool paused() const noexcept { return paused_.load(std::memory_order_acquire); }

 private:
  /// A due time that does not fit (a tiny speed: 1 s / 1e-300) saturates instead of an undefined conversion
  /// (config replay.speed is bounded to >= 0.001 for that reason; this keeps any caller defined).
  static std::int64_t to_ns(double v) noexcept {
    constexpr double kMax = 9.2e18;  // below INT64_MAX, exactly representable
    if (!(v < kMax)) return v != v ? 0 : static_cast<std::int64_t>(kMax);
    if (!(v > -kMax)) return -static_cast<std::int64_t>(kMax);
    return static_cast<std::int64_t>(v);
  }
  static std::int64_t sat_add(std::int64_t a, std::int64_t b) noexcept {
    std::int64_t r = 0;
    if (__builtin_add_overflow(a, b, &r))
      return b > 0 ? std::numeric_limits<std::int64_t>::max() : std::numeric_limits<std::int64_t>::min();
    return r;
  }

  double speed_;
  bool fast_;
  std::atomic<bool> anchored_{false}, paused_{false};
  std::atomic<std::int64_t> anchor_rec_{0}, anchor_mono_{0}, shift_{0}, paused_at_{0};
};

}  // namespace torqued
