#include "wheel_names.hpp"

#include <charconv>
#include <vector>

namespace torqued {

bool wheel_from_runs(int positions, const int* runs, int n_runs, WheelGeometry& wheel, std::string* error) {
  int pos = 0, n = 0;
  WheelGeometry w = wheel;
  for (int r = 0; r < n_runs; ++r) {
    if (runs[r] < 0 || (r % 2 == 0 && n + runs[r] > kMaxTeeth)) {
      if (error) *error = "wheel: bad run length";
      return false;
    }
    if (r % 2 == 0) {
      for (int i = 0; i < runs[r]; ++i) w.tooth_angles_deg[static_cast<std::size_t>(n++)] = 360.0 * (pos++) / positions;
    } else {
      pos += runs[r];
    }
  }
  if (pos != positions) {
    if (error) *error = "wheel: runs cover " + std::to_string(pos) + " positions, expected " + std::to_string(positions);
    return false;
  }
  w.positions = positions;
  w.tooth_count = n;
  w.missing = positions - n;
  wheel = w;
  return true;
}

bool wheel_from_name(std::string_view name, WheelGeometry& wheel, std::string* error) {
  if (name == "36-2-1") {
    static constexpr int runs[] = {17, 2, 16, 1};
    return wheel_from_runs(36, runs, 4, wheel, error);
  }
  if (name == "36-2-2-2" || name == "36-2-2-2-h4") {
    static constexpr int runs[] = {13, 2, 16, 2, 1, 2};
    return wheel_from_runs(36, runs, 6, wheel, error);
  }
  std::vector<int> nums;
  const char* p = name.data();
  const char* end = p + name.size();
  while (p < end) {
    int v = 0;
    const auto r = std::from_chars(p, end, v);
    if (r.ec != std::errc() || v < 0) break;
    nums.push_back(v);
    p = r.ptr;
    if (p < end && *p == '-') ++p;
    else break;
  }
  if (p != end || nums.size() != 2 || nums[0] < 3 || nums[0] > kMaxTeeth || nums[1] < 1 || nums[1] >= nums[0] - 1) {
    if (error) {
      *error = "wheel '" + std::string(name) + "': expected N-M (e.g. 60-2, 36-1, 24-1), 36-2-1 or 36-2-2-2";
    }
    return false;
  }
  wheel.positions = nums[0];
  wheel.missing = nums[1];
  wheel.tooth_count = 0;
  return true;
}

}  // namespace torqued
