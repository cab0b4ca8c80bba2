// Crank decoder wheel tables and the identifying-window search. See decoder_wheel.hpp.
#include "decoder_wheel.hpp"

#include <algorithm>
#include <numbers>

namespace torqued {
namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kDegToRad = std::numbers::pi / 180.0;

// Tooth count and nominal tooth angles (listed, or N-M with equal pitch).
std::string init_angles(const WheelGeometry& wheel, WheelTables& tab) {
  const int t = wheel.teeth();
  if (t < 2 || t > kMaxTeeth)
    return "wheel: tooth count " + std::to_string(t) + " outside 2.." + std::to_string(kMaxTeeth);
  tab.teeth = t;
  if (wheel.tooth_count > 0) {
    for (int i = 0; i < t; ++i) {
      const double a = wheel.tooth_angles_deg[static_cast<std::size_t>(i)];
      if (!(a >= 0.0 && a < 360.0) ||
          (i > 0 && !(a > wheel.tooth_angles_deg[static_cast<std::size_t>(i - 1)]))) {
        return "wheel: tooth_angles_deg must be strictly increasing in [0, 360); entry " + std::to_string(i) +
               " is " + std::to_string(a);
      }
      tab.angle[static_cast<std::size_t>(i)] = a * kDegToRad;
    }
    return {};
  }
  if (wheel.positions < 2 || wheel.missing < 1 || wheel.missing >= wheel.positions)
    return "wheel: need positions >= 2 and 1 <= missing < positions (a gap is required for sync)";
  for (int i = 0; i < t; ++i) tab.angle[static_cast<std::size_t>(i)] = kTwoPi * i / wheel.positions;
  return {};
}
}  // namespace

std::string build_wheel_tables(const WheelGeometry& wheel, WheelTables& tab) {
  std::string err = init_angles(wheel, tab);
  if (!err.empty()) return err;
  // Period widths and the pitch (smallest width).
  const int t = tab.teeth;
  tab.pitch_rad = kTwoPi;
  for (int i = 0; i < t; ++i) {
    const double prev = i == 0 ? tab.angle_of(t - 1) - kTwoPi : tab.angle_of(i - 1);
    tab.width[static_cast<std::size_t>(i)] = tab.angle_of(i) - prev;
    tab.pitch_rad = std::min(tab.pitch_rad, tab.width_of(i));
  }
  return {};
}

int shortest_identifying_window(std::span<const int> values) noexcept {
  const int n = static_cast<int>(values.size());
  auto at = [&](int i) { return values[static_cast<std::size_t>((i + 2 * n) % n)]; };
  for (int len = 1; len <= n; ++len) {
    bool unique = true;
    for (int a = 0; a < n && unique; ++a) {
      for (int b = a + 1; b < n && unique; ++b) {
        bool same = true;
        for (int k = 0; k < len && same; ++k) same = at(a - k) == at(b - k);
        unique = !same;
      }
    }
    if (unique) return len;
  }
  return 0;
}

}  // namespace torqued
