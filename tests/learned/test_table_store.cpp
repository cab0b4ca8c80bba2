// tests/learned/test_table_store.cpp: the start-up table cache (learned/table_store.hpp). A table read back
// is the same bytes the computation wrote (so the estimators' output does not depend on the cache), the
// Kalman gains and load RLS tables built from the cache equal those computed, and a file that is corrupt,
// truncated, of another build or of other inputs is never used.
#include <gtest/gtest.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "chauvin_kalman.hpp"
#include "load_rls.hpp"
#include "table_store.hpp"

namespace torqued {
namespace {

namespace fs = std::filesystem;
constexpr std::uint64_t kBuild = 0x1234;  // a fixed binary id: the tests do not depend on a build id

struct TempDir {
  fs::path path = fs::temp_directory_path() / ("torqued_tables_" + std::to_string(::getpid()));
  TempDir() { fs::remove_all(path); }
  ~TempDir() { fs::remove_all(path); }
};

bool same_bytes(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

TEST(TableStore, StoredTableLoadsWithTheSameBytes) {
  TempDir d;
  TableStore st(d.path.string(), kBuild);
  const std::vector<double> t{0.0, -0.0, 1.0 / 3.0, -1e-300, 4.9e-324, 1e308, std::nan("7")};
  st.store("demo", 99, t);
  const auto back = st.load("demo", 99);
  ASSERT_TRUE(back.has_value());
  ASSERT_EQ(back->size(), t.size());
  for (std::size_t i = 0; i < t.size(); ++i) EXPECT_TRUE(same_bytes((*back)[i], t[i])) << i;
  EXPECT_FALSE(st.load("demo", 98).has_value());   // another key: another file, none there
  EXPECT_FALSE(st.load("other", 99).has_value());  // another kind
}

TEST(TableStore, CorruptTruncatedOrForeignFilesAreNotUsed) {
  TempDir d;
  TableStore st(d.path.string(), kBuild);
  const std::vector<double> t(100, 2.5);
  const std::string path = st.path_of("demo", 7);
  auto rewrite = [&](auto&& edit) {
    st.store("demo", 7, t);
    std::string bytes;
    {
      std::ifstream in(path, std::ios::binary);
      bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    edit(bytes);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  };
  rewrite([](std::string& b) { b[8 * 4 + 13] ^= 0x01; });  // one bit of the data
  EXPECT_FALSE(st.load("demo", 7).has_value());
  rewrite([](std::string& b) { b.resize(b.size() - 8); });  // the checksum cut off
  EXPECT_FALSE(st.load("demo", 7).has_value());
  rewrite([](std::string& b) { b[0] = 'X'; });  // not a table file
  EXPECT_FALSE(st.load("demo", 7).has_value());
  rewrite([](std::string& b) { b.assign(3, 'a'); });
  EXPECT_FALSE(st.load("demo", 7).has_value());
  (void)st.take_messages();  // the messages of the rewrites above are not this check's
  st.store("demo", 7, t);
  TableStore rebuilt(d.path.string(), kBuild + 1);  // the same inputs, another build of the daemon
  EXPECT_FALSE(rebuilt.load("demo", 7).has_value());
  const auto msgs = rebuilt.take_messages();
  ASSERT_EQ(msgs.size(), 1u);
  EXPECT_NE(msgs[0].find("another build"), std::string::npos) << msgs[0];
  EXPECT_TRUE(st.load("demo", 7).has_value());  // the original build still reads it
}

TEST(TableStore, TableDirectoryFollowsTheConfiguration) {
  EXPECT_EQ(table_dir_for("off", "/var/lib/torqued"), "");
  EXPECT_EQ(table_dir_for("/tmp/t", "/var/lib/torqued"), "/tmp/t");
  EXPECT_EQ(table_dir_for("", "/var/lib/torqued"), "/var/lib/torqued/tables");
}

TEST(TableStore, KalmanGainsFromTheCacheEqualTheComputedOnes) {
  TempDir d;
  const EngineGeometry eng;
  const WheelGeometry wheel;
  KalmanParams kp;
  kp.speed_bins = 6;  // a small schedule: the test stays fast
  const ChauvinKalman computed(eng, wheel, kp);
  TableStore st(d.path.string(), kBuild);
  const ScopedTableCache use(&st);
  const ChauvinKalman first(eng, wheel, kp);  // computes and stores
  EXPECT_EQ(st.hits(), 0);
  EXPECT_EQ(st.misses(), 1);
  const ChauvinKalman second(eng, wheel, kp);  // loads
  EXPECT_EQ(st.hits(), 1);
  for (int k = 0; k < computed.table().samples; k += 7)
    for (double w : {60.0, 157.0, 400.0, 790.0}) {
      const auto a = computed.periodic_gain(k, w), b = first.periodic_gain(k, w),
                 c = second.periodic_gain(k, w);
      for (int i = 0; i < ChauvinKalman::kStates; ++i) {
        EXPECT_TRUE(same_bytes(a(i), b(i)) && same_bytes(a(i), c(i))) << k << " " << w << " " << i;
      }
      const double va = computed.periodic_output_var(k, w), vb = first.periodic_output_var(k, w),
                   vc = second.periodic_output_var(k, w);
      EXPECT_TRUE(va > 0.0 && same_bytes(va, vb) && same_bytes(va, vc)) << k << " " << w;
    }
  kp.edge_noise_deg *= 1.0 + 1e-12;  // any input changed: another key, computed again
  const ChauvinKalman other(eng, wheel, kp);
  EXPECT_EQ(st.hits(), 1);
  EXPECT_EQ(st.misses(), 2);
}

/// A parameter of the gas-model gain set keys its cache: a Kalman built with `first` applied and one with
/// `second` applied miss twice (two keys); `second` again is read back. Returns the Kalman built with
/// `second` the first time, the one read back in `again`.
ChauvinKalman built_with_two_keys(TableStore& st, KalmanParams kp,
                                  const std::function<void(KalmanParams&)>& first,
                                  const std::function<void(KalmanParams&)>& second,
                                  std::optional<ChauvinKalman>& again) {
  const EngineGeometry eng;
  const WheelGeometry wheel;
  first(kp);
  const ChauvinKalman a(eng, wheel, kp);
  second(kp);
  ChauvinKalman b(eng, wheel, kp);
  EXPECT_EQ(st.hits(), 0);
  EXPECT_EQ(st.misses(), 2);
  again.emplace(eng, wheel, kp);
  EXPECT_EQ(st.hits(), 1);  // the same value again: read back
  return b;
}

/// A fresh table store in use as the cache, Kalman parameters of 6 speed bins, and the slot for the
/// read-back.
struct KalmanCacheBed {
  TempDir d;
  KalmanParams kp = [] {
    KalmanParams p;
    p.speed_bins = 6;
    return p;
  }();
  TableStore st{d.path.string(), kBuild};
  const ScopedTableCache use{&st};
  std::optional<ChauvinKalman> again;
};

// The model-miss sigma (kalman.model_torque_sd_nm) sets the gas-model gain set: a cache written with the old
// default (75 N m) must not serve the new one (60 N m).
TEST(TableStore, KalmanGainsAreCachedPerModelMissSigma) {
  KalmanCacheBed b;
  (void)built_with_two_keys(
      b.st, b.kp, [](KalmanParams& p) { p.model_torque_sd_nm = 75.0; },
      [](KalmanParams& p) { p.model_torque_sd_nm = 60.0; }, b.again);
  b.kp.model_torque_sd_nm = 60.0;
  b.kp.gas_model = false;  // without the gas model only the whole-torque set is built: its own key
  const ChauvinKalman no_model(EngineGeometry{}, WheelGeometry{}, b.kp);
  EXPECT_EQ(b.st.misses(), 3);
}

// The model-miss pole (kalman.model_delta) sets the gas-model gain set too: a cache written with one δ is not
// read for another, and the gains read back are the computed ones bit for bit.
TEST(TableStore, KalmanGainsAreCachedPerModelDelta) {
  KalmanCacheBed b;
  const ChauvinKalman second = built_with_two_keys(
      b.st, b.kp, [](KalmanParams& p) { p.model_delta = 3.0; }, [](KalmanParams& p) { p.model_delta = 12.0; },
      b.again);
  for (int k = 0; k < second.table().samples; k += 11) {
    const auto x = second.periodic_gain_of_set(ChauvinKalman::kModelMissSet, k, 157.0);
    const auto y = b.again->periodic_gain_of_set(ChauvinKalman::kModelMissSet, k, 157.0);
    for (int i = 0; i < ChauvinKalman::kStates; ++i) EXPECT_TRUE(same_bytes(x(i), y(i))) << k << " " << i;
  }
}

TEST(TableStore, LoadRlsTablesFromTheCacheEqualTheComputedOnes) {
  TempDir d;
  const EngineGeometry eng;
  const WheelGeometry wheel;
  const EnergiesParams ep;
  const LoadRls computed(eng, wheel, ep);
  TableStore st(d.path.string(), kBuild);
  const ScopedTableCache use(&st);
  const LoadRls first(eng, wheel, ep);
  const LoadRls second(eng, wheel, ep);
  EXPECT_EQ(st.misses(), 1);
  EXPECT_EQ(st.hits(), 1);
  std::array<double, kMaxCylinders> p3{};
  for (int q = 0; q < eng.cylinders; ++q) p3[static_cast<std::size_t>(q)] = 3e6 + 1e5 * q;
  for (int k = 0; k < 116; k += 5) {
    const double a = computed.gas_ripple_nm(k, 60e3, p3);
    EXPECT_TRUE(same_bytes(a, first.gas_ripple_nm(k, 60e3, p3)) &&
                same_bytes(a, second.gas_ripple_nm(k, 60e3, p3)))
        << k;
  }
  for (int w = 0; w < 4; ++w) {  // windows of the first firing position (every shift kept on a 60-2 wheel)
    const double a = computed.window_gas_work(w, 60e3, p3);
    EXPECT_TRUE(same_bytes(a, second.window_gas_work(w, 60e3, p3))) << w;
  }
  EXPECT_TRUE(same_bytes(computed.expansion_p3(400.0, 60e3, 20.0), second.expansion_p3(400.0, 60e3, 20.0)));
  EXPECT_TRUE(same_bytes(computed.motored_torque_nm(60e3), second.motored_torque_nm(60e3)));
}

}  // namespace
}  // namespace torqued
