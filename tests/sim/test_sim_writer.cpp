// File formats of the simulator (docs/simulator.md §7: edge CSV, candump -l, truth CSVs, engine YAML) and the
// CAN packing behind config/demo.dbc (Intel and Motorola round trips, committed DBC in sync with the code).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

#include "can_codec.hpp"
#include "sim_fixture.hpp"
#include "sim_random.hpp"
#include "sim_writer.hpp"

namespace torqued::sim {
namespace {

using test::run;

std::vector<std::string> lines(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

TEST(CanCodec, RoundTripEverySignalBothByteOrders) {
  SimRandom rng(7, 7);
  for (const auto& m : demo_messages()) {
    for (int trial = 0; trial < 200; ++trial) {
      std::array<std::uint8_t, 64> data{};
      std::vector<double> want;
      for (const auto& s : m.signals) {
        const double v = s.min + (s.max - s.min) * rng.uniform();
        want.push_back(v);
        pack_signal(s, v, data.data());
      }
      // Packing later signals must not disturb earlier ones: decode all after packing all.
      for (std::size_t i = 0; i < m.signals.size(); ++i)
        EXPECT_NEAR(unpack_signal(m.signals[i], data.data()), want[i], 0.5001 * m.signals[i].factor)
            << m.name << "." << m.signals[i].name;
      for (std::size_t b = static_cast<std::size_t>(m.dlc); b < data.size(); ++b)
        EXPECT_EQ(data[b], 0) << m.name;
    }
  }
}

TEST(CanCodec, KnownBitLayouts) {
  std::array<std::uint8_t, 64> d{};
  const MessageDef* e1 = find_message(kEngine1Id);
  const MessageDef* e2 = find_message(kEngine2Id);
  ASSERT_TRUE(e1 && e2);
  pack_signal(*find_signal(*e1, "EngineSpeed"), 64.0, d.data());  // raw 256, Intel: LSB first
  EXPECT_EQ(d[0], 0x00);
  EXPECT_EQ(d[1], 0x01);
  d.fill(0);
  pack_signal(*find_signal(*e2, "MAF"), 2.56, d.data());  // raw 256, Motorola: MSB first
  EXPECT_EQ(d[0], 0x01);
  EXPECT_EQ(d[1], 0x00);
  pack_signal(*find_signal(*e2, "FuelCutoff"), 1.0, d.data());
  EXPECT_EQ(d[7], 0x80);
  pack_signal(*find_signal(*e2, "SparkAdvance"), -1.0, d.data());  // signed: raw −2 = 0xFE
  EXPECT_EQ(d[4], 0xFE);
  EXPECT_DOUBLE_EQ(unpack_signal(*find_signal(*e2, "SparkAdvance"), d.data()), -1.0);
  // Saturation instead of wrap-around.
  d.fill(0);
  pack_signal(*find_signal(*e1, "MAP"), 1e6, d.data());
  EXPECT_NEAR(unpack_signal(*find_signal(*e1, "MAP"), d.data()), 655.35, 1e-9);
}

TEST(CanCodec, CommittedDbcMatchesTheCode) {
  std::ifstream f(std::string(TORQUED_SOURCE_DIR) + "/config/demo.dbc", std::ios::binary);
  ASSERT_TRUE(f) << "config/demo.dbc missing: regenerate with torque-sim --write-dbc config/demo.dbc";
  std::stringstream ss;
  ss << f.rdbuf();
  EXPECT_EQ(ss.str(), demo_dbc_text()) << "regenerate with torque-sim --write-dbc config/demo.dbc";
  const std::string dbc = demo_dbc_text();
  EXPECT_NE(dbc.find(" SG_ MAF : 7|16@0+ (0.01,0) [0|655.35] \"g/s\""), std::string::npos);
  EXPECT_NE(dbc.find("VAL_ 257 FuelCutoff 1 \"Active\" 0 \"Inactive\" ;"), std::string::npos);
}

TEST(SimWriter, EdgeCsvFormat) {
  const auto& r = run("steady_2000_mid", 0.2);
  const auto l = lines(edges_csv(r.out));
  ASSERT_EQ(l[0], "Time [s],crank,cam");
  ASSERT_EQ(l.size(), r.out.edges.size() + 2);
  EXPECT_EQ(l[1].substr(0, 12), "0.000000000,");
  const std::regex row(R"(^\d+\.\d{9},[01],[01]$)");
  double prev = -1.0;
  int crank_prev = l[1][12] - '0', toggles_ok = 0;
  for (std::size_t i = 1; i < l.size(); ++i) {
    ASSERT_TRUE(std::regex_match(l[i], row)) << "line " << i + 1 << ": " << l[i];
    const double t = std::stod(l[i]);
    ASSERT_GE(t, prev);
    prev = t;
    if (i > 1 && r.out.edges[i - 2].channel == 0) {
      const int crank = l[i][l[i].size() - 3] - '0';
      toggles_ok += crank != crank_prev;
      crank_prev = crank;
    }
  }
  int crank_edges = 0;
  for (const auto& e : r.out.edges) crank_edges += e.channel == 0;
  EXPECT_EQ(toggles_ok, crank_edges) << "every crank row toggles the crank level";
}

TEST(SimWriter, CandumpFormatAndTimes) {
  const auto& r = run("steady_2000_mid", 0.2);
  const auto l = lines(candump_log(r.out));
  ASSERT_EQ(l.size(), r.out.can.size());
  const std::regex row(R"(^\(1700000000\.(\d{6})\) can0 ([0-9A-F]{3})#([0-9A-F]*)$)");
  std::smatch m;
  for (std::size_t i = 0; i < l.size(); ++i) {
    ASSERT_TRUE(std::regex_match(l[i], m, row)) << l[i];
    EXPECT_EQ(std::stoll(m[1]) * 1000, r.out.can[i].t_ns);
    EXPECT_EQ(m[3].length(), 2u * r.out.can[i].len);
  }
  // 4 messages at 100 Hz, 0.1 % drops.
  EXPECT_NEAR(static_cast<double>(l.size()), 4 * 100 * 0.2, 4.0);
}

TEST(SimWriter, TruthCsvHeadersAndRows) {
  const auto& r = run("steady_2000_mid", 0.2);
  const auto tooth = lines(truth_tooth_csv(r.out, r.scenario));
  EXPECT_EQ(
      tooth[0],
      "t_s,tooth,angle720_deg,speed_rad_s,t_ind_nm,t_ind_cyl1_nm,t_ind_cyl2_nm,t_ind_cyl3_nm,t_ind_cyl4_nm,"
      "t_mass_nm,t_fric_nm,t_load_nm,t_brake_nm");
  EXPECT_EQ(tooth.size(), r.out.teeth.size() + 1);
  const auto cyc = lines(truth_cycle_csv(r.out, r.scenario));
  EXPECT_EQ(
      cyc[0].rfind("cycle,t_start_s,t_end_s,speed_mean_rpm,t_ind_mean_nm,t_brake_mean_nm,t_fric_mean_nm,"
                   "t_load_mean_nm,cyl1_ind_mean_nm,cyl2_ind_mean_nm,cyl3_ind_mean_nm,cyl4_ind_mean_nm,"
                   "misfire1,misfire2,misfire3,misfire4,fuel_cut",
                   0),
      0u);
  EXPECT_EQ(cyc.size(), r.out.cycles.size() + 1);
  const auto ncols = [](const std::string& s) { return std::count(s.begin(), s.end(), ',') + 1; };
  for (const auto& l : tooth) EXPECT_EQ(ncols(l), ncols(tooth[0]));
  for (const auto& l : cyc) EXPECT_EQ(ncols(l), ncols(cyc[0]));
  const std::string yaml = engine_yaml(r.scenario);
  for (const char* key :
       {"engine:\n", "  cylinders: 4\n", "  firing_order: [1, 3, 4, 2]\n", "  bore_m: 0.0825\n",
        "  tdc_offset_deg: 90\n", "wheel:\n", "  teeth: 60\n", "  missing: 2\n", "  edge: rising\n"})
    EXPECT_NE(yaml.find(key), std::string::npos) << key;
}

TEST(SimWriter, SameSeedGivesByteIdenticalFiles) {
  Scenario sc = scenario_by_name("wheel_36_1");
  sc.duration_s = 0.3;
  const SimOutput a = simulate(sc);
  const SimOutput b = simulate(sc);
  EXPECT_EQ(edges_csv(a), edges_csv(b));
  EXPECT_EQ(candump_log(a), candump_log(b));
  EXPECT_EQ(truth_tooth_csv(a, sc), truth_tooth_csv(b, sc));
  EXPECT_EQ(truth_cycle_csv(a, sc), truth_cycle_csv(b, sc));
  sc.seed = 9;
  const SimOutput c = simulate(sc);
  EXPECT_NE(edges_csv(a), edges_csv(c));
  EXPECT_NE(tooth_errors_csv(a), tooth_errors_csv(c));
}

TEST(SimWriter, WritesAllFilesIntoADirectory) {
  const auto& r = run("steady_2000_mid", 0.2);
  const auto dir =
      std::filesystem::temp_directory_path() / ("torqued_sim_test_" + std::to_string(::getpid()));
  write_outputs(r.out, r.scenario, dir);
  for (const char* f :
       {"edges.csv", "can.log", "truth_tooth.csv", "truth_cycle.csv", "engine.yaml", "tooth_errors.csv"})
    EXPECT_GT(std::filesystem::file_size(dir / f), 10u) << f;
  std::filesystem::remove_all(dir);
  EXPECT_THROW(write_outputs(r.out, r.scenario, "/proc/no/such/dir"), std::runtime_error);
}

}  // namespace
}  // namespace torqued::sim
