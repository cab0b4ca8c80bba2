#pragma once
// Test helper: synced 6° tooth samples of a wheel turning at a constant speed, for the time chain's tests.
#include <cstdint>
#include <numbers>

#include "samples.hpp"

namespace torqued::test {

/// The next tooth after `tooth_t` (ns, advanced) at `w` rad/s.
inline ToothSample next_steady_tooth(std::int64_t& tooth_t, double w) {
  ToothSample ts;
  ts.width_rad = 6.0 * std::numbers::pi / 180.0;
  ts.dt_s = ts.width_rad / w;
  tooth_t += static_cast<std::int64_t>(ts.dt_s * 1e9);
  ts.t_ns = tooth_t;
  ts.synced = true;
  return ts;
}

}  // namespace torqued::test
