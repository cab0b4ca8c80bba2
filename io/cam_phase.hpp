#pragma once
// Crank decoder part 4 of 4: the 720° phase from the cam edge (gap-synced wheels; a cam-synced wheel's
// pattern sync gives the phase itself). A cam edge whose crank angle falls into the cam window
// [start, end) of the 720° cycle fixes which revolution we are in; with cam_window: auto the window is
// learned from the first cam_auto_edges synced cam edges. Real-time safe: plain members.
#include <cstdint>

namespace torqued {

struct DecoderParams;

class CamPhase {
 public:
  enum class Result : std::uint8_t {
    kLearning,  ///< cam_window: auto, still learning the angle (no phase decision)
    kInPhase,   ///< the edge confirms (or first establishes) the phase
    kFlipped,   ///< the phase was known and the edge says the other revolution: the revolution was flipped
    kOutside,   ///< outside the window in both revolutions (or the window covers both): ambiguous
  };

  explicit CamPhase(const DecoderParams& p) noexcept;

  /// One cam edge at a_deg (crank angle within the revolution, 0..360) while synced; `rev` (0/1, the
  /// revolution of the last tooth) is set to the revolution the cam says.
  Result on_edge(double a_deg, int& rev, const DecoderParams& p) noexcept;

  [[nodiscard]] bool known() const noexcept { return known_; }
  void set_known(bool known) noexcept { known_ = known; }
  /// Cam edge angle in the 720° cycle, learned (cam_window: auto) or last measured; -1 none yet.
  [[nodiscard]] double angle_deg() const noexcept { return angle_deg_; }
  /// Back to the configured window, learning restarted, phase unknown.
  void reset(const DecoderParams& p) noexcept;

 private:
  bool learn_step(double a_deg, int& rev, const DecoderParams& p) noexcept;

  bool known_ = false;                        ///< the 720° phase is known
  double win_start_ = 0.0, win_end_ = 360.0;  ///< cam window in use (configured or learned)
  double angle_deg_ = -1.0;
  bool learned_ = false;
  int learn_n_ = 0;
  double learn_first_ = 0.0, learn_sum_ = 0.0;
};

}  // namespace torqued
