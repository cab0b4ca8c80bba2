#pragma once
// Signal store: the latest value of each quantity the estimators need, decoded from CAN frames through the
// DBC, converted to SI, with its source time. A value older than its time-out is invalid (stale); NaN or
// out-of-DBC-range values are rejected and counted; a frame shorter than the signals need is a bad frame.
// bind() is load-time (allocates); on_frame() and signals_at() are real-time safe.
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "dbc.hpp"
#include "records.hpp"
#include "samples.hpp"

namespace torqued {

/// Quantities of EngineSignals (estimators/core/samples.hpp). Config names in quantity_name().
enum class Quantity : std::uint8_t {
  kMap = 0,
  kMaf,
  kIntakeTemp,
  kOilTemp,
  kThrottle,
  kLambda,
  kSparkAdvance,
  kFuelMass,
  kFuelCutoff,
  kLoadTorque,
  kEmTorque,    ///< electric machine torque (hybrid input, estimators/core/e_machine.hpp)
  kEmSoleLoad,  ///< flag: the machine is the only load on the crank (estimators/core/load_reference.hpp)
  kNeutral,     ///< flag: clutch open / gearbox in neutral (estimators/core/load_reference.hpp)
  kCount
};
inline constexpr int kQuantityCount = static_cast<int>(Quantity::kCount);

/// "map", "maf", "intake_temp", "oil_temp", "throttle", "lambda", "spark_advance", "fuel_mass",
/// "fuel_cutoff", "load_torque", "em_torque", "em_sole_load", "neutral" (the config keys under can.signals).
[[nodiscard]] const char* quantity_name(Quantity q) noexcept;
[[nodiscard]] bool quantity_from_name(std::string_view name, Quantity& out) noexcept;

/// Latest state of one quantity.
struct SignalValue {
  double value = 0.0;          ///< SI (Pa, kg/s, K, ...) as in EngineSignals
  std::int64_t t_ns = 0;       ///< source time of the frame it came from (ns)
  bool seen = false;           ///< at least one accepted value
  std::uint64_t updates = 0;   ///< accepted values
  std::uint64_t rejected = 0;  ///< NaN / out of range
};

struct SignalStoreStats {
  std::uint64_t frames = 0;           ///< frames offered
  std::uint64_t frames_used = 0;      ///< frames that carried at least one bound signal
  std::uint64_t bad_frames = 0;       ///< bound message with a payload too short (wrong DLC)
  std::uint64_t rejected_values = 0;  ///< NaN / out-of-range values
};

class SignalStore {
 public:
  /// `db` must outlive the store and not be copied away (bindings point into its messages; moving is fine).
  explicit SignalStore(const DbcDatabase& db);

  /// Map quantity `q` to DBC `message`.`signal` with time-out (ns). The signal's unit is converted to the SI
  /// unit of the quantity (kPa/Pa/bar/hPa, g/s/kg/s/kg/h, degC/°C/C/K, mg/g/kg, %, -, deg, Nm, ...). Returns
  /// false with `error` set when the message/signal is unknown or the unit is not convertible. Load-time
  /// only.
  bool bind(Quantity q, std::string_view message, std::string_view signal, std::int64_t timeout_ns,
            std::string* error);

  /// Change the time-out of an already bound quantity (SIGHUP reload). Real-time safe; ignored if not bound
  /// or <= 0.
  void set_timeout(Quantity q, std::int64_t timeout_ns) noexcept {
    Binding& b = bindings_[static_cast<std::size_t>(q)];
    if (b.sig != nullptr && timeout_ns > 0) b.timeout_ns = timeout_ns;
    cache_ok_ = false;
  }

  /// Decode every bound signal carried by this frame. Returns true if any value was accepted. Real-time safe.
  bool on_frame(const CanFrame& frame) noexcept;

  [[nodiscard]] const SignalValue& value(Quantity q) const noexcept {
    return values_[static_cast<std::size_t>(q)];
  }
  [[nodiscard]] bool bound(Quantity q) const noexcept {
    return bindings_[static_cast<std::size_t>(q)].sig != nullptr;
  }
  /// Valid at `now_ns`: bound, seen, and now_ns - t_ns <= time-out (a value from the future also counts).
  [[nodiscard]] bool valid_at(Quantity q,
                              std::int64_t now_ns) const noexcept {  // inline: per tooth x quantity
    const auto i = static_cast<std::size_t>(q);
    if (i >= bindings_.size() || bindings_[i].sig == nullptr || !values_[i].seen) return false;
    return now_ns - values_[i].t_ns <= bindings_[i].timeout_ns;
  }
  /// Age in seconds at now_ns (+inf if never seen).
  [[nodiscard]] double age_s(Quantity q, std::int64_t now_ns) const noexcept;
  /// Snapshot for the estimators at `now_ns` (validity = valid_at). Real-time safe. Cached: the same snapshot
  /// is returned while no time-out changed and now_ns stays in [the time it was built, the first time-out of
  /// a valid quantity) (per tooth and time step, frames are 10x rarer); a frame's accepted values are written
  /// into it at the next call (only those quantities), a frame older than the value it replaces rebuilds it.
  /// Like on_frame(), not for concurrent use from several threads (each stage owns its store).
  [[nodiscard]] EngineSignals signals_at(std::int64_t now_ns) const noexcept;
  /// signals_at() without the copy: the cached snapshot (valid until the next call or frame), and in `stale`
  /// bit i set for each bound quantity i not valid at now_ns (built with the snapshot, not per call).
  /// Inline: the cached snapshot is returned per tooth and time step, frames are 10x rarer.
  [[nodiscard]] const EngineSignals& snapshot_at(std::int64_t now_ns, std::uint32_t& stale) const noexcept {
    if (cache_ok_ && changed_ == 0 && now_ns >= cache_from_ns_ && now_ns < cache_until_ns_) [[likely]] {
      stale = cache_stale_;
      return cache_;
    }
    return snapshot_update(now_ns, stale);
  }
  [[nodiscard]] const SignalStoreStats& stats() const noexcept { return stats_; }
  /// One line per bound signal that met frames too short for it, naming the first such frame:
  /// "CAN frame 0x100 (ENGINE_1) at t=12.345678 s: 4 data bytes, ENGINE_1.MAP needs 6 (DBC DLC 8); 17 such
  /// frames". Empty when none. Not real-time (allocates); call from the store's thread or after it stopped.
  [[nodiscard]] std::vector<std::string> describe_bad_frames() const;

 private:
  struct Binding {
    const DbcMessage* msg = nullptr;
    const DbcSignal* sig = nullptr;
    double scale = 1.0;  ///< SI = physical × scale + shift
    double shift = 0.0;
    std::int64_t timeout_ns = 0;
    // Prepared at bind() for on_frame() (per frame and bound signal): the message's id, the payload length
    // the signal needs, the accepted physical range and, for a plain integer signal within 8 bytes from
    // `first`, its word-at-a-time decode (word_decode(); else DbcSignal::decode).
    double lo = 0.0, hi = 0.0;  ///< DBC range widened by its tolerance; ±inf without a range
    std::uint64_t mask = 0;     ///< the raw value's bits
    std::uint64_t sign = 0;     ///< a signed signal's sign bit (0: unsigned)
    std::uint32_t id = 0;
    bool extended = false;
    bool word = false;       ///< word_decode() applies
    bool motorola = false;   ///< the 8 bytes read big-endian
    std::uint8_t need = 0;   ///< DbcSignal::bytes_needed()
    std::uint8_t first = 0;  ///< first of the 8 payload bytes read
    std::uint8_t right = 0;  ///< right shift of the word read
  };
  struct ShortFrames {  ///< frames of a bound message too short for its signal (per quantity)
    std::uint64_t count = 0;
    std::int64_t first_t_ns = 0;
    std::uint8_t first_len = 0;
  };
  /// Quantity i's stale bit, and its share of the snapshot's newest time and validity end (snapshot_at()).
  void account(std::size_t i, bool valid, std::uint32_t& stale, std::int64_t& newest,
               std::int64_t& until) const noexcept;
  /// Writes the quantities with a value accepted since the snapshot was built into it (at now_ns).
  void refresh_changed(std::int64_t now_ns) const noexcept;
  /// snapshot_at() when the cached snapshot does not hold as it is: refreshed or rebuilt.
  const EngineSignals& snapshot_update(std::int64_t now_ns, std::uint32_t& stale) const noexcept;

  /// Raw value of a `word` binding's signal, as DbcSignal::raw_value() gives it.
  [[nodiscard]] static double word_decode(const Binding& b, const std::uint8_t* data) noexcept;
  /// Fills b's prepared fields from its message and signal.
  static void prepare(Binding& b) noexcept;
  /// Rebuilds bound_ and groups_ from the bindings (bind()).
  void group_messages() noexcept;

  const DbcDatabase* db_;
  std::array<Binding, kQuantityCount> bindings_{};
  struct MessageGroup {  ///< the bound quantities of one message id: bound_[first, first + count)
    std::uint32_t id = 0;
    bool extended = false;
    std::uint8_t first = 0, count = 0;
  };
  std::array<std::uint8_t, kQuantityCount> bound_{};  ///< bound quantities by message id, index order within
  std::array<MessageGroup, kQuantityCount> groups_{};
  int group_count_ = 0;
  std::array<SignalValue, kQuantityCount> values_{};
  std::array<ShortFrames, kQuantityCount> short_{};
  SignalStoreStats stats_;
  mutable EngineSignals cache_{};  ///< signals_at() result valid for now in [cache_from_ns_, cache_until_ns_)
  mutable std::int64_t cache_from_ns_ = 0, cache_until_ns_ = 0;
  mutable std::uint32_t cache_stale_ = 0;  ///< bound and not valid, bit per quantity, of cache_
  mutable std::uint32_t changed_ =
      0;  ///< bit per quantity: a value accepted since cache_ was built or refreshed
  mutable bool cache_ok_ = false;
};

}  // namespace torqued
