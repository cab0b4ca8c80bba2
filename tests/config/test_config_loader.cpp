// config/config_loader.cpp: every bad file in tests/config/bad is refused with the expected message
// (file:line:col, key, found, expected), good files load with the values they give, defaults equal Config{}.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "config_loader.hpp"
#include "config_schema.hpp"
#include "signal_store.hpp"

namespace torqued {
namespace {

const std::string kDir = std::string(TORQUED_SOURCE_DIR) + "/tests/config/";

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += x + "\n";
  return s;
}

struct BadCase {
  const char* file;
  const char* expected;  ///< substring of one error, with line:col
  std::size_t errors;    ///< total number of errors expected
};

// GIVEN a bad file WHEN it is loaded THEN it is refused, one error names file:line:col, key, found and
// expected.
const BadCase kBad[] = {
    {"negative_bore",
     "negative_bore.yaml:4:11: key 'engine.bore_m': found '-0.08', expected a finite number (m, range (0, "
     "1])",
     1},
    {"firing_order_not_permutation",
     "firing_order_not_permutation.yaml:5:17: key 'engine.firing_order': found '[1, 3, 3, 2]', expected a "
     "permutation of 1..4 (cylinder 3 appears twice)",
     1},
    {"firing_order_wrong_length",
     ":5:17: key 'engine.firing_order': found '[1, 3, 4, 2]', expected a permutation of 1..3 (4 entries for "
     "3 cylinders)",
     1},
    {"rod_too_short",
     "rod_too_short.yaml:5:10: key 'engine.rod_m': found '0.04', expected a rod longer than the crank radius "
     "stroke_m/2 = 0.043 m",
     1},
    {"missing_ge_teeth",
     "missing_ge_teeth.yaml:5:12: key 'wheel.missing': found '36', expected fewer missing teeth than teeth = "
     "36",
     1},
    {"unknown_key_typo",
     "unknown_key_typo.yaml:4:3: unknown key 'engine.boer_m' (did you mean 'engine.bore_m'?)", 1},
    {"unknown_section", "unknown_section.yaml:3:1: unknown key 'engin' (did you mean 'engine'?)", 1},
    {"key_in_wrong_section",
     "key_in_wrong_section.yaml:4:3: unknown key 'engine.teeth' (did you mean 'wheel.teeth'?)", 1},
    {"wrong_type",
     "wrong_type.yaml:4:14: key 'engine.cylinders': found 'four', expected an integer (range [1, 8])", 1},
    {"float_for_integer",
     "float_for_integer.yaml:4:14: key 'engine.cylinders': found '4.5', expected an integer", 1},
    {"invalid_syntax", "invalid_syntax.yaml:5:9: invalid YAML: end of sequence flow not found", 1},
    {"tab_indent", "tab_indent.yaml:4:8: invalid YAML:", 1},
    {"unknown_backend",
     "unknown_backend.yaml:4:14: key 'inputs.edges.backend': found 'serial', expected one of "
     "file|gpio|can_encoder",
     1},
    {"priority_150",
     "priority_150.yaml:6:15: key 'realtime.angle.priority': found '150', expected an integer (range [0, "
     "99])",
     1},
    {"fifo_priority_zero",
     "fifo_priority_zero.yaml:6:15: key 'realtime.time.priority': found '0', expected 1..99 with policy fifo",
     1},
    {"missing_input_file",
     "missing_input_file.yaml:5:11: key 'inputs.edges.path': found '../data/does_not_exist.csv' (= ", 1},
    {"nan_value",
     "nan_value.yaml:4:22: key 'engine.compression_ratio': found '.nan', expected a finite number (range (1, "
     "40])",
     1},
    {"infinite_value",
     "infinite_value.yaml:4:15: key 'engine.j_rot_kgm2': found '.inf', expected a finite number (kg m^2", 1},
    {"compression_ratio_le_1",
     "compression_ratio_le_1.yaml:4:22: key 'engine.compression_ratio': found '0.9', expected a finite "
     "number (range (1, 40])",
     1},
    {"unknown_enum_typo",
     "unknown_enum_typo.yaml:4:9: key 'wheel.edge': found 'risin', expected one of rising|falling (did you "
     "mean 'rising'?)",
     1},
    {"fast_threads_two",
     "fast_threads_two.yaml:4:17: key 'replay.fast_threads': found '2', expected one of auto|1|3", 1},
    {"fourier_unstable",
     "fourier_unstable.yaml:5:11: key 'estimators.fourier.l_ke': found '0.001', expected stable observer "
     "gains: ",
     1},
    {"duplicate_key", "duplicate_key.yaml:5:3: key 'engine.bore_m' appears twice in the same section", 1},
    {"tooth_angles_and_teeth",
     "tooth_angles_and_teeth.yaml:4:10: key 'wheel.teeth': found '36', expected no value when "
     "wheel.tooth_angles_deg is given",
     1},
    {"tooth_angles_not_increasing",
     "tooth_angles_not_increasing.yaml:4:21: key 'wheel.tooth_angles_deg': found '205', expected strictly "
     "increasing angles",
     1},
    {"cpus_not_a_list",
     "cpus_not_a_list.yaml:5:11: key 'realtime.angle.cpus': found '0,1', expected a list of integers", 1},
    {"signal_without_dbc", "signal_without_dbc.yaml:3:1: key 'can.dbc': found '', expected a DBC file path",
     1},
    {"section_is_scalar",
     "section_is_scalar.yaml:3:9: key 'engine': found '4', expected a section (mapping of keys: bore_m,", 1},
    {"dbc_signal_typo",
     "dbc_signal_typo.yaml:6:38: key 'can.signals.map.signal': found 'MAPP', expected a signal of message "
     "ENGINE_1 in test.dbc (MAP)",
     2},
    {"dbc_skipped_signal",
     "dbc_skipped_signal.yaml:7:38: key 'can.signals.map.signal': found 'MAP', expected a signal the DBC "
     "parser "
     "can load (",
     1},
    {"e_machine_ratio_zero",
     "e_machine_ratio_zero.yaml:5:12: key 'can.e_machine.ratio': found '0', expected a finite number (range "
     "(0, 100])",
     1},
    {"e_machine_sign_zero",
     "e_machine_sign_zero.yaml:5:11: key 'can.e_machine.sign': found '0', expected +1 or -1", 1},
    {"e_machine_sole_load_unmapped",
     "e_machine_sole_load_unmapped.yaml:5:16: key 'can.e_machine.sole_load': found 'true', expected "
     "can.signals.em_torque mapped",
     1},
    {"cylinder_window_overlaps",
     "cylinder_window_overlaps.yaml:8:26: key 'estimators.energies.cylinder_window_deg': found '150', "
     "expected less than 720 deg / cylinders = 120 deg",
     1},
    {"blowdown_before_evo",
     "blowdown_before_evo.yaml:6:28: key 'estimators.energies.blowdown_end_atdc_deg': found '100', expected "
     "more than evo_atdc_deg = 130 deg",
     1},
    {"model_delta_zero",
     "model_delta_zero.yaml:5:18: key 'estimators.kalman.model_delta': found '0', expected a finite number "
     "(1/rad, range [0.001, 1000])",
     1},
    {"delta_subnormal_pole",
     "delta_subnormal_pole.yaml:5:12: key 'estimators.kalman.delta': found '1e-300', expected a finite "
     "number "
     "(1/rad, range [0.001, 1000])",
     1},
    {"burn_phase_offset_beyond_tables",
     "burn_phase_offset_beyond_tables.yaml:5:32: key 'estimators.kalman.burn_phase_max_offset_deg': found "
     "'40', "
     "expected a finite number (deg, range [0, 28])",
     1},
    {"free_coast_band_inverted",
     "free_coast_band_inverted.yaml:4:3: key 'can.load_reference.free_coast_decel_max': found '1.8' "
     "(default), "
     "expected "
     "more than free_coast_decel_min = 1.9",
     1},
    {"many_errors",
     "many_errors.yaml:12:10: key 'logging.level': found 'verbose', expected one of "
     "trace|debug|info|warn|error|critical|off",
     6},
};

class BadFile : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadFile, IsRefusedWithPositionKeyFoundExpected) {
  const BadCase& c = GetParam();
  const std::string path = kDir + "bad/" + c.file + ".yaml";
  ASSERT_TRUE(std::filesystem::exists(path)) << path;
  const LoadResult r = load_config(path);
  EXPECT_FALSE(r.ok());
  EXPECT_FALSE(r.config.has_value());
  EXPECT_EQ(r.errors.size(), c.errors) << joined(r.errors);
  const bool found = std::any_of(r.errors.begin(), r.errors.end(), [&](const std::string& e) {
    return e.find(c.expected) != std::string::npos;
  });
  EXPECT_TRUE(found) << "expected an error containing\n  " << c.expected << "\ngot\n" << joined(r.errors);
  for (const auto& e : r.errors)
    EXPECT_EQ(e.rfind(path + ":", 0), 0u) << "error must start with the file: " << e;
}

INSTANTIATE_TEST_SUITE_P(Config, BadFile, ::testing::ValuesIn(kBad),
                         [](const ::testing::TestParamInfo<BadCase>& i) {
                           return std::string(i.param.file);
                         });

TEST(ConfigLoader, EveryBadFileIsInTheTable) {
  std::size_t files = 0;
  for (const auto& f : std::filesystem::directory_iterator(kDir + "bad")) {
    if (f.path().extension() != ".yaml") continue;
    ++files;
    const std::string stem = f.path().stem().string();
    EXPECT_TRUE(
        std::any_of(std::begin(kBad), std::end(kBad), [&](const BadCase& c) { return stem == c.file; }))
        << stem << " has no expected error in kBad";
  }
  EXPECT_GE(files, 12u);
}

TEST(ConfigLoader, ManyErrorsAreAllReported) {
  const LoadResult r = load_config(kDir + "bad/many_errors.yaml");
  const char* keys[] = {"engine.bore_m", "engine.stroke_m", "engine.cylinders",
                        "wheel.teeth",   "dds.domain_id",   "logging.level"};
  for (const char* k : keys)
    EXPECT_NE(joined(r.errors).find(std::string("key '") + k + "'"), std::string::npos) << k << "\n"
                                                                                        << joined(r.errors);
}

TEST(ConfigLoader, GoodFileValuesAndRelativePaths) {
  const LoadResult r = load_config(kDir + "good/files.yaml");
  ASSERT_TRUE(r.ok()) << joined(r.errors);
  const Config& c = *r.config;
  EXPECT_EQ(c.engine.cylinders, 3);
  EXPECT_EQ(c.engine.firing_order[0], 1);
  EXPECT_EQ(c.engine.firing_order[1], 2);
  EXPECT_EQ(c.engine.firing_order[2], 3);
  EXPECT_EQ(c.engine.firing_order[3], 0);
  EXPECT_NEAR(c.engine.tdc_offset_rad, 114.0 * std::numbers::pi / 180.0, 1e-12);  // YAML degrees → radians
  EXPECT_EQ(c.wheel.geometry.positions, 36);
  EXPECT_EQ(c.wheel.geometry.missing, 1);
  EXPECT_FALSE(c.wheel.geometry.rising_edge);
  EXPECT_EQ(c.inputs.edges.backend, EdgeBackend::kFile);
  EXPECT_EQ(c.inputs.edges.path, std::filesystem::path(kDir + "data/edges.csv").lexically_normal().string());
  EXPECT_EQ(c.can.dbc, std::filesystem::path(kDir + "data/test.dbc").lexically_normal().string());
  EXPECT_DOUBLE_EQ(c.inputs.can.time_offset_s, -1700000000.0);
  EXPECT_EQ(c.can.signals[0].message, "ENGINE_1");
  EXPECT_EQ(c.can.signals[0].timeout_ms, 250);
  EXPECT_FALSE(c.can.signals[1].mapped());
  EXPECT_EQ(c.realtime.angle.priority, 90);
  EXPECT_EQ(c.realtime.angle.cpus, (std::vector<int>{2, 3}));
  EXPECT_EQ(c.realtime.publisher.policy, SchedPolicy::kOther);
  EXPECT_EQ(c.dds.engine_id, 42);  // hex 0x2A
  EXPECT_TRUE(std::filesystem::path(c.source_file).is_absolute());
}

TEST(ConfigLoader, EmptyDocumentGivesDefaults) {
  const LoadResult r = load_config_from_string("inputs: {edges: {backend: gpio}}\n", "/tmp/x.yaml");
  ASSERT_TRUE(r.ok()) << joined(r.errors);
  const Config defaults;
  for (const auto& e : config_schema()) {
    if (e.key == "inputs.edges.backend") continue;
    EXPECT_EQ(format_config_value(e, e.get(*r.config)), format_config_value(e, e.get(defaults))) << e.key;
  }
}

TEST(ConfigLoader, EveryDefaultIsInsideItsBounds) {
  // Catches a default changed in estimators/core/params.hpp without updating the schema table.
  const Config defaults;
  for (const auto& e : config_schema()) {
    if (!e.bounded) continue;
    const ConfigValue v = e.get(defaults);
    std::vector<double> xs;
    if (e.kind == ValueKind::kDouble)
      xs = {v.d};
    else if (e.kind == ValueKind::kInt)
      xs = {static_cast<double>(v.i)};
    else if (e.kind == ValueKind::kDoubleList)
      xs = v.dl;
    else if (e.kind == ValueKind::kIntList)
      xs.assign(v.il.begin(), v.il.end());
    for (double x : xs) {
      EXPECT_TRUE(e.lo_open ? x > e.lo : x >= e.lo)
          << e.key << " default " << x << " vs " << describe_expected(e);
      EXPECT_TRUE(e.hi_open ? x < e.hi : x <= e.hi)
          << e.key << " default " << x << " vs " << describe_expected(e);
    }
  }
  EXPECT_TRUE(check_config_physics(defaults).empty());
}

TEST(ConfigLoader, EnabledFlagsOfNaEstimatorsReachTheTimePipeline) {
  const LoadResult r = load_config_from_string(
      "inputs: {edges: {backend: gpio}}\nestimators: {uio: {enabled: false}, adaptive: {enabled: false}}\n",
      "/tmp/x.yaml");
  ASSERT_TRUE(r.ok()) << joined(r.errors);
  EXPECT_FALSE(r.config->estimators.uio.enabled);
  EXPECT_FALSE(r.config->estimators.time_pipeline.uio);
  EXPECT_FALSE(r.config->estimators.time_pipeline.adaptive);
  EXPECT_TRUE(r.config->estimators.time_pipeline.sliding_mode);
}

TEST(ConfigLoader, MissingFileIsAClearError) {
  const LoadResult r = load_config(kDir + "no_such_config.yaml");
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].find("no_such_config.yaml: cannot open configuration file"), std::string::npos)
      << r.errors[0];
}

TEST(ConfigLoader, CheckRunsTheDaemonsDbcParser) {
  // GIVEN a DBC whose mapped signal's line is broken and which has another bad line nothing maps
  const LoadResult r = load_config(kDir + "bad/dbc_skipped_signal.yaml");
  // THEN the mapped signal is an error naming the DBC's file:line and what was expected; the other is a
  // warning
  ASSERT_EQ(r.errors.size(), 1u) << joined(r.errors);
  EXPECT_NE(r.errors[0].find("vehicle_defects.dbc:6: signal ENGINE_1.MAP: expected '[<min>|<max>]'"),
            std::string::npos)
      << r.errors[0];
  EXPECT_NE(joined(r.warnings).find("vehicle_defects.dbc:9: message name '2ND_MESSAGE' starts with a digit"),
            std::string::npos)
      << joined(r.warnings);
}

TEST(ConfigLoader, FileChecksCanBeSkipped) {
  const std::string yaml = "inputs: {edges: {backend: file, path: /nonexistent/edges.csv}}\n";
  EXPECT_FALSE(load_config_from_string(yaml, "/tmp/x.yaml").ok());
  EXPECT_TRUE(load_config_from_string(yaml, "/tmp/x.yaml", LoadOptions{false}).ok());
}

TEST(ConfigLoader, FourierStabilityMatchesCf14) {
  // GIVEN a 60-2 wheel (N = 120 samples, dalpha = 6 deg): the bound is (dalpha/2)(L_a0 + L_ref n_h(n_h+1)/2).
  WheelGeometry w;
  FourierParams p;
  p.harmonics = 5;
  p.l_a0 = 0.05;
  p.l_ref = 0.05;
  const double bound = 0.5 * (4.0 * std::numbers::pi / 120.0) * (0.05 + 0.05 * 15.0);
  p.l_ke = bound * 1.01;
  EXPECT_FALSE(check_fourier_stability(p, w).has_value());
  p.l_ke = bound * 0.99;
  EXPECT_TRUE(check_fourier_stability(p, w).has_value());
  p.l_ke = 10.0;
  p.harmonics = 60;  // 2 n_h + 1 = 121 >= 120 samples
  EXPECT_TRUE(check_fourier_stability(p, w).has_value());
}

TEST(ConfigLoader, QuantityOrderMatchesSignalStore) {
  for (std::size_t i = 0; i < kCanQuantityCount; ++i)
    EXPECT_EQ(can_quantity_name(i), std::string(quantity_name(static_cast<Quantity>(i)))) << i;
  EXPECT_EQ(static_cast<std::size_t>(kQuantityCount), kCanQuantityCount);
}

TEST(ConfigLoader, DemoConfigIsValid) {
  const std::string path = std::string(TORQUED_SOURCE_DIR) + "/config/demo.yaml";
  const LoadResult r = load_config(path, LoadOptions{false});
  ASSERT_TRUE(r.ok()) << joined(r.errors);
  EXPECT_EQ(r.config->dds.domain_id, 0);
  EXPECT_DOUBLE_EQ(r.config->inputs.can.time_offset_s, -1700000000.0);
  // Every quantity but the electric machine's and the vehicle flags (the demo is a dynamometer bench with no
  // machine: its replay stays byte-identical).
  for (std::size_t i = 0; i < kCanQuantityCount; ++i)
    EXPECT_EQ(r.config->can.signals[i].mapped(), i != kCanEmTorque && i != kCanEmSoleLoad && i != kCanNeutral)
        << can_quantity_name(i);
  if (std::filesystem::exists(std::string(TORQUED_SOURCE_DIR) + "/data/demo/edges.csv")) {
    const LoadResult full = load_config(path);
    EXPECT_TRUE(full.ok()) << joined(full.errors);
  }
}

}  // namespace
}  // namespace torqued
