#pragma once
// The ONE table of configuration keys: YAML key, type, default (taken from Config{}), bounds, unit and a
// one-line description (docs/conventions.md habit 7). The loader parses against it, `torqued --print-schema`
// prints it, and config/torqued.example.yaml is checked against it by tests/config.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "config.hpp"

namespace torqued {

enum class ValueKind : std::uint8_t { kDouble, kInt, kBool, kString, kPath, kEnum, kDoubleList, kIntList };

/// A value in YAML units (e.g. degrees where the YAML key says _deg).
struct ConfigValue {
  double d = 0.0;
  std::int64_t i = 0;
  bool b = false;
  std::string s;                 ///< kString, kPath, kEnum
  std::vector<double> dl;        ///< kDoubleList
  std::vector<std::int64_t> il;  ///< kIntList
};

struct SchemaEntry {
  std::string key;  ///< dotted YAML path, e.g. "engine.bore_m"
  ValueKind kind = ValueKind::kDouble;
  std::string unit;         ///< "" for dimensionless
  std::string description;  ///< one line
  // Numeric bounds (each element for lists); open = exclusive.
  double lo = 0.0, hi = 0.0;
  bool lo_open = false, hi_open = false;
  bool bounded = false;
  std::vector<std::string> choices;      ///< kEnum
  std::size_t min_len = 0, max_len = 0;  ///< lists (max_len 0 = unbounded)
  std::function<void(Config&, const ConfigValue&)> set;
  std::function<ConfigValue(const Config&)> get;
};

/// Every key, in documentation order.
[[nodiscard]] const std::vector<SchemaEntry>& config_schema();
/// Entry for a dotted key, or nullptr.
[[nodiscard]] const SchemaEntry* find_schema_entry(const std::string& key);
/// True if some key lies below `prefix` (prefix is a section).
[[nodiscard]] bool is_schema_section(const std::string& prefix);

/// YAML rendering of a value of that entry ("0.0825", "[1, 3, 4, 2]", "\"crank\"", "rising").
[[nodiscard]] std::string format_config_value(const SchemaEntry& e, const ConfigValue& v);
/// "a number > 0 (m, range (0, 1])", "one of file|gpio|can_encoder", ...
[[nodiscard]] std::string describe_expected(const SchemaEntry& e);
/// A complete YAML file with every key at its default, each preceded by a comment (unit, bounds,
/// description).
[[nodiscard]] std::string schema_example_yaml();
/// Human-readable table (key, type, default, bounds, unit, description), one key per line.
[[nodiscard]] std::string schema_table_text();

}  // namespace torqued
