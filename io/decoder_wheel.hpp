#pragma once
// Crank decoder wheel tables (built once, read by every part of the decoder) and the search shared by the gap
// sync and the pulse-width code: the shortest window of a cyclic sequence that identifies its position.
#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "engine_geometry.hpp"

namespace torqued {

/// Nominal tooth angles and period widths of one revolution (see crank_decoder.hpp for the wheel model).
struct WheelTables {
  int teeth = 0;
  double pitch_rad = 0.0;                 ///< smallest tooth spacing (rad)
  std::array<double, kMaxTeeth> angle{};  ///< nominal tooth angle within a revolution (rad)
  std::array<double, kMaxTeeth> width{};  ///< nominal width of the period ending at tooth i (rad)

  [[nodiscard]] int next(int i) const noexcept { return i + 1 == teeth ? 0 : i + 1; }
  [[nodiscard]] double width_of(int i) const noexcept { return width[static_cast<std::size_t>(i)]; }
  [[nodiscard]] double angle_of(int i) const noexcept { return angle[static_cast<std::size_t>(i)]; }
};

/// Fills `t` from the wheel (listed tooth angles, or N-M with equal pitch). Returns an error text, empty if
/// ok.
[[nodiscard]] std::string build_wheel_tables(const WheelGeometry& wheel, WheelTables& t);

/// Shortest window length L such that the last L values of the cyclic sequence ending at each position
/// (values[a], values[a-1], ..., values[a-L+1], indices mod n) differ between every two positions: the number
/// of consecutive observations that identify where on the cycle one is. 0 when no window does (the sequence
/// is rotationally symmetric). Not real-time (construction only; O(n³)).
[[nodiscard]] int shortest_identifying_window(std::span<const int> values) noexcept;

/// Period trend (ratio of two normalised periods) clamped to [1/max_trend, max_trend].
[[nodiscard]] inline double clamp_trend(double x, double max_trend) noexcept {
  return x > max_trend ? max_trend : (x * max_trend < 1.0 ? 1.0 / max_trend : x);
}

}  // namespace torqued
