#pragma once
// Wide kinetic-energy window for the 720° balance (brake / indicated cycle means), for the cycle-mean
// accuracy at 4000 rpm. The 720° balance ΔKE/4π differences the window-mean ½J(c_k)(w_k/dt_k)² at the same
// boundary one cycle apart. Inside a window the edge jitter telescopes (each interior edge lengthens one
// period and shortens the next), only the two outer edges remain, divided by the number of periods: the noise
// of the balance falls as 1/window. With the per-cylinder window (±15°, 5 periods) the 0.3 µs edge jitter
// gives ≈ 1.4 N m RMS at 4000 rpm (KE ∝ ω², its relative error ∝ ω·jitter), 84 % of cycles within 2 N m. A
// window of W = 120° ending where the per-cylinder window ends (no extra latency) divides it by ≈ 4. The
// result is still an exact balance: the mean over boundary shifts in [−W + w/2, w/2) of the 720° balance,
// i.e. a 720° cycle mean with W-wide ramps (docs/equations.md §0, CF-2). Real-time safe update(); tables
// built at construction (they come from CycleEnergy's geometry).
#include <cstdint>
#include <vector>

#include "cycle_energy.hpp"
#include "samples.hpp"

namespace torqued {

class CycleKeWindow {
 public:
  /// `window_deg` ≤ 0 disables it (enabled() false). `end_deg`: window end after boundary 0 (per-cylinder
  /// w/2).
  CycleKeWindow(const CycleEnergy& geometry, double window_deg, double end_deg);

  void reset() noexcept;
  [[nodiscard]] bool enabled() const noexcept { return expected_ > 0; }
  /// Real-time safe. Returns true when the window around boundary 0 completed on this tooth.
  bool update(const ToothSample& s) noexcept;
  /// update() for a sample already checked as update() does (synced, finite positive dt and width, tooth in
  /// [0, samples)): AnglePipeline::on_tooth checks once per tooth. Real-time safe.
  bool update_checked(const ToothSample& s) noexcept;
  /// Window-mean ½Jθ̇² of the last completed window (J) and whether all its periods were seen in sequence.
  [[nodiscard]] double ke_j() const noexcept { return ke_j_; }
  [[nodiscard]] bool ke_valid() const noexcept { return ke_ok_; }
  /// KE(this window) − KE(the same window one cycle earlier) (J), valid if both were complete with no break.
  [[nodiscard]] double d_ke_cycle_j() const noexcept { return d_ke_j_; }
  [[nodiscard]] bool cycle_valid() const noexcept { return d_ke_ok_; }

 private:
  void restart(int tooth) noexcept;
  int samples_ = 0;
  std::vector<double> j_center_, width_;
  std::vector<std::uint8_t> in_;    ///< 1 if the period ending at tooth k lies in the window
  std::vector<std::uint8_t> last_;  ///< 1 if tooth k closes the window
  int expected_ = 0;                ///< periods in the window
  int prev_tooth_ = -1;
  int count_ = 0;
  double sum_w_ = 0.0, sum_wke_ = 0.0;
  double ke_j_ = 0.0, d_ke_j_ = 0.0;
  bool ke_ok_ = false, d_ke_ok_ = false;
};

}  // namespace torqued
