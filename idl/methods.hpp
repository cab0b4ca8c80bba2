#pragma once
// The method registry: one entry per EstimatorTorque.method id. Everything that names, labels or sorts the
// methods follows from this table: the metrics label and the CSV/JSON/table name (`name`), the dashboard's
// label (`label`, sent to the page by torque-dash), which methods the dashboard places on the crank angle
// (`in_cycle`), which methods the time stage emits (`domain` kTime, in this order) and where each is
// described. The IDL (idl/torque.idl METHOD_*) stays the wire contract: every entry is checked against its
// constant below (a mismatch fails the build) and tests/idl/test_method_registry.cpp checks that every
// METHOD_* constant of the IDL has an entry. Adding a method: its IDL constant, one entry here, one
// static_assert below. Paper equation tags: Na = Na et al. 2017 (time domain), CK / CF = Chauvin's Kalman /
// Fourier observers, EN = Energies 2019 (docs/time_estimators.md, docs/angle_estimators.md,
// docs/angle_pipeline.md).
#include <cstdint>
#include <string_view>

#include "torque.h"

namespace torqued::dds {

enum class MethodDomain : std::uint8_t {
  kTime,          ///< time pipeline (timer, mean-value model), published every time_decimation-th step
  kAngleInCycle,  ///< angle domain, per tooth: the torque within the cycle
  kPerCycle,      ///< angle domain, per combustion segment / 720° cycle
  kFused,         ///< the fusion of the others
};

struct MethodInfo {
  std::uint8_t id;         ///< EstimatorTorque.method (= torque_METHOD_* of the IDL)
  std::string_view name;   ///< metrics label, CSV/JSON/table name (lower case, no spaces)
  std::string_view label;  ///< human label (dashboard legend)
  MethodDomain domain;
  bool in_cycle;  ///< instantaneous value within the cycle (true) or a mean (time-filtered or 720°)
  std::string_view reference;  ///< paper and equations it implements
  std::string_view doc;        ///< the project's page describing it
};

/// Index = id (checked below), so method_info() is a lookup, not a search.
inline constexpr MethodInfo kMethods[] = {
    {0, "uio", "UIO", MethodDomain::kTime, false, "Na-9, Na-14", "docs/time_estimators.md"},
    {1, "sliding_mode", "Sliding mode", MethodDomain::kTime, false, "Na-19..21", "docs/time_estimators.md"},
    {2, "dirty_diff", "Dirty differentiation", MethodDomain::kTime, false, "Na-24",
     "docs/time_estimators.md"},
    {3, "adaptive", "Adaptive", MethodDomain::kTime, false, "Na-41..54", "docs/time_estimators.md"},
    {4, "kalman", "Kalman", MethodDomain::kAngleInCycle, true, "CK-3..13, CK-18", "docs/angle_estimators.md"},
    {5, "fourier", "Fourier", MethodDomain::kAngleInCycle, true, "CF-2..10", "docs/angle_estimators.md"},
    {6, "load_rls", "Load RLS", MethodDomain::kPerCycle, false, "EN-10..15", "docs/angle_pipeline.md"},
    {7, "indicated_eso", "Indicated ESO", MethodDomain::kPerCycle, false, "EN-16..23",
     "docs/angle_pipeline.md"},
    {8, "cycle_energy", "Cycle energy", MethodDomain::kPerCycle, false, "CF-2 (energy balance over 720°)",
     "docs/angle_pipeline.md"},
    {9, "friction", "Friction", MethodDomain::kPerCycle, false, "EN-24, EN-30..36", "docs/angle_pipeline.md"},
    {10, "fused", "Fused", MethodDomain::kFused, false, "fusion rule (no paper)", "docs/angle_pipeline.md"},
};
inline constexpr int kMethodCount = static_cast<int>(sizeof(kMethods) / sizeof(kMethods[0]));

/// The wire contract: each entry's id is its IDL constant.
static_assert(kMethods[0].id == torque_METHOD_UIO && kMethods[0].name == "uio");
static_assert(kMethods[1].id == torque_METHOD_SLIDING_MODE && kMethods[1].name == "sliding_mode");
static_assert(kMethods[2].id == torque_METHOD_DIRTY_DIFF && kMethods[2].name == "dirty_diff");
static_assert(kMethods[3].id == torque_METHOD_ADAPTIVE && kMethods[3].name == "adaptive");
static_assert(kMethods[4].id == torque_METHOD_KALMAN && kMethods[4].name == "kalman");
static_assert(kMethods[5].id == torque_METHOD_FOURIER && kMethods[5].name == "fourier");
static_assert(kMethods[6].id == torque_METHOD_LOAD_RLS && kMethods[6].name == "load_rls");
static_assert(kMethods[7].id == torque_METHOD_INDICATED_ESO && kMethods[7].name == "indicated_eso");
static_assert(kMethods[8].id == torque_METHOD_CYCLE_ENERGY && kMethods[8].name == "cycle_energy");
static_assert(kMethods[9].id == torque_METHOD_FRICTION && kMethods[9].name == "friction");
static_assert(kMethods[10].id == torque_METHOD_FUSED && kMethods[10].name == "fused");

namespace detail {
consteval bool ids_are_indices() {
  for (int i = 0; i < kMethodCount; ++i)
    if (kMethods[i].id != i) return false;
  return true;
}
consteval bool names_unique() {
  for (int i = 0; i < kMethodCount; ++i)
    for (int j = i + 1; j < kMethodCount; ++j)
      if (kMethods[i].name == kMethods[j].name) return false;
  return true;
}
}  // namespace detail
static_assert(detail::ids_are_indices(), "kMethods: entry i must have id i (no gaps, in id order)");
static_assert(detail::names_unique(), "kMethods: names must be unique (metrics labels, CSV)");

/// The entry of `id`, or nullptr for an id this build does not know.
constexpr const MethodInfo* method_info(std::uint8_t id) noexcept {
  return id < kMethodCount ? &kMethods[id] : nullptr;
}
/// The name of `id` ("?" for an unknown id). Null-terminated (string literals).
constexpr const char* method_name(std::uint8_t id) noexcept {
  return id < kMethodCount ? kMethods[id].name.data() : "?";
}
constexpr bool is_in_cycle(std::uint8_t id) noexcept { return id < kMethodCount && kMethods[id].in_cycle; }
/// How many methods of `d` (sizes arrays indexed by a domain's own order).
constexpr int method_count(MethodDomain d) noexcept {
  int n = 0;
  for (const auto& m : kMethods) n += m.domain == d ? 1 : 0;
  return n;
}
constexpr std::string_view domain_name(MethodDomain d) noexcept {
  switch (d) {
    case MethodDomain::kTime:
      return "time";
    case MethodDomain::kAngleInCycle:
      return "angle_in_cycle";
    case MethodDomain::kPerCycle:
      return "per_cycle";
    case MethodDomain::kFused:
      return "fused";
  }
  return "?";
}

}  // namespace torqued::dds
