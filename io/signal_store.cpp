#include "signal_store.hpp"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

namespace torqued {
namespace {

constexpr const char* kNames[kQuantityCount] = {
    "map",       "maf",         "intake_temp", "oil_temp",  "throttle",     "lambda", "spark_advance",
    "fuel_mass", "fuel_cutoff", "load_torque", "em_torque", "em_sole_load", "neutral"};

std::string norm_unit(std::string_view u) {
  std::string s;
  for (const char c : u) {
    if (c == ' ' || c == '\t' || c == '_') continue;
    s += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  // UTF-8 / Latin-1 degree signs and the "N·m" middle dot
  for (const std::string deg : {"\xc2\xb0", "\xb0"}) {
    for (std::size_t p; (p = s.find(deg)) != std::string::npos;) s.replace(p, deg.size(), "deg");
  }
  for (const std::string dot : {"\xc2\xb7", "\xb7", "."}) {
    for (std::size_t p; (p = s.find(dot)) != std::string::npos;) s.erase(p, dot.size());
  }
  return s;
}

struct Conv {
  const char* unit;
  double scale, shift;
};

/// Physical (DBC unit) -> the SI unit of each quantity in EngineSignals.
bool conversion(Quantity q, const std::string& u, double& scale, double& shift) {
  static const Conv kPressure[] = {{"kpa", 1e3, 0},  {"pa", 1, 0},    {"hpa", 100, 0},
                                   {"mbar", 100, 0}, {"bar", 1e5, 0}, {"psi", 6894.757293168, 0}};
  static const Conv kMassFlow[] = {
      {"g/s", 1e-3, 0}, {"kg/s", 1, 0}, {"kg/h", 1.0 / 3600.0, 0}, {"g/min", 1e-3 / 60, 0}};
  static const Conv kTempK[] = {{"degc", 1, 273.15}, {"c", 1, 273.15}, {"degreesc", 1, 273.15}, {"k", 1, 0}};
  static const Conv kTempC[] = {{"degc", 1, 0}, {"c", 1, 0}, {"degreesc", 1, 0}, {"k", 1, -273.15}};
  static const Conv kPercent[] = {{"%", 1, 0}, {"", 1, 0}, {"pct", 1, 0}};
  static const Conv kRatio[] = {{"", 1, 0}, {"-", 1, 0}, {"lambda", 1, 0}, {"1", 1, 0}};
  static const Conv kAngle[] = {
      {"deg", 1, 0}, {"degca", 1, 0}, {"degbtdc", 1, 0}, {"degcrk", 1, 0}, {"", 1, 0}};
  static const Conv kMass[] = {
      {"mg", 1e-6, 0}, {"g", 1e-3, 0}, {"kg", 1, 0}, {"ug", 1e-9, 0}, {"\xc2\xb5g", 1e-9, 0}};
  static const Conv kFlag[] = {{"", 1, 0}, {"-", 1, 0}, {"bool", 1, 0}, {"1", 1, 0}};
  static const Conv kTorque[] = {{"nm", 1, 0}, {"knm", 1e3, 0}};
  auto find = [&](const auto& table) {
    for (const Conv& c : table) {
      if (u == c.unit) {
        scale = c.scale;
        shift = c.shift;
        return true;
      }
    }
    return false;
  };
  switch (q) {
    case Quantity::kMap:
      return find(kPressure);
    case Quantity::kMaf:
      return find(kMassFlow);
    case Quantity::kIntakeTemp:
      return find(kTempK);
    case Quantity::kOilTemp:
      return find(kTempC);
    case Quantity::kThrottle:
      return find(kPercent);
    case Quantity::kLambda:
      return find(kRatio);
    case Quantity::kSparkAdvance:
      return find(kAngle);
    case Quantity::kFuelMass:
      return find(kMass);
    case Quantity::kFuelCutoff:
    case Quantity::kEmSoleLoad:
    case Quantity::kNeutral:
      return find(kFlag);
    case Quantity::kLoadTorque:
    case Quantity::kEmTorque:
      return find(kTorque);
    case Quantity::kCount:
      break;
  }
  return false;
}

}  // namespace

const char* quantity_name(Quantity q) noexcept {
  const int i = static_cast<int>(q);
  return i >= 0 && i < kQuantityCount ? kNames[i] : "unknown";
}

bool quantity_from_name(std::string_view name, Quantity& out) noexcept {
  for (int i = 0; i < kQuantityCount; ++i) {
    if (name == kNames[i]) {
      out = static_cast<Quantity>(i);
      return true;
    }
  }
  return false;
}

SignalStore::SignalStore(const DbcDatabase& db) : db_(&db) {}

bool SignalStore::bind(Quantity q, std::string_view message, std::string_view signal, std::int64_t timeout_ns,
                       std::string* error) {
  auto fail = [&](const std::string& what) {
    if (error != nullptr) *error = what;
    return false;
  };
  if (q == Quantity::kCount) return fail("unknown quantity");
  const DbcMessage* m = db_->find(message);
  if (m == nullptr)
    return fail(std::string("can.signals.") + quantity_name(q) + ": no message '" + std::string(message) +
                "' in the DBC");
  const DbcSignal* s = m->find(signal);
  if (s == nullptr) {
    std::string names;
    for (const auto& x : m->signals) names += (names.empty() ? "" : ", ") + x.name;
    return fail(std::string("can.signals.") + quantity_name(q) + ": message " + m->name + " has no signal '" +
                std::string(signal) + "' (has: " + names + ")");
  }
  if (timeout_ns <= 0) return fail(std::string("can.signals.") + quantity_name(q) + ": time-out must be > 0");
  Binding b;
  if (!conversion(q, norm_unit(s->unit), b.scale, b.shift)) {
    return fail(std::string("can.signals.") + quantity_name(q) + ": unit '" + s->unit + "' of " + m->name +
                "." + s->name + " cannot be converted to the quantity's unit");
  }
  b.msg = m;
  b.sig = s;
  b.timeout_ns = timeout_ns;
  prepare(b);
  bindings_[static_cast<std::size_t>(q)] = b;
  group_messages();
  values_[static_cast<std::size_t>(q)] = SignalValue{};
  cache_ok_ = false;
  return true;
}

void SignalStore::prepare(Binding& b) noexcept {
  const DbcSignal& s = *b.sig;
  b.id = b.msg->id;
  b.extended = b.msg->extended;
  b.need = static_cast<std::uint8_t>(std::min<std::size_t>(s.bytes_needed(), 255));
  // The tolerance on_frame() applied per frame: the same doubles, computed once.
  const double eps = 1e-9 * (std::abs(s.max) + std::abs(s.min)) + 1e-12;
  b.lo = s.has_range() ? s.min - eps : -std::numeric_limits<double>::infinity();
  b.hi = s.has_range() ? s.max + eps : std::numeric_limits<double>::infinity();
  // DbcSignal::raw_bits() gathers the `bytes` bytes the signal spans into one integer (Intel: the first
  // lowest; Motorola: the first highest), shifts and masks. Reading 8 bytes from the same first byte gives
  // that integer with more bytes above (Intel) or below (Motorola, then shifted by 8·(8 − bytes) more): the
  // same n bits after the shift and the mask. Multiplexed signals, IEEE floats, 64-bit signals, a span over
  // 8 bytes or past the 64-byte payload buffer keep the general decode.
  const int n = s.length, first = s.start_bit / 8, in_byte = s.start_bit % 8;
  const int bytes = s.little_endian ? (in_byte + n + 7) / 8 : (7 - in_byte + n + 7) / 8;
  b.word = s.value_type == DbcSignal::ValueType::kInteger && s.mux != DbcSignal::Mux::kMultiplexed &&
           n >= 1 && n <= 63 && bytes <= 8 && first + 8 <= static_cast<int>(sizeof(CanFrame::data));
  if (!b.word) return;
  b.motorola = !s.little_endian;
  b.first = static_cast<std::uint8_t>(first);
  b.right = static_cast<std::uint8_t>(s.little_endian ? in_byte : 57 + in_byte - n);
  b.mask = (std::uint64_t{1} << n) - 1u;
  b.sign = s.is_signed ? std::uint64_t{1} << (n - 1) : 0u;
}

double SignalStore::word_decode(const Binding& b, const std::uint8_t* data) noexcept {
  std::uint64_t w = 0;
  std::memcpy(&w, data + b.first, sizeof w);
  if ((std::endian::native == std::endian::big) != b.motorola) w = __builtin_bswap64(w);
  const std::uint64_t v = (w >> b.right) & b.mask;
  if (b.sign == 0) return static_cast<double>(v);
  return static_cast<double>(static_cast<std::int64_t>((v ^ b.sign) - b.sign));  // sign-extended
}

// The bound quantities grouped by message id (groups in order of first appearance, quantities in index order
// within a group): on_frame() finds the frame's group and visits only its quantities.
void SignalStore::group_messages() noexcept {
  group_count_ = 0;
  int n = 0;
  for (std::size_t i = 0; i < bindings_.size(); ++i) {
    const Binding& b = bindings_[i];
    if (b.sig == nullptr) continue;
    bool seen = false;
    for (int g = 0; g < group_count_; ++g)
      seen = seen || (groups_[static_cast<std::size_t>(g)].id == b.id &&
                      groups_[static_cast<std::size_t>(g)].extended == b.extended);
    if (seen) continue;
    MessageGroup& g = groups_[static_cast<std::size_t>(group_count_++)];
    g = MessageGroup{b.id, b.extended, static_cast<std::uint8_t>(n), 0};
    for (std::size_t j = i; j < bindings_.size(); ++j) {
      if (bindings_[j].sig == nullptr || bindings_[j].id != b.id || bindings_[j].extended != b.extended)
        continue;
      bound_[static_cast<std::size_t>(n++)] = static_cast<std::uint8_t>(j);
      ++g.count;
    }
  }
}

bool SignalStore::on_frame(const CanFrame& frame) noexcept {
  ++stats_.frames;
  const MessageGroup* group = nullptr;
  for (int g = 0; g < group_count_; ++g) {
    if (groups_[static_cast<std::size_t>(g)].id == frame.id &&
        groups_[static_cast<std::size_t>(g)].extended == frame.extended) {
      group = &groups_[static_cast<std::size_t>(g)];
      break;
    }
  }
  if (group == nullptr) return false;  // no bound signal in this message
  bool any = false, bad = false;
  for (int n = group->first; n < group->first + group->count; ++n) {
    const std::size_t i = bound_[static_cast<std::size_t>(n)];
    const Binding& b = bindings_[i];
    if (frame.len < b.need) {  // wrong DLC: the signal is not (fully) in this frame
      bad = true;
      ShortFrames& sf = short_[i];
      if (sf.count++ == 0) {
        sf.first_t_ns = frame.t_ns;
        sf.first_len = frame.len;
      }
      continue;
    }
    double phys = 0.0;
    if (b.word) {  // DbcSignal::decode()'s raw × factor + offset
      phys = word_decode(b, frame.data.data()) * b.sig->factor + b.sig->offset;
    } else {
      if (!b.msg->signal_present(*b.sig, frame.data.data(), frame.len)) continue;
      phys = b.sig->decode(frame.data.data(), frame.len);
    }
    SignalValue& v = values_[i];
    if (!std::isfinite(phys) || phys < b.lo || phys > b.hi) {
      ++v.rejected;
      ++stats_.rejected_values;
      continue;
    }
    // An older frame than the value it replaces can lower the snapshot's newest time: rebuild it whole.
    if (v.seen && frame.t_ns < v.t_ns) cache_ok_ = false;
    v.value = phys * b.scale + b.shift;
    v.t_ns = frame.t_ns;
    v.seen = true;
    ++v.updates;
    changed_ |= 1u << i;
    any = true;
  }
  ++stats_.frames_used;
  if (bad) ++stats_.bad_frames;
  return any;
}

std::vector<std::string> SignalStore::describe_bad_frames() const {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < bindings_.size(); ++i) {
    const ShortFrames& sf = short_[i];
    const Binding& b = bindings_[i];
    if (sf.count == 0 || b.sig == nullptr) continue;
    char buf[320];
    std::snprintf(
        buf, sizeof buf,
        "CAN frame 0x%X (%s) at t=%.6f s: %u data bytes, %s.%s needs %u (DBC DLC %u); %llu such frame%s",
        static_cast<unsigned>(b.msg->id), b.msg->name.c_str(), static_cast<double>(sf.first_t_ns) * 1e-9,
        static_cast<unsigned>(sf.first_len), b.msg->name.c_str(), b.sig->name.c_str(),
        static_cast<unsigned>(b.sig->bytes_needed()), static_cast<unsigned>(b.msg->dlc),
        static_cast<unsigned long long>(sf.count), sf.count == 1 ? "" : "s");
    out.emplace_back(buf);
  }
  return out;
}

double SignalStore::age_s(Quantity q, std::int64_t now_ns) const noexcept {
  const auto i = static_cast<std::size_t>(q);
  if (i >= values_.size() || !values_[i].seen) return std::numeric_limits<double>::infinity();
  return static_cast<double>(now_ns - values_[i].t_ns) * 1e-9;
}

EngineSignals SignalStore::signals_at(std::int64_t now_ns) const noexcept {
  std::uint32_t stale = 0;
  return snapshot_at(now_ns, stale);
}

namespace {
/// Quantity i's fields in the snapshot: its validity, and its value once one was accepted (else the field's
/// default); the flags are the value > 0.5 (fuel cut-off) or non-zero (the machine is the only load,
/// neutral).
void put(EngineSignals& s, std::size_t i, const SignalValue& v, bool valid) noexcept {
  const double x = v.value;
  switch (static_cast<Quantity>(i)) {
    case Quantity::kMap:
      s.map_valid = valid;
      if (v.seen) s.map_pa = x;
      break;
    case Quantity::kMaf:
      s.maf_valid = valid;
      if (v.seen) s.maf_kg_s = x;
      break;
    case Quantity::kIntakeTemp:
      s.intake_temp_valid = valid;
      if (v.seen) s.intake_temp_k = x;
      break;
    case Quantity::kOilTemp:
      s.oil_temp_valid = valid;
      if (v.seen) s.oil_temp_c = x;
      break;
    case Quantity::kThrottle:
      s.throttle_valid = valid;
      if (v.seen) s.throttle_pct = x;
      break;
    case Quantity::kLambda:
      s.lambda_valid = valid;
      if (v.seen) s.lambda = x;
      break;
    case Quantity::kSparkAdvance:
      s.spark_valid = valid;
      if (v.seen) s.spark_advance_deg = x;
      break;
    case Quantity::kFuelMass:
      s.fuel_mass_valid = valid;
      if (v.seen) s.fuel_mass_kg = x;
      break;
    case Quantity::kFuelCutoff:
      s.fuel_cutoff_valid = valid;
      s.fuel_cutoff = v.seen && x > 0.5;
      break;
    case Quantity::kLoadTorque:
      s.load_torque_valid = valid;
      if (v.seen) s.load_torque_nm = x;
      break;
    case Quantity::kEmTorque:
      s.em_torque_valid = valid;
      if (v.seen) s.em_torque_nm = x;
      break;
    case Quantity::kEmSoleLoad:
      s.em_sole_load_valid = valid;
      s.em_sole_load = v.seen && x != 0.0;  // non-zero: the machine is the only load
      break;
    case Quantity::kNeutral:
      s.neutral_valid = valid;
      s.neutral = v.seen && x != 0.0;
      break;
    case Quantity::kCount:
      break;
  }
}
}  // namespace

void SignalStore::account(std::size_t i, bool valid, std::uint32_t& stale, std::int64_t& newest,
                          std::int64_t& until) const noexcept {
  const SignalValue& v = values_[i];
  if (bindings_[i].sig != nullptr && !valid) stale |= 1u << i;
  if (valid && v.t_ns > newest) newest = v.t_ns;
  const std::int64_t to = bindings_[i].timeout_ns;  // valid while now - t <= time-out (no overflow below)
  if (valid && (v.t_ns < 0 || to < std::numeric_limits<std::int64_t>::max() - 1 - v.t_ns))
    until = std::min(until, v.t_ns + to + 1);
}

// The snapshot holds for every quantity not changed since it was built (now_ns is inside its window); a
// changed one's new time is not older than its previous one (on_frame() rebuilds otherwise), so the newest
// time is the larger of the two, and the window's end only moves earlier (the replaced value's end stays in
// the minimum: an end earlier than needed costs one rebuild, never a wrong snapshot). A changed quantity not
// valid at now_ns may be valid before it: the window starts at now_ns.
void SignalStore::refresh_changed(std::int64_t now_ns) const noexcept {
  std::uint32_t stale = cache_stale_ & ~changed_;
  std::int64_t newest = cache_.t_ns;
  for (std::uint32_t bits = changed_; bits != 0; bits &= bits - 1) {
    const auto i = static_cast<std::size_t>(__builtin_ctz(bits));
    const bool valid = valid_at(static_cast<Quantity>(i), now_ns);
    put(cache_, i, values_[i], valid);
    account(i, valid, stale, newest, cache_until_ns_);
  }
  cache_.t_ns = newest;
  cache_stale_ = stale;
  cache_from_ns_ = now_ns;
  changed_ = 0;
}

const EngineSignals& SignalStore::snapshot_update(std::int64_t now_ns,
                                                  std::uint32_t& stale_mask) const noexcept {
  // Validity only changes with a frame (on_frame), a time-out change, or when now passes t + time-out of a
  // valid quantity; an invalid one stays invalid for a later now. So the snapshot holds for a later now_ns
  // up to the first such time-out.
  if (cache_ok_ && now_ns >= cache_from_ns_ && now_ns < cache_until_ns_) {
    if (changed_ != 0) refresh_changed(now_ns);
    stale_mask = cache_stale_;
    return cache_;
  }
  EngineSignals s;
  std::uint32_t stale = 0;
  std::int64_t newest = 0;
  std::int64_t until = std::numeric_limits<std::int64_t>::max();
  for (std::size_t i = 0; i < values_.size(); ++i) {
    const bool valid = valid_at(static_cast<Quantity>(i), now_ns);
    put(s, i, values_[i], valid);
    account(i, valid, stale, newest, until);
  }
  s.t_ns = newest;
  cache_ = s;
  cache_stale_ = stale;
  cache_from_ns_ = now_ns;
  cache_until_ns_ = until;
  cache_ok_ = true;
  changed_ = 0;
  stale_mask = stale;
  return cache_;
}

}  // namespace torqued
