#pragma once
// What wheel does a capture show? (load-time helper behind `torque-decode --detect-wheel`, docs/io.md): the
// gap structure read off the marking-edge periods, the catalogue entries that match it, the tooth angles to
// paste as wheel.tooth_angles_deg, and the speed range seen.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace torqued {

struct WheelCamEdge {
  std::int64_t t_ns = 0;
  bool rising = false;
};

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
  std::string stretch;                   ///< non-empty: only this clean stretch of a noisy capture was read
  std::string ambiguity;  ///< non-empty: why the candidates (each a turn of the same cycle) cannot be told
  std::string thin;       ///< non-empty: too little evidence to name an entry (why); the names are candidates
  // Pattern wheels (no missing-tooth gap; positions == 0): the tooth periods repeat every pattern_teeth.
  int pattern_teeth = 0;        ///< teeth per repeat (smallest repeat of the spacings)
  std::vector<double> spacing;  ///< tooth i to i+1 as a fraction of the repeat, tooth 0 after the widest
  double repeat_deg = 0.0;      ///< crank degrees per repeat (0: unknown, rpm is then per repeat)
  std::vector<std::string> candidates;  ///< equally good catalogue entries the crank alone cannot tell apart
  std::string width_code;               ///< non-empty: the pulse widths are two-valued (width-coded wheel)
  int cam_cycle_teeth = 0;  ///< crank teeth per cam cycle (720 deg) read off the cam edges (0: no cam / none)
};

/// Reads the wheel off the times (ns, increasing) of the marking crank edges; `other_t_ns` (optional) are the
/// crank edges of the other polarity, used only to tell a pulse-width-coded wheel; `cam` (optional) the cam
/// edges, whose pattern repeats once per 720 deg: it gives the teeth per revolution of an equally spaced
/// wheel.
[[nodiscard]] WheelDetection detect_wheel(std::span<const std::int64_t> tooth_t_ns,
                                          std::span<const std::int64_t> other_t_ns = {},
                                          std::span<const WheelCamEdge> cam = {});

/// The report printed by torque-decode --detect-wheel.
[[nodiscard]] std::string describe(const WheelDetection& d);

}  // namespace torqued
