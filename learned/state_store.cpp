#include "state_store.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <type_traits>
#include <utility>
#include <vector>

#include "config.hpp"
#include "friction_learner.hpp"

namespace torqued {
namespace {
std::string errno_text(const std::string& what) { return what + ": " + std::strerror(errno); }

std::uint32_t crc32(const char* p, std::size_t n) {
  static const auto table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i) c = table[(c ^ static_cast<unsigned char>(p[i])) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

bool write_all(int fd, const std::string& text) {
  std::size_t off = 0;
  while (off < text.size()) {
    const ssize_t n = ::write(fd, text.data() + off, text.size() - off);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    off += static_cast<std::size_t>(n);
  }
  return true;
}

void fsync_dir(const std::string& path) {
  const std::filesystem::path p(path);
  const std::string dir = p.has_parent_path() ? p.parent_path().string() : ".";
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

/// Largest |T_fric| of the law with coefficients `c` over the speed and oil-temperature ranges (inf if not
/// finite somewhere).
double max_abs_friction(const FrictionParams& params, const std::array<double, 4>& c) {
  FrictionParams p = params;
  p.c = c;
  const FrictionLearner law(p);
  double worst = 0.0;
  constexpr int kSpeeds = 64;
  for (int i = 0; i <= kSpeeds; ++i) {
    const double n = params.max_rpm * i / kSpeeds;
    for (const double t : {-40.0, 0.0, 40.0, 90.0, 150.0, 200.0}) {
      const double v = std::abs(law.law_nm(n, t));
      if (!std::isfinite(v)) return HUGE_VAL;
      worst = std::max(worst, v);
    }
  }
  return worst;
}

bool read_file(const std::string& path, std::string* text, std::string* error) {
  // Only a regular file: a FIFO (or a device) in its place would block the start-up in open()/read().
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    if (error) *error = path + ": not a regular file (a FIFO, device or directory is never read as state)";
    return false;
  }
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    if (error) *error = path + ": cannot open (" + std::strerror(errno) + ")";
    return false;
  }
  std::ostringstream ss;
  ss << f.rdbuf();
  if (f.bad()) {
    if (error) *error = path + ": read error";
    return false;
  }
  *text = ss.str();
  return true;
}
}  // namespace

StateContext state_context_from(const Config& cfg) {
  StateContext ctx;
  const EngineGeometry& e = cfg.engine;
  const WheelGeometry& w = cfg.wheel.geometry;
  char buf[256];
  std::snprintf(buf, sizeof buf, "engine_id=%d cylinders=%d bore_m=%.6g stroke_m=%.6g wheel=%d-%d teeth=%d",
                cfg.dds.engine_id, e.cylinders, e.bore_m, e.stroke_m, w.positions, w.missing, w.teeth());
  ctx.identity = buf;
  ctx.teeth = w.teeth();
  // The tighter of half a tooth pitch (the decoder's own limit) and realistic machining
  // (estimators.tooth_learn.max_correction_deg).
  ctx.max_tooth_corr_rad = w.positions > 0
                               ? std::min(0.5 * 2.0 * std::numbers::pi / w.positions,
                                          cfg.estimators.tooth_max_correction_deg * std::numbers::pi / 180.0)
                               : 0.0;
  ctx.friction = cfg.estimators.friction.params;
  const double vd = e.cylinders * std::numbers::pi / 4.0 * e.bore_m * e.bore_m * e.stroke_m;
  ctx.max_friction_nm = std::max(kMaxFrictionMepPa * vd / (4.0 * std::numbers::pi),
                                 2.0 * max_abs_friction(ctx.friction, ctx.friction.c));
  ctx.max_eta = e.compression_ratio > 1.0 ? 1.0 - std::pow(e.compression_ratio, 1.0 - 1.4) : 1.0;
  ctx.max_torque_sd_nm = kMaxFrictionMepPa * vd / (4.0 * std::numbers::pi);
  ctx.min_inertia_scale = cfg.estimators.energies.params.inertia.min_scale;
  ctx.max_inertia_scale = cfg.estimators.energies.params.inertia.max_scale;
  ctx.min_burn_offset_deg = cfg.estimators.kalman.params.burn_phase.min_offset_deg;
  ctx.max_burn_offset_deg = cfg.estimators.kalman.params.burn_phase.max_offset_deg;
  return ctx;
}

// ---- The line table -------------------------------------------------------------------------------------
// Every persisted line "<key> <numbers>" is described once, in kLines: serialize_state writes the rows whose
// value is present, in table order; parse_state reads a row's numbers by their kinds; check_state runs each
// present row's physical bounds check. Adding a learned quantity: its field in learned_state.hpp, its row
// here, and where the chain fills and applies it (chain/angle_chain.cpp).

namespace {
/// One number of a line, by kind: 'g' a finite real (written %.17g), 'c' a count held as a real (0..2^32-1,
/// written %.0f), 'u' an unsigned 32-bit integer, 'i' a signed 64-bit integer (both written in decimal), 'p'
/// the word "physics" that opens an optional part (n = 1 when present). A row's get() may stop at a '|': the
/// line then ends there, as an older file's did.
struct Num {
  double x = 0.0;      ///< kinds g, c
  std::int64_t n = 0;  ///< kinds u, i
};
using Nums = std::vector<Num>;

/// One persisted line.
struct Line {
  const char* key;
  /// One letter per number (see Num). A '|' marks where older files may end the line: the values after it
  /// are optional trailing values, read as 0 when absent (always written).
  const char* kinds;
  /// > 0: the line is "<key> <n> <n numbers of kinds[0]>" with n <= max_count (a count field).
  std::size_t max_count;
  const char* expect;                       ///< what a malformed line is told it should hold
  bool (*has)(const LearnedState&);         ///< present: written and checked
  void (*get)(const LearnedState&, Nums&);  ///< the numbers to write
  bool (*set)(LearnedState&, const Nums&);  ///< from the numbers read; false: not a valid value
  bool (*check)(const LearnedState&, const StateContext&, std::string* what);  ///< bounds; null: none
};

// Rows of Opt<double> and Opt<std::array<double, N>> fields share these.
template <auto F>
bool has_opt(const LearnedState& s) {
  return (s.*F).has_value();
}
template <auto F>
void get_reals(const LearnedState& s, Nums& v) {
  const auto& x = *(s.*F);
  if constexpr (std::is_same_v<std::remove_cvref_t<decltype(x)>, double>)
    v.push_back({.x = x});
  else
    for (const double e : x) v.push_back({.x = e});
}
template <auto F>
bool set_reals(LearnedState& s, const Nums& v) {
  std::remove_cvref_t<decltype(*(s.*F))> a{};
  if constexpr (std::is_same_v<decltype(a), double>)
    a = v[0].x;
  else
    for (std::size_t i = 0; i < a.size(); ++i) a[i] = v[i].x;
  s.*F = a;
  return true;
}

/// The fuel_model line's numbers: the two-parameter (Willans) view at the reference point (efficiency,
/// pumping term p_exh V_d/4pi in N m, its covariance P00 P01 P10 P11), residual variance (N m^2), reference
/// count | 68th percentile of |residual| (N m), its count (added later: read as 0 = not measured yet) | the
/// word "physics" then the physics model's 4 parameters, its 4 x 4 covariance and the 16 speed x MAP cell
/// counts (added with the physics model: absent in older files, which FuelTorque::import_state converts) |
/// the parameters' cross-covariance with the accessories' shared bias (added later: absent reads as 0, no
/// driveline-open reference learned yet).
constexpr const char* kFuelKinds =
    "gggggggu|gu|p"
    "gggg"
    "gggggggggggggggg"
    "uuuuuuuuuuuuuuuu|"
    "gggg";
void fuel_to_numbers(const FuelTorqueState& f, Nums& v) {
  v = {{.x = f.eta_ref}, {.x = f.p_exh_nm},  {.x = f.p2[0]},      {.x = f.p2[1]},    {.x = f.p2[2]},
       {.x = f.p2[3]},   {.x = f.resid_var}, {.n = f.references}, {.x = f.cover.sd}, {.n = f.cover.n}};
  if (!f.physics) return;  // an older file's model: the line ends before the physics part
  v.push_back({.n = 1});
  for (const double x : f.theta) v.push_back({.x = x});
  for (const double x : f.p) v.push_back({.x = x});
  for (const auto c : f.cells) v.push_back({.n = c});
  for (const double x : f.pxb) v.push_back({.x = x});
}
bool fuel_from_numbers(const Nums& v, FuelTorqueState& f) {
  f.eta_ref = v[0].x;
  f.p_exh_nm = v[1].x;
  f.p2 = {v[2].x, v[3].x, v[4].x, v[5].x};
  f.resid_var = v[6].x;
  f.references = static_cast<std::uint32_t>(v[7].n);
  f.cover.sd = v[8].x;
  f.cover.n = static_cast<std::uint32_t>(v[9].n);
  f.physics = v[10].n == 1;
  std::size_t i = 11;
  for (double& x : f.theta) x = v[i++].x;
  for (double& x : f.p) x = v[i++].x;
  for (auto& c : f.cells) {
    if (v[i].n > 0xFFFF) return false;
    c = static_cast<std::uint16_t>(v[i++].n);
  }
  for (double& x : f.pxb) x = v[i++].x;
  return f.cover.sd >= 0.0;
}

bool check_friction(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const auto& c = *s.friction;
  const double worst = max_abs_friction(ctx.friction, c);
  if (worst <= ctx.max_friction_nm) return true;
  *what = "friction law [" + fmt("%g", c[0]) + fmt(", %g", c[1]) + fmt(", %g", c[2]) + fmt(", %g", c[3]) +
          "] reaches " + fmt("%g", worst) + " N m over 0.." + fmt("%g", ctx.friction.max_rpm) +
          " rpm, -40..200 degC; physical bound " + fmt("%g", ctx.max_friction_nm) + " N m";
  return false;
}

bool check_friction_idle(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const auto& v = *s.friction_idle;
  if (!(std::abs(v[0]) <= ctx.max_friction_nm))
    *what = "idle friction correction " + fmt("%g", v[0]) + " N m beyond the physical bound " +
            fmt("%g", ctx.max_friction_nm) + " N m";
  else if (!(v[1] > 0.0 && v[1] <= ctx.friction.max_rpm))
    *what = "idle speed " + fmt("%g", v[1]) + " rpm not in (0, " + fmt("%g", ctx.friction.max_rpm) + "]";
  else if (!s.friction)
    *what = "an idle friction correction without friction coefficients";
  else
    return true;
  return false;
}

bool check_friction_reference(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const double v = *s.friction_reference_sd;
  if (!(v >= 0.0 && v <= ctx.max_torque_sd_nm))
    *what = "friction reference 1 sigma " + fmt("%g", v) + " N m not in [0, " +
            fmt("%g", ctx.max_torque_sd_nm) + "]";
  else if (!s.friction)
    *what = "a friction reference 1 sigma without friction coefficients";
  else
    return true;
  return false;
}

bool check_friction_observations(const LearnedState& s, const StateContext&, std::string* what) {
  if (!s.friction) {
    *what = "a friction observation count without friction coefficients";
    return false;
  }
  return true;
}

bool check_friction_residual(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const double v = (*s.friction_residual)[0];
  if (!(v > 0.0 && v <= ctx.max_torque_sd_nm))
    *what = "motoring residual scale " + fmt("%g", v) + " N m not in (0, " + fmt("%g", ctx.max_torque_sd_nm) +
            "]";
  else if (!s.friction)
    *what = "a motoring residual scale without friction coefficients";
  else
    return true;
  return false;
}

bool check_teeth(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const auto& t = s.tooth_corrections_rad;
  if (t.size() != static_cast<std::size_t>(ctx.teeth)) {
    *what = std::to_string(t.size()) + " tooth corrections, but the wheel has " + std::to_string(ctx.teeth) +
            " teeth";
    return false;
  }
  for (std::size_t i = 0; i < t.size(); ++i)
    if (!(std::abs(t[i]) < ctx.max_tooth_corr_rad)) {
      *what = "tooth correction " + std::to_string(i) + " = " + fmt("%g", t[i]) +
              " rad is beyond the bound " + fmt("%g", ctx.max_tooth_corr_rad) +
              " rad (estimators.tooth_learn.max_correction_deg, at most half a tooth pitch)";
      return false;
    }
  return true;
}

/// Physical bounds of a learned fuel model: 0 < efficiency < Otto efficiency; |pumping term| and the residual
/// 1 sigma within the torque of kMaxFrictionMepPa; covariance symmetric positive semi-definite.
bool check_fuel(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const FuelTorqueState& f = *s.fuel;
  const double lim = ctx.max_torque_sd_nm;
  const auto& p = f.p2;
  const double tol = 1e-9 * (std::abs(p[1]) + std::abs(p[2])) + 1e-300;
  bool negative_variance = false;
  for (int i = 0; f.physics && i < kFuelParams; ++i)
    negative_variance = negative_variance || !(f.p[static_cast<std::size_t>(i * kFuelParams + i)] >= 0.0);
  if (!(f.eta_ref > 0.0 && f.eta_ref < ctx.max_eta))
    *what = "fuel model efficiency " + fmt("%g", f.eta_ref) + " not in (0, " + fmt("%g", ctx.max_eta) +
            ") (the Otto cycle's at this compression ratio)";
  else if (!(std::abs(f.p_exh_nm) <= lim))
    *what = "fuel model pumping term " + fmt("%g", f.p_exh_nm) + " N m beyond " + fmt("%g", lim) + " N m";
  else if (negative_variance)
    *what = "fuel model covariance has a negative variance";
  else if (!(f.resid_var >= 0.0 && std::sqrt(f.resid_var) <= lim))
    *what = "fuel model residual variance " + fmt("%g", f.resid_var) + " N m^2 out of range";
  else if (!(f.cover.sd >= 0.0 && f.cover.sd <= lim))
    *what = "fuel model residual scale " + fmt("%g", f.cover.sd) + " N m not in [0, " + fmt("%g", lim) + "]";
  else if (!(p[0] >= 0.0 && p[3] >= 0.0 && std::abs(p[1] - p[2]) <= tol &&
             p[1] * p[2] <= p[0] * p[3] * (1.0 + 1e-9)))
    *what = "fuel model covariance [" + fmt("%g", p[0]) + fmt(" %g", p[1]) + fmt(" %g", p[2]) +
            fmt(" %g", p[3]) + "] is not symmetric positive semi-definite";
  else
    return true;
  return false;
}

bool check_crank_var(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const double v = *s.crank_error_var;
  if (v >= 0.0 && std::sqrt(v) <= ctx.max_torque_sd_nm) return true;
  *what = "crank-only error variance " + fmt("%g", v) + " N m^2 not in [0, (" +
          fmt("%g", ctx.max_torque_sd_nm) + " N m)^2]";
  return false;
}

bool check_inertia(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const auto& v = *s.inertia;
  if (v[0] >= ctx.min_inertia_scale && v[0] <= ctx.max_inertia_scale && v[1] > 0.0 && v[2] > 0.0) return true;
  *what = "inertia scale " + fmt("%g", v[0]) + " not in [" + fmt("%g", ctx.min_inertia_scale) + ", " +
          fmt("%g", ctx.max_inertia_scale) + "], or information " + fmt("%g", v[1]) + " or spec J " +
          fmt("%g", v[2]) + " kg m^2 not positive";
  return false;
}

bool check_burn_phase(const LearnedState& s, const StateContext& ctx, std::string* what) {
  const auto& v = *s.burn_phase;
  if (v[0] >= ctx.min_burn_offset_deg && v[0] <= ctx.max_burn_offset_deg && v[1] >= 0.0) return true;
  *what = "burn phase offset " + fmt("%g", v[0]) + " deg not in [" + fmt("%g", ctx.min_burn_offset_deg) +
          ", " + fmt("%g", ctx.max_burn_offset_deg) + "], or its cycle count " + fmt("%g", v[1]) +
          " negative";
  return false;
}

using S = LearnedState;
const Line kLines[] = {
    {"friction", "gggg", 0, "expected 4 finite friction coefficients", has_opt<&S::friction>,
     get_reals<&S::friction>, set_reals<&S::friction>, check_friction},
    {"friction_idle", "gg", 0, "expected an idle friction correction (N m) and a positive idle speed (rpm)",
     has_opt<&S::friction_idle>, get_reals<&S::friction_idle>,
     [](S& s, const Nums& v) { return v[1].x > 0.0 && set_reals<&S::friction_idle>(s, v); },
     check_friction_idle},
    {"friction_residual", "gc", 0, "expected a positive motoring residual scale (N m) and a count",
     has_opt<&S::friction_residual>, get_reals<&S::friction_residual>,
     [](S& s, const Nums& v) { return v[0].x > 0.0 && set_reals<&S::friction_residual>(s, v); },
     check_friction_residual},
    {"friction_reference", "g", 0,
     "expected the 1 sigma (N m) of the load references the friction law rests on",
     has_opt<&S::friction_reference_sd>, get_reals<&S::friction_reference_sd>,
     set_reals<&S::friction_reference_sd>, check_friction_reference},
    {"friction_observations", "c", 0,
     "expected the count of motoring observations a not yet converged friction law rests on",
     has_opt<&S::friction_observations>, get_reals<&S::friction_observations>,
     set_reals<&S::friction_observations>, check_friction_observations},
    {"tooth_corrections", "g", kMaxToothCorrections,
     "expected a tooth count and that many finite corrections",
     [](const S& s) { return !s.tooth_corrections_rad.empty(); },
     [](const S& s, Nums& v) {
       for (const double x : s.tooth_corrections_rad) v.push_back({.x = x});
     },
     [](S& s, const Nums& v) {
       s.tooth_corrections_rad.clear();
       for (const Num& x : v) s.tooth_corrections_rad.push_back(x.x);
       return true;
     },
     check_teeth},
    {"fuel_model", kFuelKinds, 0,
     "expected efficiency, pumping term (N m), 4 covariance entries, residual variance (N m^2), a reference "
     "count and optionally the residual scale (N m) and its count, then \"physics\", 4 parameters, their 4 x "
     "4 "
     "covariance, 16 cell counts and optionally 4 cross-covariances with the accessories' shared bias",
     has_opt<&S::fuel>, [](const S& s, Nums& v) { fuel_to_numbers(*s.fuel, v); },
     [](S& s, const Nums& v) {
       FuelTorqueState f;
       if (!fuel_from_numbers(v, f)) return false;
       s.fuel = f;
       return true;
     },
     check_fuel},
    {"crank_error_var", "g", 0, "expected a finite variance (N m^2)", has_opt<&S::crank_error_var>,
     get_reals<&S::crank_error_var>, set_reals<&S::crank_error_var>, check_crank_var},
    {"inertia", "ggg", 0, "expected an inertia scale, its information (1/sigma^2) and the spec J (kg m^2)",
     has_opt<&S::inertia>, get_reals<&S::inertia>, set_reals<&S::inertia>, check_inertia},
    {"burn_phase", "gc", 0, "expected a burn phase offset (deg) and the used cycles behind it",
     has_opt<&S::burn_phase>, get_reals<&S::burn_phase>, set_reals<&S::burn_phase>, check_burn_phase},
    {"saved_at_t_ns", "i", 0, "expected an integer time", [](const S&) { return true; },
     [](const S& s, Nums& v) { v.push_back({.n = s.saved_at_t_ns}); },
     [](S& s, const Nums& v) {
       s.saved_at_t_ns = v[0].n;
       return true;
     },
     nullptr},
};

/// Kind of the i-th number of `l` (a count field's numbers all have kinds[0]).
char kind_at(const Line& l, std::size_t i) {
  if (l.max_count > 0) return l.kinds[0];
  for (const char* k = l.kinds; *k; ++k)
    if (*k != '|' && i-- == 0) return *k;
  return 'g';
}

void append_number(std::string& text, char kind, const Num& v) {
  if (kind == 'p')
    text += " physics";
  else if (kind == 'g')
    text += fmt(" %.17g", v.x);
  else if (kind == 'c')
    text += fmt(" %.0f", v.x);
  else
    (text += ' ') += std::to_string(v.n);
}

bool read_number(std::istringstream& ls, char kind, Num& v) {
  std::string word;
  switch (kind) {
    case 'p':  // a literal word that opens an optional part; present = 1
      v.n = 1;
      return (ls >> word) && word == "physics";
    case 'g':
      return static_cast<bool>(ls >> v.x) && std::isfinite(v.x);
    case 'c':
      return static_cast<bool>(ls >> v.x) && v.x >= 0.0 && v.x <= 4294967295.0;
    case 'u':
      return static_cast<bool>(ls >> v.n) && v.n >= 0 && v.n <= 0xFFFFFFFFll;
    default:
      return static_cast<bool>(ls >> v.n);
  }
}

/// The numbers of a `l` line (after its key); false when one is missing or out of its kind's range.
bool read_numbers(const Line& l, std::istringstream& ls, Nums& v) {
  if (l.max_count > 0) {
    std::int64_t n = -1;
    if (!(ls >> n) || n < 0 || static_cast<std::size_t>(n) > l.max_count) return false;
    v.assign(static_cast<std::size_t>(n), Num{});
    for (Num& x : v)
      if (!read_number(ls, l.kinds[0], x)) return false;
    return true;
  }
  v.clear();
  for (const char* k = l.kinds; *k; ++k)
    if (*k != '|') v.emplace_back();  // absent optional trailing values stay 0
  std::size_t i = 0;
  for (const char* k = l.kinds; *k; ++k) {
    if (*k == '|') {
      if ((ls >> std::ws).eof()) return true;
      continue;
    }
    if (!read_number(ls, *k, v[i++])) return false;
  }
  return true;
}
}  // namespace

std::string serialize_state(const LearnedState& s, const std::string& identity) {
  std::string text = "torqued-state 2\nidentity " + identity + "\n";
  Nums v;
  for (const Line& l : kLines) {
    if (!l.has(s)) continue;
    v.clear();
    l.get(s, v);
    text += l.key;
    if (l.max_count > 0) (text += ' ') += std::to_string(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) append_number(text, kind_at(l, i), v[i]);
    text += '\n';
  }
  char sum[32];
  std::snprintf(sum, sizeof sum, "checksum crc32 %08x\n", crc32(text.data(), text.size()));
  return text + sum;
}

namespace {
/// One "key values..." line into `s`; false with `what` set.
bool parse_line(const std::string& key, std::istringstream& ls, LearnedState& s, std::string* what) {
  const Line* l =
      std::find_if(std::begin(kLines), std::end(kLines), [&](const Line& r) { return key == r.key; });
  if (l != std::end(kLines)) {
    Nums v;
    if (!read_numbers(*l, ls, v) || !l->set(s, v)) {
      *what = l->expect;
      if (l->max_count > 0) *what += " (a count <= " + std::to_string(l->max_count) + ")";
      return false;
    }
  } else if (key == "identity" && s.version >= 2) {
    std::string id;
    std::getline(ls >> std::ws, id);
    if (id.size() > kMaxIdentityChars)
      return *what = "identity longer than " + std::to_string(kMaxIdentityChars) + " characters", false;
    s.identity = id;
  } else {
    return *what = "unknown key '" + key + "'", false;
  }
  std::string extra;
  if (ls >> extra) return *what = "unexpected '" + extra + "' after the " + key + " values", false;
  return true;
}
}  // namespace

std::optional<LearnedState> parse_state(const std::string& text, const std::string& name,
                                        std::string* error) {
  LearnedState s;
  int lineno = 0;
  auto fail = [&](const std::string& what) {
    if (error) *error = name + ":" + std::to_string(lineno) + ": " + what;
    return std::nullopt;
  };
  if (text.empty()) return fail("empty file");
  bool have_sum = false;
  std::size_t pos = 0;
  while (pos < text.size()) {
    const std::size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) return ++lineno, fail("truncated (last line has no newline)");
    const std::string line = text.substr(pos, eol - pos);
    ++lineno;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (have_sum) return fail("text after the checksum line");
    if (lineno == 1) {
      if (key != "torqued-state" || !(ls >> s.version) || (s.version != 1 && s.version != 2))
        return fail("expected a 'torqued-state 1' or 'torqued-state 2' header");
    } else if (key == "checksum" && s.version >= 2) {
      std::string algo;
      unsigned long sum = 0;
      if (!(ls >> algo >> std::hex >> sum) || algo != "crc32") return fail("expected 'checksum crc32 <hex>'");
      const std::uint32_t want = crc32(text.data(), pos);
      if (sum != want) {
        char b[96];
        std::snprintf(b, sizeof b,
                      "checksum mismatch (file says %08lx, content gives %08x): edited or corrupt", sum,
                      want);
        return fail(b);
      }
      have_sum = true;
    } else if (!key.empty() && key[0] != '#') {
      std::string what;
      if (!parse_line(key, ls, s, &what)) return fail(what);
    }
    pos = eol + 1;
  }
  if (s.version >= 2 && !have_sum) return fail("no checksum line (truncated?)");
  if (s.version >= 2 && s.identity.empty()) return fail("no identity line");
  return s;
}

bool check_state(const LearnedState& s, const StateContext& ctx, const std::string& name,
                 std::string* error) {
  auto fail = [&](const std::string& what) {
    if (error) *error = name + ": " + what;
    return false;
  };
  if (s.version >= 2 && s.identity != ctx.identity)
    return fail("belongs to another engine/wheel (file: '" + s.identity.str() + "', this configuration: '" +
                ctx.identity + "')");
  std::string what;
  for (const Line& l : kLines)
    if (l.check && l.has(s) && !l.check(s, ctx, &what)) return fail(what);
  return true;
}

bool save_state_atomic(const std::string& path, const LearnedState& s, const std::string& identity,
                       std::string* error) {
  const std::string text = serialize_state(s, identity);
  const std::filesystem::path p(path);
  std::error_code ec;
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path(), ec);
  const std::string tmp = path + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    if (error) *error = errno_text("open " + tmp);
    return false;
  }
  if (!write_all(fd, text) || ::fsync(fd) != 0) {
    if (error) *error = errno_text("write " + tmp);
    ::close(fd);
    ::unlink(tmp.c_str());
    return false;
  }
  ::close(fd);
  // The current file (written by us or checked at load) becomes the backup. A kill between these steps leaves
  // <path> intact (a missing or older backup at worst).
  const std::string bak = path + ".bak";
  if (::access(path.c_str(), F_OK) == 0) {
    ::unlink(bak.c_str());
    if (::link(path.c_str(), bak.c_str()) != 0 && error) *error = errno_text("backup " + bak);  // not fatal
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    if (error) *error = errno_text("rename " + tmp + " -> " + path);
    return false;
  }
  fsync_dir(path);  // make the rename itself durable
  return true;
}

bool save_state_atomic(const std::string& path, const LearnedState& s, std::string* error) {
  return save_state_atomic(path, s, s.identity.empty() ? std::string("unspecified") : s.identity.str(),
                           error);
}

std::optional<LearnedState> load_state(const std::string& path, std::string* error) {
  std::string text;
  if (!read_file(path, &text, error)) return std::nullopt;
  return parse_state(text, path, error);
}

namespace {
std::string utc_stamp() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y%m%dT%H%M%SZ", &tm);
  return b;
}

/// Renames a rejected file out of the way; the new name, or "" (with `error`) when that failed.
std::string set_aside(const std::string& path, std::string* error) {
  std::string to = path + ".rejected-" + utc_stamp();
  for (int i = 1; ::access(to.c_str(), F_OK) == 0 && i < 100; ++i)
    to = path + ".rejected-" + utc_stamp() + "-" + std::to_string(i);
  if (::rename(path.c_str(), to.c_str()) != 0) {
    *error = errno_text("cannot set " + path + " aside as " + to);
    return {};
  }
  fsync_dir(path);
  return to;
}

/// One candidate file: the checked state, or nullopt after setting the file aside (messages into `r`).
std::optional<LearnedState> try_file(const std::string& path, const StateContext& ctx, RestoreResult& r) {
  std::string err;
  std::optional<LearnedState> s = load_state(path, &err);
  if (s && check_state(*s, ctx, path, &err)) return s;
  std::string aside_err;
  const std::string to = set_aside(path, &aside_err);
  if (to.empty()) {
    r.warnings.push_back("learned state rejected: " + err + "; " + aside_err +
                         ": not saving this run (the file is kept as it is)");
    r.may_save = false;
  } else {
    r.warnings.push_back("learned state rejected: " + err + "; moved to " + to);
  }
  return std::nullopt;
}
}  // namespace

RestoreResult restore_learned_state(const std::string& path, const StateContext& ctx) {
  RestoreResult r;
  const std::string bak = path + ".bak";
  const bool have_main = ::access(path.c_str(), F_OK) == 0;
  if (have_main) r.state = try_file(path, ctx, r);
  if (!r.state && ::access(bak.c_str(), F_OK) == 0) {
    r.state = try_file(bak, ctx, r);
    if (r.state) r.warnings.push_back("learned state taken from the backup " + bak);
  }
  if (r.state && r.state->version < 2)
    r.infos.push_back(
        "learned state in format version 1 (no identity, no checksum): rewritten as version 2 at the "
        "next save");
  if (!r.state)
    r.infos.push_back(have_main
                          ? "learning restarts from the configured prior"
                          : "no learned state at " + path + ": learning starts from the configured prior");
  return r;
}

// ---- StateSaver
// ---------------------------------------------------------------------------------------------

struct StateSaver::Shared {
  Writer writer;
  std::mutex m;
  std::condition_variable cv;
  std::optional<LearnedState> queued;
  bool busy = false;
  bool stop = false;
  std::vector<std::string> errors;
  std::uint64_t saves = 0, failures = 0;
};

StateSaver::StateSaver(std::string path, StateContext ctx)
    : StateSaver(Writer([path = std::move(path), ctx = std::move(ctx)](const LearnedState& in,
                                                                       std::string* e) {
        LearnedState s = in;
        s.identity = ctx.identity;  // learned by this configuration
        s.version = 2;
        return check_state(s, ctx, "learned state to save", e) && save_state_atomic(path, s, ctx.identity, e);
      })) {}

StateSaver::StateSaver(Writer writer) : sh_(std::make_shared<Shared>()) {
  sh_->writer = std::move(writer);
  thread_ = std::thread([sh = sh_] { run(sh); });
}

StateSaver::~StateSaver() {
  if (!thread_.joinable() || !finish(5.0)) return;  // finish() detached a stuck thread
  {
    std::lock_guard lk(sh_->m);
    sh_->stop = true;
  }
  sh_->cv.notify_all();
  if (thread_.joinable()) thread_.join();
}

void StateSaver::run(const std::shared_ptr<Shared>& sh) {
  std::unique_lock lk(sh->m);
  for (;;) {
    sh->cv.wait(lk, [&] { return sh->stop || sh->queued.has_value(); });
    if (!sh->queued) return;       // stop, nothing queued
    LearnedState s = *sh->queued;  // trivially copyable: a copy
    sh->queued.reset();
    sh->busy = true;
    lk.unlock();
    std::string err;
    const bool ok = sh->writer(s, &err);
    lk.lock();
    sh->busy = false;
    ++(ok ? sh->saves : sh->failures);
    if (!ok) sh->errors.push_back(err);
    sh->cv.notify_all();
  }
}

void StateSaver::submit(LearnedState s) {
  {
    std::lock_guard lk(sh_->m);
    sh_->queued = s;
  }
  sh_->cv.notify_all();
}

bool StateSaver::finish(double timeout_s) {
  std::unique_lock lk(sh_->m);
  const bool idle = sh_->cv.wait_for(lk, std::chrono::duration<double>(timeout_s),
                                     [&] { return !sh_->busy && !sh_->queued.has_value(); });
  if (!idle && thread_.joinable()) {
    sh_->stop = true;
    thread_.detach();  // stuck in the kernel: let it finish or die with the process
  }
  return idle;
}

std::vector<std::string> StateSaver::take_errors() {
  std::lock_guard lk(sh_->m);
  return std::exchange(sh_->errors, {});
}

std::uint64_t StateSaver::saves() const {
  std::lock_guard lk(sh_->m);
  return sh_->saves;
}

std::uint64_t StateSaver::failures() const {
  std::lock_guard lk(sh_->m);
  return sh_->failures;
}

}  // namespace torqued
