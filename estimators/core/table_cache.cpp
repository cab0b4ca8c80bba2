#include "table_cache.hpp"

#include <atomic>

namespace torqued {

namespace {
std::atomic<TableCache*> g_cache{nullptr};
}  // namespace

TableCache* table_cache() noexcept { return g_cache.load(std::memory_order_acquire); }
void set_table_cache(TableCache* cache) noexcept { g_cache.store(cache, std::memory_order_release); }

}  // namespace torqued
