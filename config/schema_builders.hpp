#pragma once
// Internal to config/: small builders for the schema table (config_schema.cpp, config_schema_estimators.cpp).
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "config_schema.hpp"

namespace torqued::schema_detail {

inline constexpr double kInf = std::numeric_limits<double>::infinity();
inline constexpr double kDegToRad = std::numbers::pi / 180.0;

struct Bounds {
  double lo = -kInf, hi = kInf;
  bool lo_open = false, hi_open = false;
};
inline Bounds closed(double lo, double hi) { return {lo, hi, false, false}; }
inline Bounds positive(double hi) { return {0.0, hi, true, false}; }  // (0, hi]
inline Bounds unbounded() { return {}; }

inline void apply(SchemaEntry& e, Bounds b) {
  e.lo = b.lo;
  e.hi = b.hi;
  e.lo_open = b.lo_open;
  e.hi_open = b.hi_open;
  e.bounded = std::isfinite(b.lo) || std::isfinite(b.hi);
}

template <class T>
using Ref = T& (*)(Config&);

inline SchemaEntry entry(std::string key, ValueKind kind, std::string unit, std::string desc) {
  SchemaEntry e;
  e.key = std::move(key);
  e.kind = kind;
  e.unit = std::move(unit);
  e.description = std::move(desc);
  return e;
}

inline Config& mut(const Config& c) {
  return const_cast<Config&>(c);
}  // getters only read through the reference

inline SchemaEntry number(std::string key, Ref<double> ref, Bounds b, std::string unit, std::string desc,
                          double scale = 1.0) {
  SchemaEntry e = entry(std::move(key), ValueKind::kDouble, std::move(unit), std::move(desc));
  apply(e, b);
  e.set = [ref, scale](Config& c, const ConfigValue& v) { ref(c) = v.d * scale; };
  e.get = [ref, scale](const Config& c) {
    ConfigValue v;
    v.d = ref(mut(c)) / scale;
    return v;
  };
  return e;
}

template <class T>
SchemaEntry integer(std::string key, Ref<T> ref, Bounds b, std::string unit, std::string desc) {
  SchemaEntry e = entry(std::move(key), ValueKind::kInt, std::move(unit), std::move(desc));
  apply(e, b);
  e.set = [ref](Config& c, const ConfigValue& v) { ref(c) = static_cast<T>(v.i); };
  e.get = [ref](const Config& c) {
    ConfigValue v;
    v.i = static_cast<std::int64_t>(ref(mut(c)));
    return v;
  };
  return e;
}

inline SchemaEntry boolean(std::string key, Ref<bool> ref, std::string desc) {
  SchemaEntry e = entry(std::move(key), ValueKind::kBool, "", std::move(desc));
  e.set = [ref](Config& c, const ConfigValue& v) { ref(c) = v.b; };
  e.get = [ref](const Config& c) {
    ConfigValue v;
    v.b = ref(mut(c));
    return v;
  };
  return e;
}

inline SchemaEntry text(std::string key, Ref<std::string> ref, std::string desc, bool is_path = false) {
  SchemaEntry e = entry(std::move(key), is_path ? ValueKind::kPath : ValueKind::kString, "", std::move(desc));
  e.set = [ref](Config& c, const ConfigValue& v) { ref(c) = v.s; };
  e.get = [ref](const Config& c) {
    ConfigValue v;
    v.s = ref(mut(c));
    return v;
  };
  return e;
}

template <class E>
SchemaEntry choice(std::string key, Ref<E> ref, std::vector<std::pair<std::string, E>> names,
                   std::string desc) {
  SchemaEntry e = entry(std::move(key), ValueKind::kEnum, "", std::move(desc));
  for (const auto& n : names) e.choices.push_back(n.first);
  e.set = [ref, names](Config& c, const ConfigValue& v) {
    for (const auto& n : names)
      if (n.first == v.s) ref(c) = n.second;
  };
  e.get = [ref, names](const Config& c) {
    ConfigValue v;
    for (const auto& n : names)
      if (n.second == ref(mut(c))) v.s = n.first;
    return v;
  };
  return e;
}

template <std::size_t N>
SchemaEntry fixed_list(std::string key, Ref<std::array<double, N>> ref, Bounds b, std::string unit,
                       std::string desc) {
  SchemaEntry e = entry(std::move(key), ValueKind::kDoubleList, std::move(unit), std::move(desc));
  apply(e, b);
  e.min_len = e.max_len = N;
  e.set = [ref](Config& c, const ConfigValue& v) {
    for (std::size_t k = 0; k < N && k < v.dl.size(); ++k) ref(c)[k] = v.dl[k];
  };
  e.get = [ref](const Config& c) {
    ConfigValue v;
    v.dl.assign(ref(mut(c)).begin(), ref(mut(c)).end());
    return v;
  };
  return e;
}

inline SchemaEntry cpu_list(std::string key, Ref<std::vector<int>> ref, std::string desc) {
  SchemaEntry e = entry(std::move(key), ValueKind::kIntList, "", std::move(desc));
  apply(e, closed(0, 1023));
  e.max_len = 1024;
  e.set = [ref](Config& c, const ConfigValue& v) { ref(c).assign(v.il.begin(), v.il.end()); };
  e.get = [ref](const Config& c) {
    ConfigValue v;
    v.il.assign(ref(mut(c)).begin(), ref(mut(c)).end());
    return v;
  };
  return e;
}

using Arr2 = std::array<double, 2>;
using Arr4 = std::array<double, 4>;
#define TQ_REF(T, expr) (+[](Config& c) -> T& { return c.expr; })

/// Estimator keys (config_schema_estimators.cpp).
void add_estimators(std::vector<SchemaEntry>& t);

}  // namespace torqued::schema_detail
