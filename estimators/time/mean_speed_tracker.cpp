#include "mean_speed_tracker.hpp"

namespace torqued {

void MeanSpeedTracker::reset() noexcept {
  head_ = 0;
  count_ = 0;
  sum_width_ = 0.0;
  sum_dt_ = 0.0;
  speed_rad_s_ = 0.0;
  valid_ = false;
}

void MeanSpeedTracker::recompute_sums() noexcept {
  sum_width_ = 0.0;
  sum_dt_ = 0.0;
  for (int i = 0; i < count_; ++i) {
    int idx = head_ - 1 - i;  // in [-kCapacity, kCapacity): wrapped by a compare, not a division
    if (idx < 0) idx += kCapacity;
    sum_width_ += width_[static_cast<std::size_t>(idx)];
    sum_dt_ += dt_[static_cast<std::size_t>(idx)];
  }
}

void MeanSpeedTracker::update(const ToothSample& tooth) noexcept {
  t_ns_ = tooth.t_ns;
  if (!tooth.synced || !(tooth.width_rad > 0.0) || !(tooth.dt_s > 0.0)) {
    reset();
    return;
  }
  if (count_ == kCapacity) {  // cannot happen for a window ≤ 720° and a valid wheel; drop the oldest anyway
    const int oldest = oldest_index();
    sum_width_ -= width_[static_cast<std::size_t>(oldest)];
    sum_dt_ -= dt_[static_cast<std::size_t>(oldest)];
    --count_;
  }
  width_[static_cast<std::size_t>(head_)] = tooth.width_rad;
  dt_[static_cast<std::size_t>(head_)] = tooth.dt_s;
  if (++head_ == kCapacity) head_ = 0;
  ++count_;
  sum_width_ += tooth.width_rad;
  sum_dt_ += tooth.dt_s;
  // Drop the oldest teeth while the rest still covers the window (tolerance: round-off of the widths).
  const double need = window_rad_ * (1.0 - 1e-9);
  while (count_ > 1) {
    const int oldest = oldest_index();
    const double w = width_[static_cast<std::size_t>(oldest)];
    if (sum_width_ - w < need) break;
    sum_width_ -= w;
    sum_dt_ -= dt_[static_cast<std::size_t>(oldest)];
    --count_;
  }
  if (head_ == 0) recompute_sums();
  valid_ = sum_width_ >= need;
  if (valid_) speed_rad_s_ = sum_width_ / sum_dt_;
}

}  // namespace torqued
