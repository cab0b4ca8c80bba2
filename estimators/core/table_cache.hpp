#pragma once
// Start-up tables computed once per engine, wheel and parameter set (the Kalman filter's periodic gains, the
// load RLS's pressure-model integrals) and reused by later runs. The estimators describe every input that
// determines a table by a TableKey and ask the process-wide TableCache; without one (tests, tools) they
// compute as before. The file-backed cache the daemon installs is learned/table_store.hpp. A table read from
// the cache is the same bytes the computation wrote, so the output does not depend on whether it was
// cached. Not real-time: used at construction only.
#include <cstdint>
#include <cstring>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "engine_geometry.hpp"

namespace torqued {

// Guards for the keys below (LP64 layouts): a new field changes the size, so it gets hashed too.
static_assert(sizeof(EngineGeometry) == 104,
              "EngineGeometry changed: hash it in TableKey::add(EngineGeometry)");
static_assert(sizeof(WheelGeometry) == 16 + 8 * kMaxTeeth + 8,
              "WheelGeometry changed: hash it in TableKey::add(WheelGeometry)");

/// 64-bit FNV-1a hash of the inputs of a table (Fowler, Noll, Vo: offset basis and prime of the 64-bit
/// variant). Doubles are hashed by their bytes, so any change of an input, however small, changes the key.
class TableKey {
 public:
  TableKey& bytes(const void* p, std::size_t n) noexcept {
    const auto* c = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h_ = (h_ ^ c[i]) * 0x100000001b3ULL;
    return *this;
  }
  TableKey& add(double v) noexcept { return bytes(&v, sizeof v); }
  TableKey& add(std::int64_t v) noexcept { return bytes(&v, sizeof v); }
  TableKey& add(int v) noexcept { return add(static_cast<std::int64_t>(v)); }
  TableKey& add(bool v) noexcept { return add(static_cast<std::int64_t>(v ? 1 : 0)); }
  TableKey& add(std::span<const double> v) noexcept {
    add(static_cast<std::int64_t>(v.size()));
    return bytes(v.data(), v.size_bytes());
  }
  TableKey& add(std::string_view s) noexcept {
    add(static_cast<std::int64_t>(s.size()));
    return bytes(s.data(), s.size());
  }
  /// Every field of the engine's geometry and of the wheel (a new field changes their size: add it here).
  TableKey& add(const EngineGeometry& e) noexcept {
    add(e.cylinders).add(e.bore_m).add(e.stroke_m).add(e.rod_m).add(e.compression_ratio).add(e.j_rot_kgm2);
    add(e.m_osc_kg).add(e.tdc_offset_rad).add(e.crankcase_pressure_pa);
    for (int c : e.firing_order) add(c);
    return *this;
  }
  TableKey& add(const WheelGeometry& w) noexcept {
    add(w.positions).add(w.missing).add(w.tooth_count).add(w.rising_edge);
    return add(std::span<const double>(w.tooth_angles_deg));
  }
  [[nodiscard]] std::uint64_t value() const noexcept { return h_; }

 private:
  std::uint64_t h_ = 0xcbf29ce484222325ULL;
};

class TableCache {
 public:
  virtual ~TableCache() = default;
  /// The table `kind` stored under `key`, or nullopt when there is none or it is stale or corrupt.
  virtual std::optional<std::vector<double>> load(std::string_view kind, std::uint64_t key) = 0;
  /// Stores a table just computed (failures are the cache's to report; the caller carries on).
  virtual void store(std::string_view kind, std::uint64_t key, std::span<const double> table) = 0;
};

/// The process-wide cache (nullptr: none). Set once at start-up, before any estimator is built.
TableCache* table_cache() noexcept;
void set_table_cache(TableCache* cache) noexcept;

/// `table` from the cache when it holds `kind`/`key` with the size `expect_size` (0: any size); else
/// computes it with `compute(table)` and stores it. Returns true when it came from the cache.
template <class Compute>
bool cached_table(std::string_view kind, std::uint64_t key, std::vector<double>& table,
                  std::size_t expect_size, Compute&& compute) {
  TableCache* c = table_cache();
  if (c) {
    if (auto t = c->load(kind, key); t && (expect_size == 0 || t->size() == expect_size)) {
      table = std::move(*t);
      return true;
    }
  }
  compute(table);
  if (c) c->store(kind, key, table);
  return false;
}

}  // namespace torqued
