#pragma once
// Mean crank speed for the time-triggered estimators (docs/equations.md §1: "ω mean crank speed, cycle- or
// segment-averaged"): Σ width / Σ dt over the most recent teeth that cover the window (720° or 720°/n_cyl).
// Averaging over whole cycles (or firing segments) removes the in-cycle firing ripple that Na's mean-value
// model (Na-8) does not describe. Fixed-size ring, real-time safe: no allocation, O(1) per tooth
// (the running sums are recomputed from the ring once per wrap to stop round-off drift).
#include <array>
#include <cstdint>

#include "engine_geometry.hpp"
#include "samples.hpp"

namespace torqued {

class MeanSpeedTracker {
 public:
  static constexpr int kCapacity = 2 * kMaxTeeth;  ///< teeth in 720° for the densest wheel

  /// window_rad: 4π (cycle) or 4π/n_cyl (combustion segment); must be in (0, 4π].
  explicit MeanSpeedTracker(double window_rad = 4.0 * 3.141592653589793) noexcept : window_rad_(window_rad) {}

  void reset() noexcept;
  /// Adds one tooth. A tooth with synced == false, or a non-positive width/period, clears the window.
  void update(const ToothSample& tooth) noexcept;

  [[nodiscard]] bool valid() const noexcept { return valid_; }  ///< window fully covered since last sync
  [[nodiscard]] double speed_rad_s() const noexcept { return speed_rad_s_; }
  [[nodiscard]] std::int64_t t_ns() const noexcept { return t_ns_; }  ///< edge time of the newest tooth
  [[nodiscard]] double window_rad() const noexcept { return window_rad_; }
  [[nodiscard]] int teeth_in_window() const noexcept { return count_; }

 private:
  void recompute_sums() noexcept;
  /// Ring index of the oldest tooth, (head_ - count_) mod kCapacity by a compare (per tooth: no division).
  [[nodiscard]] int oldest_index() const noexcept {
    const int i = head_ - count_;
    return i < 0 ? i + kCapacity : i;
  }

  double window_rad_;
  std::array<double, kCapacity> width_{};
  std::array<double, kCapacity> dt_{};
  int head_ = 0;   ///< next write index
  int count_ = 0;  ///< teeth in the window
  double sum_width_ = 0.0;
  double sum_dt_ = 0.0;
  double speed_rad_s_ = 0.0;
  std::int64_t t_ns_ = 0;
  bool valid_ = false;
};

}  // namespace torqued
