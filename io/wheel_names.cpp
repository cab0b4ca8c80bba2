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
      for (int i = 0; i < runs[r]; ++i)
        w.tooth_angles_deg[static_cast<std::size_t>(n++)] = 360.0 * (pos++) / positions;
    } else {
      pos += runs[r];
    }
  }
  if (pos != positions) {
    if (error)
      *error =
          "wheel: runs cover " + std::to_string(pos) + " positions, expected " + std::to_string(positions);
    return false;
  }
  w.positions = positions;
  w.tooth_count = n;
  w.missing = positions - n;
  wheel = w;
  return true;
}

namespace {
// Each entry in rotation order (teeth passing the sensor with the engine turning forward), starting with the
// first tooth after the entry's first gap.
constexpr NamedWheel kCatalogue[] = {
    {"36-2-1",
     36,
     {17, 1, 16, 2},
     4,
     "Mitsubishi 4B11: 17 teeth, 1 missing, 16 teeth, 2 missing. Published as 36-2-1; the "
     "rotation order was inverted ({17,2,16,1}) in rusEFI too before its fix (issue 13)."},
    {"36-2-2",
     36,
     {16, 2, 16, 2},
     4,
     "two 2-tooth gaps 180 deg apart: 16 teeth, 2 missing, 16 teeth, 2 missing. Symmetric: the crank alone "
     "gives "
     "the position only modulo 180 deg, so the decoder refuses it (needs a cam-resolved half turn)."},
    {"36-2-2-2",
     36,
     {13, 2, 16, 2, 1, 2},
     6,
     "Subaru H4 (EJ): 13 teeth, 2 missing, 16 teeth, 2 missing, 1 tooth, 2 missing (speeduino/rusEFI "
     "'36-2-2-2 H4')."},
    {"36-2-2-2-h4", 36, {13, 2, 16, 2, 1, 2}, 6, "alias of 36-2-2-2"},
    {"arctic-cat",
     24,
     {11, 1, 10, 2},
     4,
     "Arctic Cat two-stroke snowmobile: 24 x 15 deg positions, 11 teeth, 1 missing, 10 teeth, 2 missing; "
     "read "
     "off the rusEFI capture arctic-cat.csv (tests/data/captures/rusefi), gap ratios 3 and 2 as rusEFI "
     "states."},
};
}  // namespace

std::span<const NamedWheel> wheel_catalogue() noexcept { return kCatalogue; }

std::string known_wheel_names() {
  std::string s = "N-M (e.g. 60-2, 36-1, 24-1, 12-1)";
  for (const NamedWheel& w : kCatalogue) s += std::string(", ") + w.name;
  return s;
}

bool wheel_from_name(std::string_view name, WheelGeometry& wheel, std::string* error) {
  for (const NamedWheel& w : kCatalogue) {
    if (name == w.name) return wheel_from_runs(w.positions, w.runs, w.n_runs, wheel, error);
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
    if (p < end && *p == '-')
      ++p;
    else
      break;
  }
  if (p != end || nums.size() != 2 || nums[0] < 3 || nums[0] > kMaxTeeth || nums[1] < 1 ||
      nums[1] >= nums[0] - 1) {
    if (error) {
      *error = "wheel '" + std::string(name) + "': unknown; known wheels: " + known_wheel_names();
    }
    return false;
  }
  wheel.positions = nums[0];
  wheel.missing = nums[1];
  wheel.tooth_count = 0;
  return true;
}

}  // namespace torqued
