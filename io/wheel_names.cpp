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
     "rotation order was inverted ({17,2,16,1}) in rusEFI too before its fix."},
    {"36-2-2-16-16",
     36,
     {16, 2, 16, 2},
     4,
     "two 2-tooth gaps 180 deg apart: 16 teeth, 2 missing, 16 teeth, 2 missing. Symmetric: the crank alone "
     "gives the position only modulo 180 deg, so the decoder refuses it (needs a cam-resolved half turn)."},
    {"36-2-2-17-15",
     36,
     {17, 2, 15, 2},
     4,
     "Jeep/Chrysler EVD 36-2-2: 17 teeth, 2 missing, 15 teeth, 2 missing (gaps 160 and 200 deg apart, so the "
     "crank alone gives the position). Tooth counts as a user's capture of the wheel shows them (the gaps "
     "after 17 and 15 teeth); no published tooth list was found to check them against."},
    {"jeep-evd", 36, {17, 2, 15, 2}, 4, "alias of 36-2-2-17-15"},
    {"bosch-60-2",
     60,
     {58, 2},
     2,
     "alias of 60-2: the Bosch VR crank wheel (60 positions, 2 consecutive missing), rusEFI's and "
     "speeduino's 'missing tooth' 60-2."},
    {"ford-edis-36-1",
     36,
     {35, 1},
     2,
     "alias of 36-1: the Ford EDIS crank wheel (36 positions, 1 missing), speeduino's 'missing tooth' "
     "36-1."},
    {"toyota-36-2",
     36,
     {34, 2},
     2,
     "alias of 36-2: Toyota 1ZZ/2ZZ/2AR/2ZR four-cylinder crank wheel (rusEFI's 'Toyota 36-2' discussion: "
     "the "
     "same 36-2 at the same angle on these engines)."},
    {"36-2-2-2",
     36,
     {13, 2, 16, 2, 1, 2},
     6,
     "Subaru H4 (EJ): 13 teeth, 2 missing, 16 teeth, 2 missing, 1 tooth, 2 missing (speeduino/rusEFI "
     "'36-2-2-2 H4')."},
    {"36-2-2-2-h4", 36, {13, 2, 16, 2, 1, 2}, 6, "alias of 36-2-2-2"},
    {"gm-24x",
     24,
     {24},
     1,
     "GM LS 24x (rusEFI TT_GM_24x): a falling edge every 15 deg, the rising edge 3 deg (narrow) or 12 deg "
     "(wide) later; the narrow/wide code 0x0A33BE read LSB first (bit i = 1: the period ending at tooth i is "
     "narrow) identifies the position after 7 teeth. Checked on gm_24x_cranking.csv: 66 consecutive periods "
     "follow the code.",
     true,
     0,
     {},
     0.0,
     true,
     0x0A33BEu},
    {"4g63",
     2,
     {2},
     1,
     "Mitsubishi 4G63 (rusEFI 2 teeth + VVT_MITSUBISHI_4G63): 2 crank teeth per revolution (rising), a cam "
     "(distributor CAS) with one short (74 deg) and one long (178 deg) pulse per cycle. Cam edges read off "
     "4g63-cranking.csv relative to the crank rising edges: F 31, R 317, F 495, R 677 deg.",
     false,
     4,
     {{31.0, false}, {317.0, true}, {495.0, false}, {677.0, true}},
     30.0},
    {"nissan-cas-24+1",
     12,
     {12},
     1,
     "Nissan optical CAS 24+1 (rusEFI TT_12_TOOTH_CRANK + VVT_SINGLE_TOOTH): 24 slots per cam turn = 12 "
     "teeth per crank revolution (rising), one cam slot per cycle; tooth 0 = the first tooth after the slot. "
     "Slot edges read off cas_nissan_24_plus_1.csv: R 699.5, F 711 deg.",
     false,
     2,
     {{699.5, true}, {711.0, false}},
     10.0},
    {"miata-nb2",
     36,
     {1, 6, 1, 10, 1, 6, 1, 10},
     8,
     "Mazda Miata NB2 (rusEFI HELLEN_NB2): 4 crank teeth at 0, 70, 180, 250 deg (rising; symmetric, 70/110 "
     "deg), cam with a double tooth and a single tooth 360 deg apart. Cam rising edges read off "
     "nb2-cranking-good.csv: 126 and 162 (double), 522 (single) deg.",
     false,
     3,
     {{126.0, true}, {162.0, true}, {522.0, true}},
     20.0},
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

bool trigger_from_name(std::string_view name, WheelGeometry& wheel, DecoderParams& params,
                       std::string* error) {
  if (!wheel_from_name(name, wheel, error)) return false;
  params.cam_pattern = CamPattern{};
  params.width_coded = false;
  params.width_code = 0;
  for (const NamedWheel& w : kCatalogue) {
    if (name != w.name || (w.n_cam == 0 && !w.width_coded)) continue;
    wheel.rising_edge = !w.falling;
    params.cam_pattern.n = w.n_cam;
    for (int j = 0; j < w.n_cam; ++j) params.cam_pattern.edges[static_cast<std::size_t>(j)] = w.cam[j];
    if (w.n_cam > 0) params.cam_pattern.tolerance_deg = w.cam_tolerance_deg;
    params.width_coded = w.width_coded;
    params.width_code = w.width_code;
  }
  return true;
}

std::span<const NamedWheel> wheel_catalogue() noexcept { return kCatalogue; }

std::string known_wheel_names() {
  std::string s = "N-M (e.g. 60-2, 36-1, 24-1, 12-1)";
  for (const NamedWheel& w : kCatalogue) s += std::string(", ") + w.name;
  return s;
}

namespace {
/// Names that several production wheels go by: refused, with the catalogue names to choose from.
struct AmbiguousName {
  const char* name;
  const char* candidates;
};
constexpr AmbiguousName kAmbiguous[] = {
    {"36-2-2",
     "36-2-2-16-16 (two gaps 180 deg apart, symmetric) or 36-2-2-17-15 / jeep-evd (Jeep/Chrysler EVD, gaps "
     "after 17 and 15 teeth); torque-decode --detect-wheel CAPTURE shows which one a capture is"},
};
}  // namespace

bool wheel_from_name(std::string_view name, WheelGeometry& wheel, std::string* error) {
  for (const AmbiguousName& a : kAmbiguous) {
    if (name != a.name) continue;
    if (error) *error = "wheel '" + std::string(name) + "' is ambiguous: " + a.candidates;
    return false;
  }
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
