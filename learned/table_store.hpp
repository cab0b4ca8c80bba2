#pragma once
// File-backed TableCache (estimators/core/table_cache.hpp): the start-up tables of the estimators, kept next
// to the learned state (<state_dir>/tables) so that a restart or a batch of short replays does not recompute
// them (the Kalman filter's periodic gains and the load RLS's integrals: most of the start-up instructions).
//
// One file per table and key: <dir>/<kind>-<key, 16 hex digits>.bin, binary, native byte order:
//   "TQTABLE1" | key (u64) | binary id (u64) | count (u64) | count doubles | checksum (u64)
// key: the estimator's hash of every input that determines the table; binary id: a hash of the executable's
// GNU build id, so a rebuilt daemon (whose code may compute a different table) never reads an old file;
// checksum: 64-bit FNV-1a over the 8-byte words before it. A file failing any check (short, wrong magic,
// key, binary id, size or checksum) is ignored and replaced by the recomputed table. Writes are atomic like
// the learned state's (state_store.hpp): <file>.tmp.<pid> written and fsync()ed, renamed over <file>, the
// directory fsync()ed; a crash leaves the old complete file or none. Not real-time (start-up only).
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "table_cache.hpp"

namespace torqued {

class TableStore final : public TableCache {
 public:
  /// Receives each message as it happens (`warning` true for a damaged file; another build's, or a
  /// directory that cannot be written, is information).
  using Reporter = std::function<void(const std::string& message, bool warning)>;
  /// `dir` is created on the first store (with its parent). `binary_id` 0: this executable's build id.
  /// Without a `reporter` the messages wait for take_messages().
  explicit TableStore(std::string dir, std::uint64_t binary_id = 0, Reporter reporter = {});

  std::optional<std::vector<double>> load(std::string_view kind, std::uint64_t key) override;
  void store(std::string_view kind, std::uint64_t key, std::span<const double> table) override;

  [[nodiscard]] std::string path_of(std::string_view kind, std::uint64_t key) const;
  [[nodiscard]] const std::string& dir() const noexcept { return dir_; }
  /// What happened since the last call, one line per table (for the daemon's log): loaded, computed and
  /// stored, or why a file was not used or could not be written.
  [[nodiscard]] std::vector<std::string> take_messages();
  [[nodiscard]] int hits() const noexcept { return hits_; }
  [[nodiscard]] int misses() const noexcept { return misses_; }
  [[nodiscard]] bool usable() const noexcept { return binary_id_ != 0; }

 private:
  std::string dir_;
  std::uint64_t binary_id_ = 0;
  std::mutex mu_;
  Reporter reporter_;
  std::vector<std::string> messages_;
  void note(std::string message, bool warning);
  int hits_ = 0, misses_ = 0;
};

/// Installs a cache as the process-wide one (table_cache()) for its lifetime; nullptr installs none.
class ScopedTableCache {
 public:
  explicit ScopedTableCache(TableCache* cache) noexcept { set_table_cache(cache); }
  ~ScopedTableCache() { set_table_cache(nullptr); }
  ScopedTableCache(const ScopedTableCache&) = delete;
  ScopedTableCache& operator=(const ScopedTableCache&) = delete;
};

/// Hash of this executable's GNU build id (.note.gnu.build-id); 0 when it has none (no cache then).
[[nodiscard]] std::uint64_t executable_build_id() noexcept;

/// The table directory for a configuration: `configured` unless empty ("off": none, returns ""); else
/// <state_dir>/tables when a state directory is set; else $XDG_CACHE_HOME/torqued or $HOME/.cache/torqued;
/// else "" (no cache).
[[nodiscard]] std::string table_dir_for(const std::string& configured, const std::string& state_dir);

}  // namespace torqued
