#pragma once
// Crank wheels by their common names: "60-2", "36-1", "24-1", ... (N positions, M missing in one gap) and the
// irregular production wheels as explicit tooth lists: "36-2-1" (17 teeth, gap 2, 16 teeth, gap 1) and
// "36-2-2-2" (Subaru H4: 13 teeth, gap 2, 16 teeth, gap 2, 1 tooth, gap 2). Load-time helper.
#include <string>
#include <string_view>

#include "engine_geometry.hpp"

namespace torqued {

/// Fills `wheel` (positions/missing or tooth_angles_deg; rising_edge untouched). False with `error` set.
bool wheel_from_name(std::string_view name, WheelGeometry& wheel, std::string* error);

/// Explicit wheel from alternating runs: teeth, missing, teeth, missing, ... over `positions` positions.
/// Tooth 0 = the first tooth of the first run (so the list should start right after a gap).
bool wheel_from_runs(int positions, const int* runs, int n_runs, WheelGeometry& wheel, std::string* error);

}  // namespace torqued
