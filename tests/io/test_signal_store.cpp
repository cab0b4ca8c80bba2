// Signal store: DBC decode -> SI values with source time; stale after the time-out; NaN / out-of-range
// rejected and counted; short frames counted as bad frames.
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace torqued
