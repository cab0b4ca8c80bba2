#pragma once
// Crank wheels by the names engine people use (load-time helper; see docs/io.md "Wheel catalogue"):
//  - "N-M" (60-2, 36-1, 24-1, 12-1, ...): N equally spaced positions, M consecutive ones missing (one gap);
//  - irregular production wheels, as explicit tooth lists in rotation order (kWheelCatalogue below).
// Rotation order: the order in which the teeth pass the sensor while the engine turns forward; tooth 0 is the
// first tooth after the catalogue entry's first gap. All entries are per crank revolution.
#include <span>
#include <string>
#include <string_view>

#include "crank_decoder.hpp"
#include "engine_geometry.hpp"

namespace torqued {

/// One named irregular wheel: alternating runs (teeth, missing, teeth, missing, ...) in rotation order.
struct NamedWheel {
  const char* name;
  int positions;  ///< equally spaced positions per crank revolution, teeth + missing
  int runs[8];    ///< teeth, missing, teeth, missing, ... (rotation order, starting after a gap)
  int n_runs;
  const char* description;  ///< what it is, and where the pattern is published
  // Wheels whose crank cannot identify the position: the cam pattern or the pulse-width code does.
  bool falling =
      false;      ///< pattern wheels: the crank edge the angles below refer to (set by trigger_from_name)
  int n_cam = 0;  ///< cam-synced: cam edges per 720° cycle (angles from tooth 0 of the first revolution)
  CamEdgeSpec cam[CamPattern::kMaxEdges] = {};
  double cam_tolerance_deg = 0.0;
  bool width_coded = false;  ///< pulse-width-coded (bit i = 1: narrow, see DecoderParams::width_coded)
  std::uint32_t width_code = 0;
};

/// The catalogue of named irregular wheels (N-M wheels are not listed: any N-M is accepted).
[[nodiscard]] std::span<const NamedWheel> wheel_catalogue() noexcept;

/// "N-M, 36-2-1, 36-2-2, ..." for messages.
[[nodiscard]] std::string known_wheel_names();

/// Fills `wheel` (positions/missing or tooth_angles_deg; rising_edge untouched). False with `error` set (an
/// unknown name lists the known ones).
bool wheel_from_name(std::string_view name, WheelGeometry& wheel, std::string* error);

/// Like wheel_from_name, and sets what the wheel needs in `params`: the cam pattern or width code of a
/// pattern wheel (with wheel.rising_edge, which the pattern's angles refer to), cleared for every other
/// wheel.
bool trigger_from_name(std::string_view name, WheelGeometry& wheel, DecoderParams& params,
                       std::string* error);

/// Explicit wheel from alternating runs: teeth, missing, teeth, missing, ... over `positions` positions.
/// Tooth 0 = the first tooth of the first run (so the list should start right after a gap).
bool wheel_from_runs(int positions, const int* runs, int n_runs, WheelGeometry& wheel, std::string* error);

}  // namespace torqued
