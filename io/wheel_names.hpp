#pragma once
// Crank wheels by the names engine people use (load-time helper; see docs/io.md "Wheel catalogue"):
//  - "N-M" (60-2, 36-1, 24-1, 12-1, ...): N equally spaced positions, M consecutive ones missing (one gap);
//  - irregular production wheels, as explicit tooth lists in rotation order (kWheelCatalogue below).
// Rotation order: the order in which the teeth pass the sensor while the engine turns forward; tooth 0 is the
// first tooth after the catalogue entry's first gap. All entries are per crank revolution.
#include <span>
#include <string>
#include <string_view>

#include "engine_geometry.hpp"

namespace torqued {

/// One named irregular wheel: alternating runs (teeth, missing, teeth, missing, ...) in rotation order.
struct NamedWheel {
  const char* name;
  int positions;  ///< equally spaced positions per crank revolution, teeth + missing
  int runs[8];    ///< teeth, missing, teeth, missing, ... (rotation order, starting after a gap)
  int n_runs;
  const char* description;  ///< what it is, and where the pattern is published
};

/// The catalogue of named irregular wheels (N-M wheels are not listed: any N-M is accepted).
[[nodiscard]] std::span<const NamedWheel> wheel_catalogue() noexcept;

/// "N-M, 36-2-1, 36-2-2, ..." for messages.
[[nodiscard]] std::string known_wheel_names();

/// Fills `wheel` (positions/missing or tooth_angles_deg; rising_edge untouched). False with `error` set (an
/// unknown name lists the known ones).
bool wheel_from_name(std::string_view name, WheelGeometry& wheel, std::string* error);

/// Explicit wheel from alternating runs: teeth, missing, teeth, missing, ... over `positions` positions.
/// Tooth 0 = the first tooth of the first run (so the list should start right after a gap).
bool wheel_from_runs(int positions, const int* runs, int n_runs, WheelGeometry& wheel, std::string* error);

}  // namespace torqued
