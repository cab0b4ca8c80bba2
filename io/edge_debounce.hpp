#pragma once
// Crank decoder part 1 of 4: glitch-pulse debounce of the crank signal (DecoderParams::min_pulse_us). A tooth
// edge is held until the opposite crank edge shows the pulse was at least min_pulse wide; a narrower pulse (a
// glitch) is dropped whole, so neither of its edges shifts a tooth time. Real-time safe; plain members.
#include <cstdint>

namespace torqued {

class EdgeDebounce {
 public:
  enum class Result : std::uint8_t {
    kNone,    ///< nothing to pass on (edge held, or an opposite edge with nothing held)
    kTooth,   ///< a confirmed tooth edge at `tooth_t_ns`
    kGlitch,  ///< a glitch pulse was dropped (count it as a rejected edge)
  };

  explicit EdgeDebounce(std::int64_t min_pulse_ns = 0) noexcept : min_pulse_ns_(min_pulse_ns) {}
  [[nodiscard]] bool enabled() const noexcept { return min_pulse_ns_ > 0; }

  /// One crank edge: `active` = the tooth polarity. On kTooth, `tooth_t_ns` is the confirmed tooth's time.
  Result on_edge(std::int64_t t_ns, bool active, std::int64_t& tooth_t_ns) noexcept;

  /// Forgets the held edge and the last opposite edge (a fresh signal). A sync loss does not call this: the
  /// debounce filters the signal, whatever the decoded position.
  void reset() noexcept {
    has_pending_ = false;
    have_inactive_ = false;
  }

 private:
  std::int64_t min_pulse_ns_ = 0;
  bool has_pending_ = false;  ///< a tooth edge waiting for the opposite edge
  std::int64_t pending_t_ns_ = 0;
  bool have_inactive_ = false;  ///< an opposite (non-tooth) crank edge was seen
  std::int64_t last_inactive_t_ns_ = 0;
};

}  // namespace torqued
