// Crank decoder glitch-pulse debounce. See edge_debounce.hpp.
#include "edge_debounce.hpp"

namespace torqued {

EdgeDebounce::Result EdgeDebounce::on_edge(std::int64_t t_ns, bool active,
                                           std::int64_t& tooth_t_ns) noexcept {
  if (active) {
    if (have_inactive_ && t_ns - last_inactive_t_ns_ < min_pulse_ns_) return Result::kGlitch;  // narrow gap
    Result r = Result::kNone;
    if (has_pending_) {  // two tooth edges in a row (opposite edge missing): the older one stands
      tooth_t_ns = pending_t_ns_;
      r = Result::kTooth;
    }
    has_pending_ = true;
    pending_t_ns_ = t_ns;
    return r;
  }
  if (!has_pending_) {
    have_inactive_ = true;
    last_inactive_t_ns_ = t_ns;
    return Result::kNone;
  }
  has_pending_ = false;
  // A narrow pulse is dropped whole: its closing edge is not the last opposite edge either (else the next
  // real tooth, coming soon after a noise pulse, would fail the narrow-gap test above and be lost too).
  if (t_ns - pending_t_ns_ < min_pulse_ns_) return Result::kGlitch;
  have_inactive_ = true;
  last_inactive_t_ns_ = t_ns;
  tooth_t_ns = pending_t_ns_;
  return Result::kTooth;
}

}  // namespace torqued
