#include "topic_format.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <type_traits>

#include "csv_number.hpp"
#include "methods.hpp"

namespace torqued::dds {
namespace {

template <class V>
void append_number(std::string& out, V v) {
  char buf[64];
  if constexpr (std::is_same_v<V, bool>) {
    out += v ? '1' : '0';
    return;
  } else if constexpr (std::is_floating_point_v<V>) {
    if (std::isnan(v)) {
      out += "nan";
      return;
    }
    if (std::isinf(v)) {
      out += v > 0 ? "inf" : "-inf";
      return;
    }
    auto r = std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, r.ptr);
  } else {
    // uint8_t must print as a number, not a character.
    using W = std::conditional_t<std::is_signed_v<V>, long long, unsigned long long>;
    auto r = std::to_chars(buf, buf + sizeof buf, static_cast<W>(v));
    out.append(buf, r.ptr);
  }
}

struct HeaderVisitor {
  std::string& out;
  template <class V>
  void operator()(std::string_view name, const V&) {
    if (name == "source_t_ns") return;  // is the first column t_ns
    out += ',';
    out += name;
  }
  template <class V>
  void operator()(std::string_view name, const V*, int n) {
    for (int i = 1; i <= n; ++i) {
      out += ',';
      out += name;
      out += '_';
      append_number(out, i);
    }
  }
};

/// CSV numbers (csv_number.hpp): integers in decimal, doubles in fixed point at the column's resolution (the
/// shortest round-trip std::to_chars form was the recorder's main cost).
template <class V>
[[gnu::always_inline]] inline char* csv_value(char* p, V v, int decimals) noexcept {
  if constexpr (std::is_same_v<V, bool>) {
    *p = v ? '1' : '0';
    return p + 1;
  } else if constexpr (std::is_floating_point_v<V>) {
    return csv::write_column_double(p, static_cast<double>(v), decimals);
  } else if constexpr (std::is_signed_v<V>) {
    return csv::write_int(p, static_cast<std::int64_t>(v));
  } else {
    return csv::write_uint(p, static_cast<std::uint64_t>(v));
  }
}

/// Per topic, computed at compile time from the field names: the decimals of each double column, the index
/// of source_t_ns (written first as t_ns) and the number of columns. Name look-ups per row were not folded by
/// the compiler; a function-local static plan cost a guard check per row.
struct RowPlan {
  std::array<std::int8_t, 64> decimals{};
  int skip = -1;
  int columns = 1;  // t_ns
};
struct PlanVisitor {
  RowPlan& plan;
  std::size_t i = 0;
  template <class V>
  constexpr void operator()(std::string_view name, const V&) {
    if (name == "source_t_ns")
      plan.skip = static_cast<int>(i);
    else
      ++plan.columns;
    plan.decimals.at(i++) = static_cast<std::int8_t>(csv::csv_decimals(name));
  }
  template <class V>
  constexpr void operator()(std::string_view name, const V*, int n) {
    plan.columns += n;
    plan.decimals.at(i++) = static_cast<std::int8_t>(csv::csv_decimals(name));
  }
};
template <class T>
constexpr RowPlan make_row_plan() {
  RowPlan plan;
  visit_fields(T{}, PlanVisitor{plan});
  return plan;
}
template <class T>
inline constexpr RowPlan kRowPlan = make_row_plan<T>();
/// Room per column: ',' + the longest number (write_fixed: 40 bytes of room, shortest double: 24 chars).
constexpr std::size_t kColumnRoom = 48;
template <class T>
inline constexpr std::size_t kRowMaxChars = static_cast<std::size_t>(kRowPlan<T>.columns) * kColumnRoom + 1;

/// CSV row writer: straight into the caller's buffer (room checked once per row by the caller), the write
/// position in a register (the former writer kept it in memory behind a stack buffer spilled into a
/// std::string: EstimatorTorque rows of a real recording 46 -> 38 ns).
template <class T>
struct RowVisitor {
  char* p;
  int i = 0;
  template <class V>
  [[gnu::always_inline]] void operator()(std::string_view, const V& v) {
    const int k = i++;
    if constexpr (std::is_same_v<V, std::int64_t>) {
      if (k == kRowPlan<T>.skip) return;
    }
    char* q = p;
    *q++ = ',';
    p = csv_value(q, v, kRowPlan<T>.decimals[static_cast<std::size_t>(k)]);
  }
  template <class V>
  [[gnu::always_inline]] void operator()(std::string_view, const V* a, int n) {
    const int d = kRowPlan<T>.decimals[static_cast<std::size_t>(i++)];
    char* q = p;
    for (int j = 0; j < n; ++j) {
      *q++ = ',';
      q = csv_value(q, a[j], d);
    }
    p = q;
  }
};

struct JsonVisitor {
  std::string& out;
  template <class V>
  void operator()(std::string_view name, const V& v) {
    out += ",\"";
    out += name;
    out += "\":";
    if constexpr (std::is_floating_point_v<V>) {
      if (!std::isfinite(v)) {
        out += "null";
        return;
      }  // JSON has no NaN/Inf
    }
    if constexpr (std::is_same_v<V, bool>) {
      out += v ? "true" : "false";
    } else {
      append_number(out, v);
    }
  }
  template <class V>
  void operator()(std::string_view name, const V* a, int n) {
    out += ",\"";
    out += name;
    out += "\":[";
    for (int i = 0; i < n; ++i) {
      if (i) out += ',';
      if (std::isfinite(static_cast<double>(a[i])))
        append_number(out, a[i]);
      else
        out += "null";
    }
    out += ']';
  }
};

void appendf(std::string& out, const char* fmt, auto... args) {
  char buf[256];
  int n = std::snprintf(buf, sizeof buf, fmt, args...);
  if (n > 0) out.append(buf, static_cast<std::size_t>(std::min<int>(n, sizeof buf - 1)));
}

double ms(std::int64_t t_ns) { return static_cast<double>(t_ns) * 1e-6; }
double rpm(double rad_s) { return rad_s * 60.0 / (2.0 * std::numbers::pi); }

}  // namespace

template <class T>
std::string csv_header() {
  std::string out = "t_ns";
  visit_fields(T{}, HeaderVisitor{out});
  out += '\n';
  return out;
}

template <class T>
std::size_t csv_row_max_chars() noexcept {
  return kRowMaxChars<T>;
}

template <class T>
[[gnu::flatten]] char* write_csv_row(char* p, const T& s) noexcept {
  RowVisitor<T> v{csv_value(p, s.source_t_ns, 0)};
  visit_fields(s, v);
  *v.p = '\n';
  return v.p + 1;
}

template <class T>
void append_csv_row(std::string& out, const T& s) {
  char buf[kRowMaxChars<T>];
  out.append(buf, write_csv_row(buf, s));
}

template <class T>
void append_json(std::string& out, const T& s) {
  out += "{\"topic\":\"";
  out += TopicTraits<T>::name;
  out += '"';
  visit_fields(s, JsonVisitor{out});
  out += "}\n";
}

template <>
std::string table_header<torque_EngineTorque>() {
  return "   t [s] kind   cyc  rpm     brake   indic   frict    load   fused  q valid\n";
}
template <>
std::string table_header<torque_EstimatorTorque>() {
  return "   t [s] method            value [Nm]  uncert  health\n";
}
template <>
std::string table_header<torque_CylinderTorque>() {
  return "   t [s]   cyc  indicated per cylinder [Nm] / imbalance [%] / misfire mask\n";
}
template <>
std::string table_header<torque_CrankState>() {
  return "   t [s] tooth sync   angle [deg]     rpm   accel [rad/s2]\n";
}
template <>
std::string table_header<torque_DaemonStatus>() {
  return "   t [s] health flags  edges  teeth  frames cycles drops(e/c/o) overruns p50/p99/max [us]\n";
}

template <>
void append_table_row(std::string& out, const torque_EngineTorque& s) {
  appendf(out, "%8.3f %-5s %5u %5.0f %7.1f %7.1f %7.1f %7.1f %7.1f %2u 0x%02x\n", ms(s.source_t_ns) * 1e-3,
          s.kind == torque_KIND_CYCLE ? "cycle" : "seg", s.cycle, rpm(s.speed_rad_s), s.brake_nm,
          s.indicated_nm, s.friction_nm, s.load_nm, s.fused_nm, unsigned{s.quality}, s.validity);
}
template <>
void append_table_row(std::string& out, const torque_EstimatorTorque& s) {
  const char* m = method_name(s.method);
  appendf(out, "%8.3f %-16s %11.2f %7.3g %7u\n", ms(s.source_t_ns) * 1e-3, m, s.value_nm, s.uncertainty,
          unsigned{s.health});
}
template <>
void append_table_row(std::string& out, const torque_CylinderTorque& s) {
  appendf(out, "%8.3f %5u ", ms(s.source_t_ns) * 1e-3, s.cycle);
  for (int i = 0; i < s.cylinders && i < 8; ++i) appendf(out, "%7.1f", s.indicated_nm[i]);
  out += " /";
  for (int i = 0; i < s.cylinders && i < 8; ++i) appendf(out, "%6.1f", s.imbalance_pct[i]);
  appendf(out, " / 0x%02x\n", unsigned{s.misfire_mask});
}
template <>
void append_table_row(std::string& out, const torque_CrankState& s) {
  appendf(out, "%8.3f %5d %4u %13.2f %7.0f %16.1f\n", ms(s.source_t_ns) * 1e-3, int{s.tooth},
          unsigned{s.sync}, s.angle_rad * 180.0 / std::numbers::pi, rpm(s.speed_rad_s), s.accel_rad_s2);
}
template <>
void append_table_row(std::string& out, const torque_DaemonStatus& s) {
  appendf(out, "%8.3f %6u 0x%03x %6llu %6llu %7llu %6llu %4llu/%llu/%llu %8llu %.1f/%.1f/%.1f\n",
          ms(s.source_t_ns) * 1e-3, unsigned{s.health}, s.flags, (unsigned long long)s.edges,
          (unsigned long long)s.teeth, (unsigned long long)s.can_frames, (unsigned long long)s.cycles,
          (unsigned long long)s.ring_drops_edge, (unsigned long long)s.ring_drops_can,
          (unsigned long long)s.ring_drops_out, (unsigned long long)s.overruns, s.latency_p50_ns * 1e-3,
          s.latency_p99_ns * 1e-3, s.latency_max_ns * 1e-3);
}

#define TORQUED_INSTANTIATE(T)                               \
  template std::string csv_header<T>();                      \
  template void append_csv_row<T>(std::string&, const T&);   \
  template std::size_t csv_row_max_chars<T>() noexcept;      \
  template char* write_csv_row<T>(char*, const T&) noexcept; \
  template void append_json<T>(std::string&, const T&);
TORQUED_INSTANTIATE(torque_EngineTorque)
TORQUED_INSTANTIATE(torque_EstimatorTorque)
TORQUED_INSTANTIATE(torque_CylinderTorque)
TORQUED_INSTANTIATE(torque_CrankState)
TORQUED_INSTANTIATE(torque_DaemonStatus)
#undef TORQUED_INSTANTIATE

}  // namespace torqued::dds
