#pragma once
// Learned state (friction coefficients, per-tooth angle corrections) persisted across restarts.
// Written atomically: write <file>.tmp, fsync it, rename over <file>, fsync the directory — a crash or
// kill -9 at any moment leaves either the old or the new complete file, never a torn one.
// Text format (versioned, exact round trip with %.17g):
//   torqued-state 1
//   friction <c1> <c2> <c3> <c4>
//   friction_idle <correction N m> <idle speed rpm>     (optional: FrictionLearner's local idle correction)
//   tooth_corrections <n> <rad_0> ... <rad_n-1>
//   saved_at_t_ns <edge-clock time>
// Not real-time: called by the supervisor thread.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace torqued {

struct LearnedState {
  std::optional<std::array<double, 4>> friction;  ///< FrictionLearner coefficients [C1..C4]
  std::optional<std::array<double, 2>> friction_idle;  ///< idle correction (N m) and its idle speed (rpm)
  std::vector<double> tooth_corrections_rad;        ///< ToothErrorLearner table (empty = none)
  std::int64_t saved_at_t_ns = 0;
};

/// Writes atomically; returns false with `error` set on any failure (the old file stays intact).
bool save_state_atomic(const std::string& path, const LearnedState& s, std::string* error);
/// Reads; nullopt with `error` set when missing or malformed (error names the file and line).
std::optional<LearnedState> load_state(const std::string& path, std::string* error);

}  // namespace torqued
