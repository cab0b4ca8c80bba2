#pragma once
// What wheel does a capture show? (load-time helper behind `torque-decode --detect-wheel`, docs/io.md): the
// gap structure read off the marking-edge periods, the catalogue entries that match it, the tooth angles to
// paste as wheel.tooth_angles_deg, and the speed range seen.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace torqued {

struct WheelDetection {
  std::string error;      ///< non-empty: no repeating gap structure found (what was seen instead)
  int positions = 0;      ///< equally spaced positions per revolution (teeth + missing)
  std::vector<int> runs;  ///< teeth, missing, teeth, missing, ... starting after the widest gap
  int revolutions = 0;    ///< whole revolutions seen
  int noise_periods = 0;  ///< periods shorter than 0.6 of their neighbours (ignored)
  double rpm_min = 0.0, rpm_max = 0.0;   ///< per-revolution speed range
  std::vector<std::string> matches;      ///< catalogue names (and "N-M" for one gap) with the same wheel
  std::vector<double> tooth_angles_deg;  ///< from runs, tooth 0 = first tooth after the first gap
  std::string decoder_error;             ///< why the decoder refuses this wheel by itself ("" = it syncs)
};

/// Reads the wheel off the times (ns, increasing) of the marking crank edges.
[[nodiscard]] WheelDetection detect_wheel(std::span<const std::int64_t> tooth_t_ns);

/// The report printed by torque-decode --detect-wheel.
[[nodiscard]] std::string describe(const WheelDetection& d);

}  // namespace torqued
