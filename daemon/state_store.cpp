#include "state_store.hpp"

#include <fcntl.h>
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
#include <utility>

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
  ctx.max_tooth_corr_rad = w.positions > 0 ? 0.5 * 2.0 * std::numbers::pi / w.positions : 0.0;
  ctx.friction = cfg.estimators.friction.params;
  const double vd = e.cylinders * std::numbers::pi / 4.0 * e.bore_m * e.bore_m * e.stroke_m;
  ctx.max_friction_nm = std::max(kMaxFrictionMepPa * vd / (4.0 * std::numbers::pi),
                                 2.0 * max_abs_friction(ctx.friction, ctx.friction.c));
  ctx.max_eta = e.compression_ratio > 1.0 ? 1.0 - std::pow(e.compression_ratio, 1.0 - 1.4) : 1.0;
  ctx.max_torque_sd_nm = kMaxFrictionMepPa * vd / (4.0 * std::numbers::pi);
  ctx.min_inertia_scale = cfg.estimators.energies.params.inertia.min_scale;
  ctx.max_inertia_scale = cfg.estimators.energies.params.inertia.max_scale;
  return ctx;
}

std::string serialize_state(const LearnedState& s, const std::string& identity) {
  std::string text = "torqued-state 2\nidentity " + identity + "\n";
  if (s.friction) {
    text += "friction";
    for (double c : *s.friction) text += fmt(" %.17g", c);
    text += '\n';
  }
  if (s.friction_idle)
    text +=
        "friction_idle" + fmt(" %.17g", (*s.friction_idle)[0]) + fmt(" %.17g", (*s.friction_idle)[1]) + "\n";
  if (s.friction_residual)
    text += "friction_residual" + fmt(" %.17g", (*s.friction_residual)[0]) +
            fmt(" %.0f", (*s.friction_residual)[1]) + "\n";
  if (!s.tooth_corrections_rad.empty()) {
    text += "tooth_corrections " + std::to_string(s.tooth_corrections_rad.size());
    for (double c : s.tooth_corrections_rad) text += fmt(" %.17g", c);
    text += '\n';
  }
  if (s.fuel) {
    const FuelTorqueState& f = *s.fuel;
    text += "fuel_model" + fmt(" %.17g", f.eta_ref) + fmt(" %.17g", f.p_exh_nm);
    for (double v : f.p2) text += fmt(" %.17g", v);
    text += fmt(" %.17g", f.resid_var) + " " + std::to_string(f.references);
    text += fmt(" %.17g", f.cover.sd) + " " + std::to_string(f.cover.n);
    if (f.physics) {
      text += " physics";
      for (double v : f.theta) text += fmt(" %.17g", v);
      for (double v : f.p) text += fmt(" %.17g", v);
      for (auto c : f.cells) text += " " + std::to_string(c);
    }
    text += "\n";
  }
  if (s.crank_error_var) text += "crank_error_var" + fmt(" %.17g", *s.crank_error_var) + "\n";
  if (s.inertia) {
    text += "inertia";
    for (double v : *s.inertia) text += fmt(" %.17g", v);
    text += '\n';
  }
  text += "saved_at_t_ns " + std::to_string(s.saved_at_t_ns) + "\n";
  char sum[32];
  std::snprintf(sum, sizeof sum, "checksum crc32 %08x\n", crc32(text.data(), text.size()));
  return text + sum;
}

namespace {
/// The physics model's extension of a fuel_model line: "physics" θ[4] P[16] cells[16].
bool parse_fuel_physics(std::istringstream& ls, FuelTorqueState& f) {
  std::string tag;
  if (!(ls >> tag) || tag != "physics") return false;
  for (double& v : f.theta)
    if (!(ls >> v) || !std::isfinite(v)) return false;
  for (double& v : f.p)
    if (!(ls >> v) || !std::isfinite(v)) return false;
  for (auto& c : f.cells) {
    std::int64_t n = -1;
    if (!(ls >> n) || n < 0 || n > 0xFFFF) return false;
    c = static_cast<std::uint16_t>(n);
  }
  f.physics = true;
  return true;
}

/// One "key values..." line into `s`; false with `what` set.
bool parse_line(const std::string& key, std::istringstream& ls, LearnedState& s, std::string* what) {
  if (key == "friction") {
    std::array<double, 4> c{};
    for (double& v : c)
      if (!(ls >> v) || !std::isfinite(v)) return *what = "expected 4 finite friction coefficients", false;
    s.friction = c;
  } else if (key == "friction_idle") {
    std::array<double, 2> v{};
    if (!(ls >> v[0] >> v[1]) || !std::isfinite(v[0]) || !std::isfinite(v[1]) || !(v[1] > 0.0))
      return *what = "expected an idle friction correction (N m) and a positive idle speed (rpm)", false;
    s.friction_idle = v;
  } else if (key == "friction_residual") {
    std::array<double, 2> v{};
    if (!(ls >> v[0] >> v[1]) || !std::isfinite(v[0]) || !(v[0] > 0.0) ||
        !(v[1] >= 0.0 && v[1] <= 4294967295.0))
      return *what = "expected a positive motoring residual scale (N m) and a count", false;
    s.friction_residual = v;
  } else if (key == "tooth_corrections") {
    std::size_t n = 0;
    if (!(ls >> n) || n > 2 * static_cast<std::size_t>(kMaxTeeth))
      return *what = "expected a tooth count (<= " + std::to_string(2 * kMaxTeeth) + ")", false;
    s.tooth_corrections_rad.resize(n);
    for (double& v : s.tooth_corrections_rad)
      if (!(ls >> v) || !std::isfinite(v))
        return *what = "expected " + std::to_string(n) + " finite corrections", false;
  } else if (key == "fuel_model") {
    FuelTorqueState f;
    std::int64_t refs = -1;
    bool ok = static_cast<bool>(ls >> f.eta_ref >> f.p_exh_nm);
    for (double& v : f.p2) ok = ok && static_cast<bool>(ls >> v);
    ok = ok && (ls >> f.resid_var >> refs) && refs >= 0 && refs <= 0xFFFFFFFFll;
    std::int64_t cover_n = 0;
    if (ok && !(ls >> std::ws).eof())  // the residual scale and its count (absent in older files)
      ok = (ls >> f.cover.sd >> cover_n) && cover_n >= 0 && cover_n <= 0xFFFFFFFFll && f.cover.sd >= 0.0;
    for (double v : {f.eta_ref, f.p_exh_nm, f.p2[0], f.p2[1], f.p2[2], f.p2[3], f.resid_var, f.cover.sd})
      ok = ok && std::isfinite(v);
    f.physics = false;  // older files: the two-parameter model only (FuelTorque::import_state converts)
    if (ok && !(ls >> std::ws).eof()) ok = parse_fuel_physics(ls, f);
    if (!ok)
      return *what =
                 "expected efficiency, pumping term (N m), 4 covariance entries, residual variance (N m^2), "
                 "a reference count, optionally the residual scale (N m) and its count, optionally 'physics' "
                 "with 4 parameters, 16 covariance entries and 16 cell counts",
             false;
    f.references = static_cast<std::uint32_t>(refs);
    f.cover.n = static_cast<std::uint32_t>(cover_n);
    s.fuel = f;
  } else if (key == "crank_error_var") {
    double v = 0.0;
    if (!(ls >> v) || !std::isfinite(v)) return *what = "expected a finite variance (N m^2)", false;
    s.crank_error_var = v;
  } else if (key == "inertia") {
    std::array<double, 3> v{};
    if (!(ls >> v[0] >> v[1] >> v[2]) || !std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
      return *what = "expected an inertia scale, its information (1/sigma^2) and the spec J (kg m^2)", false;
    s.inertia = v;
  } else if (key == "saved_at_t_ns") {
    if (!(ls >> s.saved_at_t_ns)) return *what = "expected an integer time", false;
  } else if (key == "identity" && s.version >= 2) {
    std::getline(ls >> std::ws, s.identity);
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

namespace {
/// Physical bounds of a learned fuel model: 0 < efficiency < Otto efficiency; |pumping term| and the residual
/// 1 sigma within the torque of kMaxFrictionMepPa; covariance symmetric positive semi-definite.
bool check_fuel(const FuelTorqueState& f, const StateContext& ctx, std::string* what) {
  if (!(f.eta_ref > 0.0 && f.eta_ref < ctx.max_eta)) {
    *what = "fuel model efficiency " + fmt("%g", f.eta_ref) + " not in (0, " + fmt("%g", ctx.max_eta) +
            ") (the Otto cycle's at this compression ratio)";
    return false;
  }
  if (!(std::abs(f.p_exh_nm) <= ctx.max_torque_sd_nm)) {
    *what = "fuel model pumping term " + fmt("%g", f.p_exh_nm) + " N m beyond " +
            fmt("%g", ctx.max_torque_sd_nm) + " N m";
    return false;
  }
  if (f.physics) {
    for (int i = 0; i < kFuelParams; ++i)
      if (!(f.p[static_cast<std::size_t>(i * kFuelParams + i)] >= 0.0)) {
        *what = "fuel model covariance has a negative variance";
        return false;
      }
  }
  if (!(f.resid_var >= 0.0 && std::sqrt(f.resid_var) <= ctx.max_torque_sd_nm)) {
    *what = "fuel model residual variance " + fmt("%g", f.resid_var) + " N m^2 out of range";
    return false;
  }
  if (!(f.cover.sd >= 0.0 && f.cover.sd <= ctx.max_torque_sd_nm)) {
    *what = "fuel model residual scale " + fmt("%g", f.cover.sd) + " N m not in [0, " +
            fmt("%g", ctx.max_torque_sd_nm) + "]";
    return false;
  }
  const auto& p = f.p2;
  const double tol = 1e-9 * (std::abs(p[1]) + std::abs(p[2])) + 1e-300;
  if (!(p[0] >= 0.0 && p[3] >= 0.0 && std::abs(p[1] - p[2]) <= tol && p[1] * p[2] <= p[0] * p[3] * (1.0 + 1e-9))) {
    *what = "fuel model covariance [" + fmt("%g", p[0]) + fmt(" %g", p[1]) + fmt(" %g", p[2]) + fmt(" %g", p[3]) +
            "] is not symmetric positive semi-definite";
    return false;
  }
  return true;
}
}  // namespace

bool check_state(const LearnedState& s, const StateContext& ctx, const std::string& name,
                 std::string* error) {
  std::string fuel_err;
  auto fail = [&](const std::string& what) {
    if (error) *error = name + ": " + what;
    return false;
  };
  if (s.version >= 2 && s.identity != ctx.identity)
    return fail("belongs to another engine/wheel (file: '" + s.identity + "', this configuration: '" +
                ctx.identity + "')");
  const auto n = s.tooth_corrections_rad.size();
  if (n != 0 && n != static_cast<std::size_t>(ctx.teeth))
    return fail(std::to_string(n) + " tooth corrections, but the wheel has " + std::to_string(ctx.teeth) +
                " teeth");
  for (std::size_t i = 0; i < n; ++i)
    if (!(std::abs(s.tooth_corrections_rad[i]) < ctx.max_tooth_corr_rad))
      return fail("tooth correction " + std::to_string(i) + " = " + fmt("%g", s.tooth_corrections_rad[i]) +
                  " rad is not within half a tooth pitch (" + fmt("%g", ctx.max_tooth_corr_rad) + " rad)");
  if (s.friction) {
    const auto& c = *s.friction;
    const double worst = max_abs_friction(ctx.friction, c);
    if (!(worst <= ctx.max_friction_nm))
      return fail("friction law [" + fmt("%g", c[0]) + fmt(", %g", c[1]) + fmt(", %g", c[2]) +
                  fmt(", %g", c[3]) + "] reaches " + fmt("%g", worst) + " N m over 0.." +
                  fmt("%g", ctx.friction.max_rpm) + " rpm, -40..200 degC; physical bound " +
                  fmt("%g", ctx.max_friction_nm) + " N m");
  }
  if (s.friction_idle) {
    const auto& v = *s.friction_idle;
    if (!(std::abs(v[0]) <= ctx.max_friction_nm))
      return fail("idle friction correction " + fmt("%g", v[0]) + " N m beyond the physical bound " +
                  fmt("%g", ctx.max_friction_nm) + " N m");
    if (!(v[1] > 0.0 && v[1] <= ctx.friction.max_rpm))
      return fail("idle speed " + fmt("%g", v[1]) + " rpm not in (0, " + fmt("%g", ctx.friction.max_rpm) +
                  "]");
    if (!s.friction) return fail("an idle friction correction without friction coefficients");
  }
  if (s.friction_residual) {
    const double v = (*s.friction_residual)[0];
    if (!(v > 0.0 && v <= ctx.max_torque_sd_nm))
      return fail("motoring residual scale " + fmt("%g", v) + " N m not in (0, " +
                  fmt("%g", ctx.max_torque_sd_nm) + "]");
    if (!s.friction) return fail("a motoring residual scale without friction coefficients");
  }
  if (s.fuel && !check_fuel(*s.fuel, ctx, &fuel_err)) return fail(fuel_err);
  if (s.crank_error_var) {
    const double v = *s.crank_error_var;
    if (!(v >= 0.0 && std::sqrt(v) <= ctx.max_torque_sd_nm))
      return fail("crank-only error variance " + fmt("%g", v) + " N m^2 not in [0, (" +
                  fmt("%g", ctx.max_torque_sd_nm) + " N m)^2]");
  }
  if (s.inertia) {
    const auto& v = *s.inertia;
    if (!(v[0] >= ctx.min_inertia_scale && v[0] <= ctx.max_inertia_scale && v[1] > 0.0 && v[2] > 0.0))
      return fail("inertia scale " + fmt("%g", v[0]) + " not in [" + fmt("%g", ctx.min_inertia_scale) + ", " +
                  fmt("%g", ctx.max_inertia_scale) + "], or information " + fmt("%g", v[1]) + " or spec J " +
                  fmt("%g", v[2]) + " kg m^2 not positive");
  }
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
  return save_state_atomic(path, s, s.identity.empty() ? std::string("unspecified") : s.identity, error);
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
    if (!sh->queued) return;  // stop, nothing queued
    LearnedState s = std::move(*sh->queued);
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
    sh_->queued = std::move(s);
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
