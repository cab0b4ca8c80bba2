// YAML → Config against the schema table (config_schema.cpp). Collects every error with file:line:col.
#include "config_loader.hpp"

#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <sstream>
#include <unordered_map>

#include "config_schema.hpp"
#include "dbc.hpp"
#include "fourier_observer.hpp"

namespace torqued {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

/// Strict number parsing: the whole scalar must be a number. YAML's .nan/.inf spellings parse to non-finite
/// values so that the caller reports them as "not finite" rather than "not a number".
bool parse_double(const std::string& s, double& out) {
  const std::string l = lower(s);
  if (l == ".nan" || l == "nan") {
    out = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  if (l == ".inf" || l == "+.inf" || l == "inf") {
    out = std::numeric_limits<double>::infinity();
    return true;
  }
  if (l == "-.inf" || l == "-inf") {
    out = -std::numeric_limits<double>::infinity();
    return true;
  }
  if (s.empty()) return false;
  const char* b = s.data();
  if (*b == '+') ++b;
  auto [p, ec] = std::from_chars(b, s.data() + s.size(), out);
  return ec == std::errc{} && p == s.data() + s.size();
}

bool parse_int(const std::string& s, std::int64_t& out) {
  if (s.empty()) return false;
  std::size_t k = 0;
  bool neg = false;
  if (s[0] == '+' || s[0] == '-') {
    neg = s[0] == '-';
    k = 1;
  }
  int base = 10;
  if (s.size() > k + 2 && s[k] == '0' && (s[k + 1] == 'x' || s[k + 1] == 'X')) {
    base = 16;
    k += 2;
  }
  std::uint64_t u = 0;
  auto [p, ec] = std::from_chars(s.data() + k, s.data() + s.size(), u, base);
  if (ec != std::errc{} || p != s.data() + s.size() || k == s.size()) return false;
  if (u > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) return false;
  out = neg ? -static_cast<std::int64_t>(u) : static_cast<std::int64_t>(u);
  return true;
}

bool parse_bool(const std::string& s, bool& out) {
  const std::string l = lower(s);
  if (l == "true" || l == "yes" || l == "on") {
    out = true;
    return true;
  }
  if (l == "false" || l == "no" || l == "off") {
    out = false;
    return true;
  }
  return false;
}

bool in_bounds(const SchemaEntry& e, double x) {
  if (!e.bounded) return true;
  if (e.lo_open ? !(x > e.lo) : !(x >= e.lo)) return false;
  if (e.hi_open ? !(x < e.hi) : !(x <= e.hi)) return false;
  return true;
}

std::string node_text(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Scalar:
      return n.Scalar();
    case YAML::NodeType::Sequence: {
      std::string s = "[";
      for (std::size_t k = 0; k < n.size(); ++k) s += (k ? ", " : "") + node_text(n[k]);
      return s + "]";
    }
    case YAML::NodeType::Map:
      return "{...}";
    default:
      return "";
  }
}

class Loader {
 public:
  Loader(std::string file, LoadOptions options) : file_(std::move(file)), options_(options) {
    std::error_code ec;
    auto abs = std::filesystem::absolute(file_, ec);
    dir_ = ec ? std::filesystem::path(".") : abs.parent_path();
    cfg_.source_file = ec ? file_ : abs.lexically_normal().string();
  }

  LoadResult run(const std::string& text) {
    YAML::Node root;
    try {
      root = YAML::Load(text);
    } catch (const YAML::ParserException& ex) {
      add(ex.mark, "invalid YAML: " + ex.msg);
      return std::move(r_);
    } catch (const YAML::Exception& ex) {
      add(ex.mark, std::string("invalid YAML: ") + ex.what());
      return std::move(r_);
    }
    if (root.IsDefined() && !root.IsNull()) {
      if (!root.IsMap())
        add(root.Mark(), "the top level must be a mapping of sections (engine:, wheel:, ...)");
      else
        walk(root, "");
    }
    // Derived settings (documented in config.hpp).
    cfg_.wheel.decoder.use_cam = !cfg_.wheel.cam_channel.empty();
    cfg_.wheel.decoder.cam_rising = cfg_.wheel.cam_rising_edge;
    check_wheel_keys();
    check_metrics_address();
    check_files();
    for (const auto& p : options_.check_physics ? check_config_physics(cfg_) : std::vector<ConfigProblem>{}) {
      if (failed_.count(p.key)) continue;  // already reported as a bad value
      if (present(p.key))
        add(mark_of(p.key), p.key, p.found, p.expected);
      else
        add(mark_of(p.key), "key '" + p.key + "': found '" + p.found + "' (default), expected " + p.expected);
    }
    if (r_.errors.empty()) r_.config = cfg_;
    return std::move(r_);
  }

 private:
  void add(const YAML::Mark& m, const std::string& msg) {
    std::ostringstream os;
    os << file_ << ":" << (m.line >= 0 ? m.line + 1 : 1) << ":" << (m.column >= 0 ? m.column + 1 : 1) << ": "
       << msg;
    r_.errors.push_back(os.str());
  }
  void add(const YAML::Mark& m, const std::string& key, const std::string& found,
           const std::string& expected) {
    add(m, "key '" + key + "': found '" + found + "', expected " + expected);
  }

  /// Mark of a key's value, or of its nearest present section (defaults have no position of their own).
  YAML::Mark mark_of(std::string key) const {
    for (;;) {
      auto it = marks_.find(key);
      if (it != marks_.end()) return it->second;
      auto dot = key.rfind('.');
      if (dot == std::string::npos) return YAML::Mark{};
      key.resize(dot);
    }
  }
  bool present(const std::string& key) const { return values_.count(key) != 0; }
  bool failed(const std::string& key) const { return failed_.count(key) != 0; }

  /// Names directly under a section ("" = the top level), sorted; from an index built once.
  static const std::vector<std::string>& children_of(const std::string& prefix) {
    static const std::map<std::string, std::vector<std::string>> index = [] {
      std::map<std::string, std::set<std::string>> names;
      for (const auto& e : config_schema()) {
        std::size_t start = 0;
        for (;;) {
          const std::size_t dot = e.key.find('.', start);
          const std::string parent = start == 0 ? "" : e.key.substr(0, start - 1);
          names[parent].insert(
              e.key.substr(start, dot == std::string::npos ? std::string::npos : dot - start));
          if (dot == std::string::npos) break;
          start = dot + 1;
        }
      }
      std::map<std::string, std::vector<std::string>> m;
      for (const auto& [k, v] : names) m.emplace(k, std::vector<std::string>(v.begin(), v.end()));
      return m;
    }();
    static const std::vector<std::string> none;
    const auto it = index.find(prefix);
    return it == index.end() ? none : it->second;
  }

  std::string suggestion(const std::string& prefix, const std::string& leaf) const {
    std::string best;
    std::size_t best_d = std::max<std::size_t>(2, leaf.size() / 3) + 1;
    for (const auto& c : children_of(prefix)) {
      const std::size_t d = edit_distance(lower(leaf), c);
      if (d < best_d) {
        best_d = d;
        best = prefix.empty() ? c : prefix + "." + c;
      }
    }
    if (!best.empty()) return best;
    for (const auto& e : config_schema()) {  // right name in the wrong section (engine.teeth → wheel.teeth)
      const std::string eleaf = e.key.substr(e.key.rfind('.') + 1);
      if (eleaf == leaf) return e.key;
    }
    return {};
  }

  void walk(const YAML::Node& map, const std::string& prefix) {
    std::set<std::string> seen;
    for (auto it = map.begin(); it != map.end(); ++it) {
      const YAML::Node k = it->first;  // copies: it-> yields a temporary proxy
      const YAML::Node v = it->second;
      const std::string name = k.IsScalar() ? k.Scalar() : node_text(k);
      const std::string key = prefix.empty() ? name : prefix + "." + name;
      const YAML::Mark vm = (v.IsDefined() && v.Mark().line >= 0 && !v.IsNull()) ? v.Mark() : k.Mark();
      if (!seen.insert(name).second) {
        add(k.Mark(), "key '" + key + "' appears twice in the same section");
        continue;
      }
      if (const SchemaEntry* e = find_schema_entry(key)) {
        marks_[key] = vm;
        const std::size_t before = r_.errors.size();
        parse_value(*e, v, key, vm);
        if (r_.errors.size() != before) failed_.insert(key);
      } else if (is_schema_section(key)) {
        marks_[key] = k.Mark();
        if (v.IsMap())
          walk(v, key);
        else if (!v.IsNull())
          add(vm, key, node_text(v), "a section (mapping of keys: " + join(children_of(key)) + ")");
      } else {
        const std::string s = suggestion(prefix, name);
        add(k.Mark(),
            "unknown key '" + key + "'" + (s.empty() ? "" : " (did you mean '" + s + "'?)") +
                (prefix.empty() || s.size() ? ""
                                            : "; keys of '" + prefix + "': " + join(children_of(prefix))));
      }
    }
  }

  static std::string join(const std::vector<std::string>& v) {
    std::string s;
    for (std::size_t k = 0; k < v.size(); ++k) s += (k ? ", " : "") + v[k];
    return s;
  }

  bool scalar_number(const SchemaEntry& e, const YAML::Node& n, const std::string& key, const YAML::Mark& m,
                     double& d) {
    const bool is_int = e.kind == ValueKind::kInt || e.kind == ValueKind::kIntList;
    if (!n.IsScalar()) {
      add(m, key, node_text(n), describe_expected(e));
      return false;
    }
    const std::string& s = n.Scalar();
    std::int64_t i = 0;
    bool ok = is_int ? parse_int(s, i) : parse_double(s, d);
    if (is_int) d = static_cast<double>(i);
    if (!ok || !std::isfinite(d) || !in_bounds(e, d)) {
      add(m, key, s, describe_expected(e));
      return false;
    }
    return true;
  }

  void parse_value(const SchemaEntry& e, const YAML::Node& n, const std::string& key, const YAML::Mark& m) {
    ConfigValue v;
    const bool null = !n.IsDefined() || n.IsNull();
    switch (e.kind) {
      case ValueKind::kDouble:
      case ValueKind::kInt: {
        double d = 0.0;
        if (null) {
          add(m, key, "", describe_expected(e));
          return;
        }
        if (!scalar_number(e, n, key, m, d)) return;
        v.d = d;
        v.i = static_cast<std::int64_t>(d);
        break;
      }
      case ValueKind::kBool:
        if (null || !n.IsScalar() || !parse_bool(n.Scalar(), v.b)) {
          add(m, key, node_text(n), describe_expected(e));
          return;
        }
        break;
      case ValueKind::kString:
      case ValueKind::kPath:
        if (!null && !n.IsScalar()) {
          add(m, key, node_text(n), describe_expected(e));
          return;
        }
        v.s = null ? "" : n.Scalar();
        if (e.kind == ValueKind::kPath && !v.s.empty()) {
          std::filesystem::path p(v.s);
          if (p.is_relative()) p = dir_ / p;
          v.s = p.lexically_normal().string();
        }
        break;
      case ValueKind::kEnum: {
        const std::string s = (!null && n.IsScalar()) ? n.Scalar() : node_text(n);
        if (std::find(e.choices.begin(), e.choices.end(), s) == e.choices.end()) {
          std::string hint;
          for (const auto& c : e.choices) {  // a near miss, not a whole other word ('2' is no typo of '3')
            const auto d = edit_distance(lower(s), c);
            if (d <= 2 && d < c.size()) hint = " (did you mean '" + c + "'?)";
          }
          add(m, key, s, describe_expected(e) + hint);
          return;
        }
        v.s = s;
        break;
      }
      case ValueKind::kDoubleList:
      case ValueKind::kIntList: {
        if (null || !n.IsSequence()) {
          add(m, key, node_text(n), describe_expected(e));
          return;
        }
        bool ok = true;
        for (std::size_t k = 0; k < n.size(); ++k) {
          double d = 0.0;
          const YAML::Mark em = n[k].Mark().line >= 0 ? n[k].Mark() : m;
          if (!scalar_number(e, n[k], key + "[" + std::to_string(k) + "]", em, d)) {
            ok = false;
            continue;
          }
          v.dl.push_back(d);
          v.il.push_back(static_cast<std::int64_t>(d));
        }
        if (!ok) return;
        if (n.size() < e.min_len || (e.max_len > 0 && n.size() > e.max_len)) {
          add(m, key, node_text(n), describe_expected(e));
          return;
        }
        break;
      }
    }
    values_[key] = node_text(n);
    e.set(cfg_, v);
  }

  /// metrics.address: HOST:PORT (PORT 1..65535; [v6]:PORT allowed), checked so the service fails at
  /// --check-config.
  void check_metrics_address() {
    const std::string& a = cfg_.metrics.address;
    const auto colon = a.rfind(':');
    bool ok = colon != std::string::npos && colon > 0 && colon + 1 < a.size() && colon + 6 >= a.size();
    long port = 0;
    for (std::size_t i = colon + 1; ok && i < a.size(); ++i) {
      ok = a[i] >= '0' && a[i] <= '9';
      port = port * 10 + (a[i] - '0');
    }
    if (ok && port >= 1 && port <= 65535) return;
    const char* k = "metrics.address";
    add(mark_of(k), k, a, "HOST:PORT, e.g. 127.0.0.1:9464 (port 1..65535)");
  }

  void check_wheel_keys() {
    if (!present("wheel.tooth_angles_deg") || cfg_.wheel.geometry.tooth_count == 0) return;  // [] = N-M wheel
    for (const char* k : {"wheel.teeth", "wheel.missing"})
      if (present(k))
        add(mark_of(k), k, values_[k],
            "no value when wheel.tooth_angles_deg is given (use one description of the wheel)");
  }

  void require_file(const std::string& key, const std::string& path, const std::string& why) {
    if (!options_.check_files) return;
    const std::string shown =
        values_.count(key) && values_.at(key) != path ? values_.at(key) + "' (= " + path + ")" : path + "'";
    auto fail = [&](const std::string& expected) {
      add(mark_of(key), "key '" + key + "': found '" + shown + ", expected " + expected);
    };
    if (path.empty()) {
      add(mark_of(key), key, "", "a file path (" + why + ")");
      return;
    }
    std::error_code ec;
    const auto st = std::filesystem::status(path, ec);
    if (ec || !std::filesystem::exists(st)) {
      fail("an existing file (" + why + "): no such file");
    } else if (!std::filesystem::is_regular_file(st)) {
      fail("a regular file (" + why + ")");
    } else if (::access(path.c_str(), R_OK) != 0) {
      fail("a readable file (" + why + "): permission denied");
    }
  }

  void check_files() {
    const auto& in = cfg_.inputs;
    if (in.edges.backend == EdgeBackend::kFile && !failed("inputs.edges.backend"))
      require_file("inputs.edges.path", in.edges.path, "inputs.edges.backend is file");
    if (in.can.backend == CanBackend::kFile && !failed("inputs.can.backend")) {
      if (!in.can.path.empty() || !options_.check_files)
        require_file("inputs.can.path", in.can.path, "inputs.can.backend is file");
      else
        r_.warnings.push_back(file_ + ": inputs.can.path is empty: no CAN input, CAN-based estimators hold");
    }
    bool any_mapped = false;
    for (std::size_t q = 0; q < kCanQuantityCount; ++q) {
      const auto& s = cfg_.can.signals[q];
      const std::string base = "can.signals." + std::string(can_quantity_name(q));
      any_mapped = any_mapped || s.mapped();
      if (s.message.empty() != s.signal.empty()) {
        const std::string missing = s.message.empty() ? base + ".message" : base + ".signal";
        add(mark_of(missing), missing, "", "a DBC name (message and signal are given together)");
      }
    }
    if (!cfg_.can.dbc.empty()) {
      const std::size_t before = r_.errors.size();
      require_file("can.dbc", cfg_.can.dbc, "named DBC file");
      if (r_.errors.size() == before && options_.check_files) check_dbc_names();
    } else if (any_mapped && options_.check_files)
      add(mark_of("can.dbc"), "can.dbc", "", "a DBC file path (can.signals maps DBC signals)");
  }

  /// Every mapped message/signal must exist in the DBC as the daemon's parser (io/dbc.cpp) reads it: a
  /// statement it skips is an error here when it takes out a mapped signal, else a warning.
  void check_dbc_names() {
    const DbcParseResult p = DbcDatabase::parse_file(cfg_.can.dbc);
    if (!p.db) {
      for (const auto& e : p.errors) add(mark_of("can.dbc"), "key 'can.dbc': " + e);
      return;
    }
    std::unordered_map<std::string, std::vector<std::string>> messages;
    for (const auto& m : p.db->messages()) {
      auto& names = messages[m.name];
      for (const auto& s : m.signals) names.push_back(s.name);
    }
    std::set<const std::string*> refused;
    for (std::size_t q = 0; q < kCanQuantityCount; ++q) {
      const auto& m = cfg_.can.signals[q];
      const std::string* e = m.mapped() ? p.affecting(m.message, m.signal) : nullptr;
      if (e == nullptr) continue;
      const std::string key = "can.signals." + std::string(can_quantity_name(q)) + ".signal";
      add(mark_of(key), key, m.signal, "a signal the DBC parser can load (" + *e + ")");
      refused.insert(e);
    }
    for (const auto& e : p.errors)
      if (refused.count(&e) == 0) r_.warnings.push_back(e);
    const std::string dbc_name = std::filesystem::path(cfg_.can.dbc).filename().string();
    for (std::size_t q = 0; q < kCanQuantityCount; ++q) {
      const auto& m = cfg_.can.signals[q];
      if (!m.mapped() || m.signal.empty()) continue;
      const std::string base = "can.signals." + std::string(can_quantity_name(q));
      if (p.affecting(m.message, m.signal) != nullptr) continue;  // named above
      auto it = messages.find(m.message);
      if (it == messages.end()) {
        std::vector<std::string> names;
        for (const auto& [n, sigs] : messages) names.push_back(n);
        std::sort(names.begin(), names.end());
        add(mark_of(base + ".message"), base + ".message", m.message,
            "a message of " + dbc_name + " (" + join(names) + ")");
      } else if (std::find(it->second.begin(), it->second.end(), m.signal) == it->second.end()) {
        add(mark_of(base + ".signal"), base + ".signal", m.signal,
            "a signal of message " + m.message + " in " + dbc_name + " (" + join(it->second) + ")");
      }
    }
  }

  std::string file_;
  LoadOptions options_;
  std::filesystem::path dir_;
  Config cfg_;
  LoadResult r_;
  std::unordered_map<std::string, YAML::Mark> marks_;
  std::unordered_map<std::string, std::string> values_;  ///< raw YAML text of every key given
  std::set<std::string> failed_;                         ///< keys whose value was refused
};

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(6);
  os << v;
  return os.str();
}

}  // namespace

std::optional<std::string> check_fourier_stability(const FourierParams& p, const WheelGeometry& w) {
  // Samples per 720° cycle: every tooth position (missing ones are interpolated) or every listed tooth.
  const int per_rev = w.tooth_count > 0 ? w.tooth_count : w.positions;
  const int n_samples = 2 * per_rev;
  if (2 * p.harmonics + 1 >= n_samples)
    return "2*harmonics+1 = " + std::to_string(2 * p.harmonics + 1) + " must be < samples per cycle " +
           std::to_string(n_samples);
  const double d_alpha = 4.0 * std::numbers::pi / n_samples;
  // CF-14: L_ke > (Δα/2) Σ_k l_k f_k(n)² with l_0 = L_a0, f_0 = 1 and l_{a_i} = l_{b_i} = i L_ref.
  double worst = 0.0;
  for (int n = 0; n < n_samples; ++n) {
    const double a = n * d_alpha;
    double s = p.l_a0;
    for (int i = 1; i <= p.harmonics; ++i) {
      const double c = std::cos(i * a / 2.0), sn = std::sin(i * a / 2.0);
      s += i * p.l_ref * (c * c + sn * sn);
    }
    worst = std::max(worst, 0.5 * d_alpha * s);
  }
  if (!(p.l_ke > worst)) return "L_ke must exceed (dalpha/2) sum l_k f_k^2 = " + fmt(worst) + " (CF-14)";
  return std::nullopt;
}

bool valid_topic_prefix(std::string_view prefix) {
  // Cyclone DDS accepts topic names of letters, digits, '_' and '/', not starting with a digit; the daemon's
  // names are "<prefix>/<Type>" (idl/qos.hpp), so the prefix obeys the same rule.
  if (!prefix.empty() && prefix.front() >= '0' && prefix.front() <= '9') return false;
  for (const char ch : prefix) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
                    ch == '_' || ch == '/';
    if (!ok) return false;
  }
  return true;
}

namespace {

// Firing order: a permutation of 1..n (docs/equations.md §0: phases come from the firing order).
void check_firing_order(const EngineGeometry& e, std::vector<ConfigProblem>& out) {
  std::vector<int> count(kMaxCylinders + 1, 0);
  std::string listed = "[";
  int len = 0;
  for (int k = 0; k < kMaxCylinders && e.firing_order[std::size_t(k)] != 0; ++k, ++len) {
    const int cyl = e.firing_order[std::size_t(k)];
    listed += (k ? ", " : "") + std::to_string(cyl);
    if (cyl >= 1 && cyl <= kMaxCylinders) ++count[std::size_t(cyl)];
  }
  listed += "]";
  std::string why;
  if (len != e.cylinders)
    why = std::to_string(len) + " entries for " + std::to_string(e.cylinders) + " cylinders";
  for (int cyl = 1; cyl <= e.cylinders && why.empty(); ++cyl) {
    if (count[std::size_t(cyl)] > 1)
      why = "cylinder " + std::to_string(cyl) + " appears twice";
    else if (count[std::size_t(cyl)] == 0)
      why = "cylinder " + std::to_string(cyl) + " is missing";
  }
  for (int k = 0; k < len && why.empty(); ++k)
    if (e.firing_order[std::size_t(k)] > e.cylinders)
      why = "cylinder " + std::to_string(e.firing_order[std::size_t(k)]) + " does not exist";
  if (!why.empty())
    out.push_back({"engine.firing_order", listed,
                   "a permutation of 1.." + std::to_string(e.cylinders) + " (" + why + ")"});
}

void check_geometry(const Config& c, std::vector<ConfigProblem>& out) {
  const auto& e = c.engine;
  check_firing_order(e, out);
  if (!(e.rod_m > e.crank_radius_m()))
    out.push_back(
        {"engine.rod_m", fmt(e.rod_m),
         "a rod longer than the crank radius stroke_m/2 = " + fmt(e.crank_radius_m()) + " m (slider-crank)"});
  const auto& w = c.wheel.geometry;
  if (w.tooth_count == 0) {
    if (w.missing >= w.positions)
      out.push_back({"wheel.missing", std::to_string(w.missing),
                     "fewer missing teeth than teeth = " + std::to_string(w.positions)});
    else if (w.positions - w.missing < 2)
      out.push_back({"wheel.missing", std::to_string(w.missing), "at least 2 real teeth per revolution"});
    return;
  }
  for (int k = 1; k < w.tooth_count; ++k)
    if (!(w.tooth_angles_deg[std::size_t(k)] > w.tooth_angles_deg[std::size_t(k - 1)])) {
      out.push_back(
          {"wheel.tooth_angles_deg", fmt(w.tooth_angles_deg[std::size_t(k)]),
           "strictly increasing angles (element " + std::to_string(k) + " is not above the previous one)"});
      break;
    }
  if (w.tooth_count < 2)
    out.push_back({"wheel.tooth_angles_deg", std::to_string(w.tooth_count) + " teeth", "at least 2 teeth"});
}

// Bounds that come in pairs: the upper one above the lower one.
void check_ordered_pairs(const Config& c, std::vector<ConfigProblem>& out) {
  if (!(c.wheel.decoder.gap_ratio_min < c.wheel.decoder.gap_ratio_max))
    out.push_back({"wheel.decoder.gap_ratio_max", fmt(c.wheel.decoder.gap_ratio_max),
                   "more than gap_ratio_min = " + fmt(c.wheel.decoder.gap_ratio_min)});
  if (!(c.wheel.decoder.cam_window_start_deg < c.wheel.decoder.cam_window_end_deg))
    out.push_back({"wheel.decoder.cam_window_end_deg", fmt(c.wheel.decoder.cam_window_end_deg),
                   "more than cam_window_start_deg = " + fmt(c.wheel.decoder.cam_window_start_deg)});
  if (!(c.estimators.kalman.params.min_rpm < c.estimators.kalman.params.max_rpm))
    out.push_back({"estimators.kalman.max_rpm", fmt(c.estimators.kalman.params.max_rpm),
                   "more than min_rpm = " + fmt(c.estimators.kalman.params.min_rpm)});
  const auto& lr = c.can.load_reference;
  if (!(lr.free_coast_step_min < lr.free_coast_step_max))
    out.push_back({"can.load_reference.free_coast_step_max", fmt(lr.free_coast_step_max),
                   "more than free_coast_step_min = " + fmt(lr.free_coast_step_min)});
  if (!(lr.free_coast_decel_min < lr.free_coast_decel_max))
    out.push_back({"can.load_reference.free_coast_decel_max", fmt(lr.free_coast_decel_max),
                   "more than free_coast_decel_min = " + fmt(lr.free_coast_decel_min)});
}

void check_energy_windows(const Config& c, bool geometry_ok, std::vector<ConfigProblem>& out) {
  const auto& en = c.estimators.energies.params;
  if (!(en.window_end_btdc_deg < en.window_start_btdc_deg))
    out.push_back({"estimators.energies.window_end_btdc_deg", fmt(en.window_end_btdc_deg),
                   "less than window_start_btdc_deg = " + fmt(en.window_start_btdc_deg) + " deg"});
  // The pressure model blends from the expansion polytrope to p_exh between EVO and the blowdown end
  // (estimators/energy/load_rls_model.hpp): the blowdown ends after the exhaust valve opens.
  if (!(en.evo_atdc_deg < en.blowdown_end_atdc_deg))
    out.push_back({"estimators.energies.blowdown_end_atdc_deg", fmt(en.blowdown_end_atdc_deg),
                   "more than evo_atdc_deg = " + fmt(en.evo_atdc_deg) +
                       " deg (the blowdown ends after the exhaust valve opens)"});
  // Per-cylinder KE windows end energy_window/2 after each boundary; neighbouring ones must not overlap.
  const double seg_deg = 720.0 / std::max(1, c.engine.cylinders);
  if (!(en.cylinder_window_deg < seg_deg))
    out.push_back({"estimators.energies.cylinder_window_deg", fmt(en.cylinder_window_deg),
                   "less than 720 deg / cylinders = " + fmt(seg_deg) +
                       " deg (windows of neighbouring boundaries must not overlap)"});
  // The estimator's own check (CF-14 at every tooth + spectral radius of the cycle map) when the Fourier
  // observer runs; check_fourier_stability() above is the paper's bound alone.
  if (c.estimators.fourier.enabled && geometry_ok)
    if (auto why = FourierObserver::check_stability(c.estimators.fourier.params, c.engine, c.wheel.geometry))
      out.push_back({"estimators.fourier.l_ke", fmt(c.estimators.fourier.params.l_ke),
                     "stable observer gains: " + *why});
}

void check_threads(const Config& c, std::vector<ConfigProblem>& out) {
  const std::pair<const char*, const ThreadConfig*> threads[] = {{"angle", &c.realtime.angle},
                                                                 {"time", &c.realtime.time},
                                                                 {"source", &c.realtime.source},
                                                                 {"publisher", &c.realtime.publisher}};
  for (const auto& [name, t] : threads) {
    const std::string base = std::string("realtime.") + name;
    if (t->policy == SchedPolicy::kFifo && t->priority < 1)
      out.push_back({base + ".priority", std::to_string(t->priority), "1..99 with policy fifo"});
    std::set<int> seen;
    for (int cpu : t->cpus)
      if (!seen.insert(cpu).second) {
        out.push_back({base + ".cpus", std::to_string(cpu), "each CPU listed once"});
        break;
      }
  }
}

// What an input backend, a CAN mapping or the DDS names need besides their own value.
void check_dependencies(const Config& c, std::vector<ConfigProblem>& out) {
  if (c.inputs.edges.backend == EdgeBackend::kGpio && c.inputs.edges.gpio_chip.empty())
    out.push_back({"inputs.edges.gpio_chip", "", "a GPIO chip device (backend gpio)"});
  if (c.inputs.can.backend == CanBackend::kSocketCan && c.inputs.can.interface.empty())
    out.push_back({"inputs.can.interface", "", "a SocketCAN interface name (backend socketcan)"});
  if (c.wheel.crank_channel.empty()) out.push_back({"wheel.crank_channel", "", "a channel name"});
  if (c.can.e_machine.sign == 0) out.push_back({"can.e_machine.sign", "0", "+1 or -1"});
  if (!valid_topic_prefix(c.dds.topic_prefix))
    out.push_back(
        {"dds.topic_prefix", c.dds.topic_prefix,
         "letters, digits, '_' and '/' only, not starting with a digit (DDS topic names: Cyclone DDS "
         "refuses any other character when the daemon creates its topics)"});
  const bool em_mapped = c.can.signals[kCanEmTorque].mapped();
  if (c.can.signals[kCanEmSoleLoad].mapped() && !em_mapped)
    out.push_back(
        {"can.signals.em_sole_load", c.can.signals[kCanEmSoleLoad].message,
         "can.signals.em_torque mapped (the flag says when the machine's torque is the only load)"});
  if (c.can.e_machine.sole_load && !em_mapped)
    out.push_back(
        {"can.e_machine.sole_load", "true", "can.signals.em_torque mapped (the machine's torque on CAN)"});
}

}  // namespace

std::vector<ConfigProblem> check_config_physics(const Config& c) {
  std::vector<ConfigProblem> out;
  check_geometry(c, out);
  const bool geometry_ok = out.empty();  // the Fourier observer's check needs a valid engine and wheel
  check_ordered_pairs(c, out);
  check_energy_windows(c, geometry_ok, out);
  check_threads(c, out);
  check_dependencies(c, out);
  return out;
}

LoadResult load_config_from_string(const std::string& yaml, const std::string& file_name,
                                   const LoadOptions& options) {
  return Loader(file_name, options).run(yaml);
}

LoadResult load_config(const std::string& path, const LoadOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    LoadResult r;
    r.errors.push_back(path + ": cannot open configuration file: " + std::strerror(errno));
    return r;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return load_config_from_string(ss.str(), path, options);
}

}  // namespace torqued
