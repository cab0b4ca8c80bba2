// Signal store: DBC decode -> SI values with source time; stale after the time-out; NaN / out-of-range
// rejected and counted; short frames counted as bad frames.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "alloc_counter.hpp"
#include "signal_store.hpp"

namespace torqued {
namespace {

constexpr const char* kDbc = R"(VERSION ""
BU_: ECU DYNO
BO_ 256 ENGINE_1: 8 ECU
 SG_ EngineSpeed : 0|16@1+ (0.25,0) [0|16383.75] "rpm" Vector__XXX
 SG_ MAP : 16|16@1+ (0.01,0) [0|300] "kPa" Vector__XXX
 SG_ IntakeAirTemp : 32|8@1- (1,0) [-40|125] "degC" Vector__XXX
 SG_ Throttle : 40|8@1+ (0.5,0) [0|100] "%" Vector__XXX
BO_ 257 ENGINE_2: 8 ECU
 SG_ MAF : 7|16@0+ (0.01,0) [0|655.35] "g/s" Vector__XXX
 SG_ FuelMass : 23|16@0+ (0.001,0) [0|65.535] "mg" Vector__XXX
 SG_ FuelCutoff : 40|1@1+ (1,0) [0|1] "" Vector__XXX
BO_ 512 DYNO_1: 4 DYNO
 SG_ LoadTorque : 0|16@1- (0.1,0) [-3000|3000] "N m" Vector__XXX
)";

class SignalStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto r = DbcDatabase::parse_string(kDbc, "t.dbc");
    ASSERT_TRUE(r.db.has_value()) << r.errors.front();
    db_ = std::move(*r.db);
    store_ = std::make_unique<SignalStore>(db_);
    std::string err;
    ASSERT_TRUE(store_->bind(Quantity::kMap, "ENGINE_1", "MAP", 50'000'000, &err)) << err;
    ASSERT_TRUE(store_->bind(Quantity::kIntakeTemp, "ENGINE_1", "IntakeAirTemp", 50'000'000, &err)) << err;
    ASSERT_TRUE(store_->bind(Quantity::kMaf, "ENGINE_2", "MAF", 50'000'000, &err)) << err;
    ASSERT_TRUE(store_->bind(Quantity::kFuelMass, "ENGINE_2", "FuelMass", 50'000'000, &err)) << err;
    ASSERT_TRUE(store_->bind(Quantity::kFuelCutoff, "ENGINE_2", "FuelCutoff", 50'000'000, &err)) << err;
    ASSERT_TRUE(store_->bind(Quantity::kLoadTorque, "DYNO_1", "LoadTorque", 50'000'000, &err)) << err;
  }
  static CanFrame frame(std::uint32_t id, std::int64_t t, std::initializer_list<std::uint8_t> bytes) {
    CanFrame f;
    f.id = id;
    f.t_ns = t;
    f.len = static_cast<std::uint8_t>(bytes.size());
    std::size_t i = 0;
    for (auto b : bytes) f.data[i++] = b;
    return f;
  }
  DbcDatabase db_;
  std::unique_ptr<SignalStore> store_;
};

TEST_F(SignalStoreTest, DecodesToSiWithSourceTime) {
  // MAP 101.3 kPa, IAT 30 degC
  EXPECT_TRUE(store_->on_frame(frame(0x100, 1'000'000, {0, 0, 0x92, 0x27, 30, 0, 0, 0})));
  // MAF 12.34 g/s, fuel 20.5 mg, cut-off 1
  EXPECT_TRUE(store_->on_frame(frame(0x101, 2'000'000, {0x04, 0xD2, 0x50, 0x14, 0, 0x01, 0, 0})));
  EXPECT_TRUE(store_->on_frame(frame(0x200, 3'000'000, {0x9C, 0xFF, 0, 0})));
  const EngineSignals s = store_->signals_at(10'000'000);
  EXPECT_TRUE(s.map_valid);
  EXPECT_NEAR(s.map_pa, 101300.0, 1e-6);
  EXPECT_NEAR(s.intake_temp_k, 303.15, 1e-9);
  EXPECT_NEAR(s.maf_kg_s, 0.01234, 1e-12);
  EXPECT_NEAR(s.fuel_mass_kg, 20.5e-6, 1e-15);
  EXPECT_TRUE(s.fuel_cutoff && s.fuel_cutoff_valid);
  EXPECT_NEAR(s.load_torque_nm, -10.0, 1e-12);
  EXPECT_FALSE(s.oil_temp_valid);  // not bound
  EXPECT_FALSE(s.throttle_valid);
  EXPECT_EQ(s.t_ns, 3'000'000);
  EXPECT_EQ(store_->value(Quantity::kMap).t_ns, 1'000'000);
  EXPECT_NEAR(store_->age_s(Quantity::kMap, 11'000'000), 0.010, 1e-12);
}

TEST_F(SignalStoreTest, StaleAfterTimeout) {
  store_->on_frame(frame(0x100, 0, {0, 0, 0x92, 0x27, 30, 0, 0, 0}));
  EXPECT_TRUE(store_->valid_at(Quantity::kMap, 50'000'000));
  EXPECT_FALSE(store_->valid_at(Quantity::kMap, 50'000'001));
  EXPECT_FALSE(store_->signals_at(60'000'000).map_valid);
  EXPECT_FALSE(store_->valid_at(Quantity::kMaf, 0));  // never seen
}

TEST_F(SignalStoreTest, OutOfRangeRejectedAndShortFrameCounted) {
  store_->on_frame(frame(0x100, 0, {0, 0, 0x92, 0x27, 30, 0, 0, 0}));
  // MAP 400 kPa > DBC max 300: rejected, old value kept
  store_->on_frame(frame(0x100, 1'000'000, {0, 0, 0x40, 0x9C, 30, 0, 0, 0}));
  EXPECT_EQ(store_->stats().rejected_values, 1u);
  EXPECT_EQ(store_->value(Quantity::kMap).rejected, 1u);
  EXPECT_NEAR(store_->value(Quantity::kMap).value, 101300.0, 1e-6);
  EXPECT_EQ(store_->value(Quantity::kMap).t_ns, 0);
  // DLC 3: MAP (bytes 2-3) and IAT (byte 4) missing
  EXPECT_FALSE(store_->on_frame(frame(0x100, 2'000'000, {0, 0, 0x92})));
  EXPECT_EQ(store_->stats().bad_frames, 1u);
  // Unrelated id: not used, not bad
  store_->on_frame(frame(0x333, 3'000'000, {1}));
  EXPECT_EQ(store_->stats().frames, 4u);
  EXPECT_EQ(store_->stats().frames_used, 3u);
}

TEST_F(SignalStoreTest, AFrameReachesTheQuantitiesOfItsMessageOnly) {
  // GIVEN quantities bound to three messages, interleaved in quantity order (MAP, MAF, IAT, fuel, ...)
  // WHEN an ENGINE_2 frame arrives, then an extended frame with ENGINE_1's id, then the intake temperature is
  // bound again (a reload) and an ENGINE_1 frame arrives
  EXPECT_TRUE(store_->on_frame(frame(0x101, 1'000'000, {0x04, 0xD2, 0x50, 0x14, 0, 0x01, 0, 0})));
  // THEN only ENGINE_2's quantities changed
  EXPECT_EQ(store_->value(Quantity::kMaf).updates, 1u);
  EXPECT_EQ(store_->value(Quantity::kFuelMass).updates, 1u);
  EXPECT_EQ(store_->value(Quantity::kFuelCutoff).updates, 1u);
  EXPECT_EQ(store_->value(Quantity::kMap).updates, 0u);
  EXPECT_EQ(store_->value(Quantity::kIntakeTemp).updates, 0u);
  EXPECT_EQ(store_->value(Quantity::kLoadTorque).updates, 0u);
  // an extended id equal to a standard one is another message
  CanFrame ext = frame(0x100, 2'000'000, {0, 0, 0x92, 0x27, 30, 0, 0, 0});
  ext.extended = true;
  EXPECT_FALSE(store_->on_frame(ext));
  EXPECT_EQ(store_->value(Quantity::kMap).updates, 0u);
  EXPECT_EQ(store_->stats().frames_used, 1u);
  std::string err;
  ASSERT_TRUE(store_->bind(Quantity::kIntakeTemp, "ENGINE_1", "IntakeAirTemp", 50'000'000, &err)) << err;
  EXPECT_TRUE(store_->on_frame(frame(0x100, 3'000'000, {0, 0, 0x92, 0x27, 30, 50, 0, 0})));
  // (each quantity once: the rebinding did not list it twice)
  EXPECT_EQ(store_->value(Quantity::kMap).updates, 1u);
  EXPECT_EQ(store_->value(Quantity::kIntakeTemp).updates, 1u);
  EXPECT_EQ(store_->value(Quantity::kMaf).updates, 1u);
}

TEST_F(SignalStoreTest, BindErrorsAreExplicit) {
  std::string err;
  EXPECT_FALSE(store_->bind(Quantity::kOilTemp, "ENGINE_3", "OilTemp", 1, &err));
  EXPECT_NE(err.find("no message 'ENGINE_3'"), std::string::npos) << err;
  EXPECT_FALSE(store_->bind(Quantity::kOilTemp, "ENGINE_1", "Oil", 1, &err));
  EXPECT_NE(err.find("has: EngineSpeed, MAP"), std::string::npos) << err;
  EXPECT_FALSE(store_->bind(Quantity::kMap, "ENGINE_1", "EngineSpeed", 1, &err));  // rpm is not a pressure
  EXPECT_NE(err.find("unit 'rpm'"), std::string::npos) << err;
  Quantity q{};
  EXPECT_TRUE(quantity_from_name("spark_advance", q));
  EXPECT_EQ(q, Quantity::kSparkAdvance);
  EXPECT_FALSE(quantity_from_name("boost", q));
}

TEST_F(SignalStoreTest, RealTimePathDoesNotAllocate) {
  const CanFrame f = frame(0x100, 0, {0, 0, 0x92, 0x27, 30, 0, 0, 0});
  const test::AllocationScope scope;
  double sum = 0;
  for (int i = 0; i < 1000; ++i) {
    store_->on_frame(f);
    sum += store_->signals_at(i).map_pa;
  }
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_GT(sum, 0);
}

// signals_at() caches its snapshot between frames: it must equal the snapshot rebuilt from value()/valid_at()
// for any query order (time going back and forth, as the angle and time stages interleave), across
// time-outs, accepted and rejected frames and a time-out change.
TEST_F(SignalStoreTest, CachedSnapshotEqualsFreshOneAtAnyTime) {
  std::mt19937_64 rng(5);
  auto expect_fresh = [&](std::int64_t now) {
    const EngineSignals s = store_->signals_at(now);
    std::int64_t newest = 0;
    auto check = [&](Quantity q, double value, bool valid, double dflt) {
      const SignalValue& v = store_->value(q);
      ASSERT_EQ(valid, store_->valid_at(q, now)) << quantity_name(q) << " at " << now;
      ASSERT_EQ(value, v.seen ? v.value : dflt) << quantity_name(q) << " at " << now;
      if (valid && v.t_ns > newest) newest = v.t_ns;
    };
    check(Quantity::kMap, s.map_pa, s.map_valid, 0.0);
    check(Quantity::kMaf, s.maf_kg_s, s.maf_valid, 0.0);
    check(Quantity::kIntakeTemp, s.intake_temp_k, s.intake_temp_valid, 0.0);
    check(Quantity::kFuelMass, s.fuel_mass_kg, s.fuel_mass_valid, 0.0);
    check(Quantity::kFuelCutoff, s.fuel_cutoff ? 1.0 : 0.0, s.fuel_cutoff_valid, 0.0);
    check(Quantity::kLoadTorque, s.load_torque_nm, s.load_torque_valid, 0.0);
    ASSERT_EQ(s.t_ns, newest) << "at " << now;
  };
  // Exactly at the time-out boundary, with the snapshot built before it.
  (void)store_->on_frame(frame(0x100, 1'000'000'000, {0, 0, 0x92, 0x27, 30, 0, 0, 0}));
  expect_fresh(1'000'000'000);
  EXPECT_TRUE(store_->signals_at(1'050'000'000).map_valid);
  EXPECT_FALSE(store_->signals_at(1'050'000'001).map_valid);
  expect_fresh(1'000'000'000);
  expect_fresh(1'050'000'001);
  std::int64_t t = 1'100'000'000;
  int hits = 0;
  for (int i = 0; i < 20000; ++i) {
    t += static_cast<std::int64_t>(rng() % 2'000'000);
    const unsigned what = static_cast<unsigned>(rng() % 100);
    if (what < 8) {  // frames: engine_1, engine_2 (sometimes out of range), dyno; sometimes a gap (stale)
      const auto b = static_cast<std::uint8_t>(rng());
      if (what < 3)
        (void)store_->on_frame(frame(0x100, t, {0, 0, b, 0x27, static_cast<std::uint8_t>(b % 100), 0, 0, 0}));
      else if (what < 6)
        (void)store_->on_frame(
            frame(0x101, t, {b, 0xD2, 0x50, 0x14, 0, static_cast<std::uint8_t>(b & 1), 0, 0}));
      else
        (void)store_->on_frame(
            frame(0x200, t, {b, static_cast<std::uint8_t>(rng() % 2 ? 0x7F : 0x01), 0, 0}));
    } else if (what == 8) {
      t += 80'000'000;  // everything times out
    } else if (what == 9) {
      store_->set_timeout(Quantity::kMap, 10'000'000 + static_cast<std::int64_t>(rng() % 90'000'000));
    }
    expect_fresh(t);
    expect_fresh(t - static_cast<std::int64_t>(rng() % 60'000'000));  // the other stage, slightly behind
    expect_fresh(t + static_cast<std::int64_t>(rng() % 60'000'000));  // a value from the future counts
    if (HasFatalFailure()) return;
    ++hits;
  }
  EXPECT_EQ(hits, 20000);
}

// A frame's accepted values are written into the cached snapshot at the next call (only the quantities it
// carried); a frame older than the value it replaces (out of order) rebuilds it. Either way every quantity's
// value, validity and stale bit and the newest time must be what a snapshot built from scratch gives.
TEST_F(SignalStoreTest, SnapshotFollowsEachFrameAlsoOutOfOrder) {
  // GIVEN frames of the three messages at jittered times, some older than the previous one of their message,
  // a snapshot taken between most of them (the stage's tooth) and sometimes several frames in between
  std::mt19937_64 rng(23);
  std::int64_t t = 2'000'000'000;
  int checked = 0;
  for (int i = 0; i < 20000; ++i) {
    t += static_cast<std::int64_t>(rng() % 1'500'000);
    const std::int64_t ft = t - static_cast<std::int64_t>(rng() % 4 == 0 ? rng() % 30'000'000 : 0);
    const auto b = static_cast<std::uint8_t>(rng());
    const unsigned what = static_cast<unsigned>(rng() % 100);
    if (what < 30)
      (void)store_->on_frame(frame(0x100, ft, {0, 0, b, 0x27, static_cast<std::uint8_t>(b % 100), 0, 0, 0}));
    else if (what < 60)
      (void)store_->on_frame(
          frame(0x101, ft, {b, 0xD2, 0x50, 0x14, 0, static_cast<std::uint8_t>(b & 1), 0, 0}));
    else if (what < 75)
      (void)store_->on_frame(frame(0x200, ft, {b, static_cast<std::uint8_t>(rng() % 2 ? 0x7F : 0x01), 0, 0}));
    else if (what == 75)
      t += 70'000'000;             // a gap: everything times out
    if (rng() % 4 == 0) continue;  // another frame before the next snapshot
    // WHEN the stage takes the snapshot now (rarely slightly behind: the other stage's time)
    const std::int64_t now = rng() % 16 == 0 ? t - static_cast<std::int64_t>(rng() % 20'000'000) : t;
    std::uint32_t stale = 0;
    const EngineSignals& s = store_->snapshot_at(now, stale);
    // THEN it equals the values and validity the store holds at now, the newest valid time and the stale bits
    std::int64_t newest = 0;
    std::uint32_t want_stale = 0;
    for (int q = 0; q < kQuantityCount; ++q) {
      const auto quantity = static_cast<Quantity>(q);
      const SignalValue& v = store_->value(quantity);
      const bool valid = store_->valid_at(quantity, now);
      if (valid && v.t_ns > newest) newest = v.t_ns;
      if (store_->bound(quantity) && !valid) want_stale |= 1u << q;
    }
    auto value_of = [&](Quantity q) { return store_->value(q).seen ? store_->value(q).value : 0.0; };
    ASSERT_EQ(s.map_pa, value_of(Quantity::kMap)) << "at " << now;
    ASSERT_EQ(s.map_valid, store_->valid_at(Quantity::kMap, now)) << "at " << now;
    ASSERT_EQ(s.intake_temp_k, value_of(Quantity::kIntakeTemp)) << "at " << now;
    ASSERT_EQ(s.maf_kg_s, value_of(Quantity::kMaf)) << "at " << now;
    ASSERT_EQ(s.maf_valid, store_->valid_at(Quantity::kMaf, now)) << "at " << now;
    ASSERT_EQ(s.fuel_mass_kg, value_of(Quantity::kFuelMass)) << "at " << now;
    ASSERT_EQ(s.fuel_cutoff, value_of(Quantity::kFuelCutoff) > 0.5) << "at " << now;
    ASSERT_EQ(s.load_torque_nm, value_of(Quantity::kLoadTorque)) << "at " << now;
    ASSERT_EQ(s.load_torque_valid, store_->valid_at(Quantity::kLoadTorque, now)) << "at " << now;
    ASSERT_EQ(s.t_ns, newest) << "at " << now;
    ASSERT_EQ(stale, want_stale) << "at " << now;
    ++checked;
  }
  EXPECT_GT(checked, 12000);
}

// on_frame() decodes a plain integer signal within 8 bytes a word at a time (bind() prepares it): the value
// must be DbcSignal::decode()'s, bit for bit, for every layout (Intel/Motorola, signed, 1-64 bits, any start,
// classic and 64-byte payloads, factor and offset), and the signals it does not take (64 bits, floats,
// multiplexed) keep the general decode. A unit-less ratio (lambda) is stored as decoded (scale 1, shift 0).
TEST(SignalStoreDecode, WordAtATimeEqualsTheDbcDecodeForAnyLayout) {
  std::mt19937_64 rng(31);
  int compared = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    // GIVEN a message with one signal of a random layout
    const int dlc = rng() % 5 == 0 ? 64 : 8;
    const int length = 1 + static_cast<int>(rng() % 64);
    const int start = static_cast<int>(rng() % static_cast<unsigned>(8 * dlc));
    const bool intel = rng() % 2 == 0, is_signed = rng() % 2 == 0;
    const char* factor = rng() % 2 == 0 ? "1" : "0.125";
    const char* offset = rng() % 2 == 0 ? "0" : "-40.5";
    const std::string kind = rng() % 8 == 0 ? "mux" : rng() % 8 == 0 ? "float" : "plain";
    std::string text = "VERSION \"\"\nBU_: ECU\nBO_ 291 M: " + std::to_string(dlc) + " ECU\n";
    if (kind == "mux") text += " SG_ Sel M : 0|2@1+ (1,0) [0|0] \"\" Vector__XXX\n";
    text += " SG_ S" + std::string(kind == "mux" ? " m1" : "") + " : " + std::to_string(start) + "|" +
            std::to_string(length) + "@" + (intel ? "1" : "0") + (is_signed ? "-" : "+") + " (" + factor +
            "," + offset + ") [0|0] \"\" Vector__XXX\n";
    if (kind == "float" && (length == 32 || length == 64))
      text += "SIG_VALTYPE_ 291 S : " + std::string(length == 32 ? "1" : "2") + ";\n";
    auto r = DbcDatabase::parse_string(text, "t.dbc");
    if (!r.db.has_value() || r.db->find("M") == nullptr || r.db->find("M")->find("S") == nullptr) continue;
    const DbcDatabase db = std::move(*r.db);
    const DbcSignal& sig = *db.find("M")->find("S");
    SignalStore store(db);
    std::string err;
    ASSERT_TRUE(store.bind(Quantity::kLambda, "M", "S", 1'000'000'000, &err)) << err;
    // WHEN random payloads of the DLC arrive
    for (int f = 0; f < 8; ++f) {
      CanFrame frame;
      frame.id = 291;
      frame.len = static_cast<std::uint8_t>(dlc);
      frame.t_ns = 1000 * (f + 1);
      for (auto& byte : frame.data) byte = static_cast<std::uint8_t>(rng());
      const std::uint64_t updates = store.value(Quantity::kLambda).updates;
      const bool accepted = store.on_frame(frame);
      // THEN the stored value is the DBC decode (when the payload holds the signal, the multiplexor selects
      // it and the value is finite)
      const bool present =
          frame.len >= sig.bytes_needed() && db.find("M")->signal_present(sig, frame.data.data(), frame.len);
      const double want = sig.decode(frame.data.data(), frame.len);
      ASSERT_EQ(accepted, present && std::isfinite(want)) << text;
      if (!accepted) continue;
      ASSERT_EQ(store.value(Quantity::kLambda).updates, updates + 1);
      ASSERT_EQ(store.value(Quantity::kLambda).value, want) << text;
      ++compared;
    }
  }
  EXPECT_GT(compared, 10000);
}

TEST_F(SignalStoreTest, SnapshotStaleMaskIsBoundAndNotValidAtAnyTime) {
  // GIVEN six bound quantities (seven unbound), frames at random times with gaps that time everything out
  std::mt19937_64 rng(11);
  std::int64_t t = 1'000'000'000;
  int checked = 0;
  for (int i = 0; i < 5000; ++i) {
    t += static_cast<std::int64_t>(rng() % 3'000'000);
    const unsigned what = static_cast<unsigned>(rng() % 100);
    const auto b = static_cast<std::uint8_t>(rng());
    if (what < 4)
      (void)store_->on_frame(frame(0x100, t, {0, 0, b, 0x27, 30, 0, 0, 0}));
    else if (what < 7)
      (void)store_->on_frame(frame(0x101, t, {b, 0xD2, 0x50, 0x14, 0, 0, 0, 0}));
    else if (what < 9)
      (void)store_->on_frame(frame(0x200, t, {b, 0x01, 0, 0}));
    else if (what == 9)
      t += 80'000'000;
    // WHEN the chain takes the cached snapshot with its stale mask, now and slightly behind or ahead
    for (const std::int64_t now : {t, t - static_cast<std::int64_t>(rng() % 60'000'000),
                                   t + static_cast<std::int64_t>(rng() % 60'000'000)}) {
      std::uint32_t stale = 0xFFFFFFFFu;
      const EngineSignals& s = store_->snapshot_at(now, stale);
      // THEN bit i is set exactly for a bound quantity i not valid at now (the per-quantity test the chain
      // did per tooth), and the snapshot is signals_at()'s
      std::uint32_t want = 0;
      for (int q = 0; q < kQuantityCount; ++q)
        if (store_->bound(static_cast<Quantity>(q)) && !store_->valid_at(static_cast<Quantity>(q), now))
          want |= 1u << q;
      ASSERT_EQ(stale, want) << "at " << now;
      const EngineSignals fresh = store_->signals_at(now);
      ASSERT_EQ(s.map_valid, fresh.map_valid);
      ASSERT_EQ(s.load_torque_valid, fresh.load_torque_valid);
      ASSERT_EQ(s.t_ns, fresh.t_ns);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 15000);
}

}  // namespace
}  // namespace torqued
