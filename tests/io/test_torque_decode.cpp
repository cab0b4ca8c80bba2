// torque-decode end to end: runs the executable on synthetic recordings (and the demo when present) and
// checks its CSV outputs and one-line summary.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "io_test_util.hpp"
#include "synthetic_wheel.hpp"

namespace torqued {
namespace {

struct ToolRun {
  int status = -1;
  std::string out;  ///< stdout + stderr
};

ToolRun run(const std::string& args) {
  ToolRun r;
  const std::string cmd = std::string(TORQUE_DECODE_EXE) + " " + args + " 2>&1";
  std::FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) return r;
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), p) != nullptr) r.out += buf.data();
  r.status = ::pclose(p);
  return r;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string edges_csv(const test::SynthOutput& s, const std::string& extra_bad_lines = "") {
  std::string csv = "Time [s],crank,cam\n0.000000000,0,0\n";
  std::array<int, 2> lvl{0, 0};
  char line[64];
  for (const auto& e : s.edges) {
    lvl[e.channel] = e.level;
    std::snprintf(line, sizeof line, "%.9f,%d,%d\n", static_cast<double>(e.t_ns) * 1e-9, lvl[0], lvl[1]);
    csv += line;
    if (&e == &s.edges[100]) csv += extra_bad_lines;
  }
  return csv;
}

TEST(TorqueDecode, SyntheticCaptureWithBadLines) {
  test::SynthOptions o;
  o.start_deg = 10;
  const auto s = test::synthesize(o);
  test::TempFile in(edges_csv(s, "not,a,row\n0.5,x,0\n"), ".csv");
  test::TempFile teeth("", ".csv");
  const ToolRun r = run("--edges " + in.path() + " --wheel 60-2 --out-teeth " + teeth.path());
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("sync losses 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("bad lines 2 edges"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(in.path() + ":104: expected a time"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("rpm 3000-3000"), std::string::npos) << r.out;
  const std::string csv = slurp(teeth.path());
  EXPECT_EQ(csv.rfind("t_ns,t_s,tooth,angle_deg,rpm,sync,phase_known,events\n", 0), 0u);
  EXPECT_NE(csv.find(",synced,1,"), std::string::npos);
  EXPECT_NE(csv.find(",synced,1,gap"), std::string::npos);
}

TEST(TorqueDecode, CanLogWithDbc) {
  test::TempFile dbc(
      "VERSION \"\"\nBU_: ECU\nBO_ 256 ENGINE_1: 2 ECU\n SG_ EngineSpeed : 0|16@1+ (0.25,0) [0|16383.75] "
      "\"rpm\" X\n"
      "VAL_ 256 EngineSpeed 0 \"Stopped\" ;\n",
      ".dbc");
  test::TempFile log(
      "(1700000000.010000) can0 100#E02E\n(1700000000.020000) can0 100#0000\n"
      "(1700000000.030000) can0 555#01\nbroken\n(1700000000.040000) can0 100#E0\n");
  test::TempFile out("", ".csv");
  const ToolRun r = run("--can " + log.path() + " --dbc " + dbc.path() +
                        " --can-offset -1700000000 --out-can " + out.path());
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("frames 4 (decoded 2, unknown id 1, bad dlc 1), bad lines 0 edges / 1 can"),
            std::string::npos)
      << r.out;
  const std::string csv = slurp(out.path());
  EXPECT_NE(csv.find("10000000,0.010000,0,0x100,ENGINE_1,EngineSpeed,3000,rpm,\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find("EngineSpeed,0,rpm,Stopped\n"), std::string::npos) << csv;
}

TEST(TorqueDecode, CanCsvIsRfc4180WithFullPrecision) {
  // GIVEN labels and a unit with commas and quotes, a 56-bit unscaled value, a scaled one and a 64-bit
  // unsigned value with bit 63 set, and a bad DBC line elsewhere (reported, the rest decodes)
  test::TempFile dbc(
      "BO_ 256 M: 8 ECU\n SG_ Big : 0|56@1+ (1,0) [0|0] \"\" X\n SG_ Scaled : 56|8@1+ (0.1,0) [0|0] "
      "\"m,s\" X\nBO_ 257 U: 8 ECU\n SG_ U64 : 0|64@1+ (1,0) [0|0] \"5\\\" pipe\" X\n"
      "BO_ 258 9BAD: 8 ECU\nVAL_ 256 Scaled 3 \"a, b\" ;\n",
      ".dbc");
  test::TempFile log("(1.000000) can0 100#FFFFFFFFFFFFFF03\n(2.000000) can0 101#0100000000000080\n");
  test::TempFile out("", ".csv");
  const ToolRun r = run("--can " + log.path() + " --dbc " + dbc.path() + " --out-can " + out.path());
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find(dbc.path() + ":6: message name '9BAD'"), std::string::npos) << r.out;
  const std::string csv = slurp(out.path());
  // THEN 2^56-1 exactly, 0.3 as the shortest text of the double 3 x 0.1, quoted fields with doubled quotes
  EXPECT_NE(csv.find(",0x100,M,Big,72057594037927935,,\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find(",0x100,M,Scaled,0.30000000000000004,\"m,s\",\"a, b\"\n"), std::string::npos) << csv;
  // (the DBC string 5\" pipe keeps its backslash, as the parser stores strings)
  EXPECT_NE(csv.find(",0x101,U,U64,9223372036854775809,\"5\\\"\" pipe\",\n"), std::string::npos) << csv;
}

TEST(TorqueDecode, DetectWheelOnARealCapture) {
  // GIVEN the arctic-cat capture (tests/data/captures/rusefi) and no wheel name
  const ToolRun r = run("--detect-wheel " + std::string(TORQUED_SOURCE_DIR) +
                        "/tests/data/captures/rusefi/arctic-cat.csv --crank 'Channel 1'");
  // THEN the gap structure, its catalogue entry and the angles to paste
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("wheel: 24 positions, 21 teeth; runs (teeth, missing): 11, 1, 10, 2"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("catalogue: arctic-cat"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("tooth_angles_deg: [0, 15, 30,"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("seen: 8 revolutions"), std::string::npos) << r.out;  // 16 gaps, 2 per turn
}

TEST(TorqueDecode, DetectWheelSaysWhenTheAskedForCamColumnIsDropped) {
  // GIVEN a capture whose cam column is named cam, and --cam with a name it does not have
  const ToolRun r = run("--detect-wheel " + std::string(TORQUED_SOURCE_DIR) +
                        "/tests/data/captures/rusefi/nb2-cranking-good.csv --crank crank --cam typo");
  // THEN the crank alone is read, and a note says the cam asked for was dropped (and why)
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("torque-decode: note: --cam 'typo' dropped ("), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("no cam column named 'typo'"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("catalogue: not identified: candidates miata-nb2"), std::string::npos) << r.out;
  // AND without --cam (the default column name, absent here) no note
  const ToolRun q = run("--detect-wheel " + std::string(TORQUED_SOURCE_DIR) +
                        "/tests/data/captures/rusefi/arctic-cat.csv --crank 'Channel 1'");
  EXPECT_EQ(q.out.find("note:"), std::string::npos) << q.out;
}

// Every real capture (tests/data/captures/rusefi): the wheel each shows, or why none; never a wrong name.
TEST(TorqueDecode, DetectWheelOnEveryRealCapture) {
  struct Case {
    const char* args;
    const char* expect;                ///< a line (start) the output must hold
    std::vector<std::string> allowed;  ///< names the "catalogue: " line may give as the match
  };
  const std::vector<Case> cases = {
      {"arctic-cat.csv --crank 'Channel 1'", "catalogue: arctic-cat", {"arctic-cat"}},
      {"noisy-trigger-1.csv", "catalogue: toyota-36-2, 36-2", {"toyota-36-2", "36-2"}},
      {"noisy-trigger-2.csv", "catalogue: toyota-36-2, 36-2", {"toyota-36-2", "36-2"}},
      {"noisy-trigger-3.csv", "detect-wheel: no repeating gap structure", {}},
      {"nb2-cranking-good.csv --crank crank", "catalogue: miata-nb2 (", {"miata-nb2"}},  // with its cam
      {"nb2-cranking-good.csv --crank crank",
       "(one cam turn = 720 deg: 4 teeth per revolution)",
       {"miata-nb2"}},
      // the crank alone: 70/110 deg every 180 deg, how many times per turn is not in the edge times
      {"nb2-cranking-good.csv --crank crank --cam ''",
       "catalogue: not identified: candidates miata-nb2 (",
       {}},
      {"4g63-cranking.csv --crank crank", "catalogue: 4g63 (", {"4g63"}},  // teeth per turn: its cam column
      {"4g63-cranking.csv --crank crank", "(one cam turn = 720 deg: 2 teeth per revolution)", {"4g63"}},
      {"4g63-cranking.csv --crank crank --cam ''", "catalogue: not identified by the crank alone", {}},
      {"cas_nissan_24_plus_1.csv --crank pri --cam sec", "catalogue: nissan-cas-24+1 (", {"nissan-cas-24+1"}},
      {"cas_nissan_24_plus_1.csv --crank pri", "catalogue: not identified by the crank alone", {}},
      {"gm_24x_cranking.csv --crank crank", "detect-wheel: pulse-width-coded wheel", {}},
      {"gm_24x_cranking.csv --crank crank --falling", "detect-wheel: pulse-width-coded wheel", {}},
  };
  const std::string dir = std::string(TORQUED_SOURCE_DIR) + "/tests/data/captures/rusefi/";
  for (const Case& c : cases) {
    const ToolRun r = run("--detect-wheel " + dir + c.args);
    EXPECT_NE(r.out.find(c.expect), std::string::npos) << c.args << "\n" << r.out;
    const auto at = r.out.find("catalogue: ");
    if (at == std::string::npos || r.out.compare(at, 25, "catalogue: not identified") == 0 ||
        r.out.compare(at, 20, "catalogue: no entry ") == 0)
      continue;
    // THEN every name given as the match is a right one
    std::string line = r.out.substr(at + 11, r.out.find_first_of("(\n", at) - at - 11);
    std::stringstream names(line);
    for (std::string n; std::getline(names, n, ',');) {
      n.erase(0, n.find_first_not_of(' '));
      n.erase(n.find_last_not_of(' ') + 1);
      EXPECT_NE(std::find(c.allowed.begin(), c.allowed.end(), n), c.allowed.end())
          << c.args << ": wrong match '" << n << "'\n"
          << r.out;
    }
  }
}

TEST(TorqueDecode, UsageErrors) {
  EXPECT_NE(run("").status, 0);
  const ToolRun bad_wheel = run("--edges /dev/null --wheel 60");
  EXPECT_NE(bad_wheel.status, 0);
  EXPECT_NE(bad_wheel.out.find("unknown; known wheels: N-M"), std::string::npos) << bad_wheel.out;
  const ToolRun missing = run("--edges /nonexistent.csv");
  EXPECT_NE(missing.status, 0);
  EXPECT_NE(missing.out.find("/nonexistent.csv"), std::string::npos) << missing.out;
}

TEST(TorqueDecode, DemoRecordingThroughConfig) {
  const std::string root = TORQUED_SOURCE_DIR;
  if (!std::ifstream(root + "/data/demo/edges.csv")) GTEST_SKIP() << "no data/demo recording";
  const ToolRun r = run("--config " + root + "/config/demo.yaml");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("sync losses 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("noise edges 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("unknown id 0, bad dlc 0), bad lines 0 edges / 0 can"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace torqued

namespace torqued {
namespace {
// Per-revolution speed and the sync/loss/glitch summary, on a real capture (rusEFI's GM 24x
// cranking, pulse-width coded): one sync, no loss, the revolutions listed, CSV and stdout agree.
TEST(TorqueDecode, PerRevolutionSpeedAndSyncSummaryOnARealCapture) {
  const std::string dir = ::testing::TempDir();
  const std::string revs = dir + "/gm_revs.csv";
  const auto r =
      run("--edges " + std::string(TORQUED_SOURCE_DIR) +
          "/tests/data/captures/rusefi/gm_24x_cranking.csv --wheel gm-24x --cam '' --first-row edges "
          "--revs --transitions --out-revs " +
          revs);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("sync: first at crank edge 8 "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("syncs 1, losses 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("width code errors 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("debug: "), std::string::npos) << r.out;  // transitions on stderr
  const std::string csv = slurp(revs);
  int rows = 0;
  double last_rpm = 0.0;
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "t_ns,t_s,rpm");
  while (std::getline(in, line)) {
    ++rows;
    last_rpm = std::stod(line.substr(line.rfind(',') + 1));
    EXPECT_NE(r.out.find("rev " + std::to_string(rows) + " "), std::string::npos) << rows;
  }
  EXPECT_GE(rows, 2);  // 66 teeth = 2.75 revolutions, synced after 8
  EXPECT_GT(last_rpm, 60.0);
  EXPECT_LT(last_rpm, 200.0);
  EXPECT_NE(r.out.find("revolutions " + std::to_string(rows) + ":"), std::string::npos) << r.out;
}

// --plot writes a PNG (skipped where Debian's python3-matplotlib is missing).
TEST(TorqueDecode, PlotWritesAPng) {
  if (std::system("/usr/bin/python3 -c 'import matplotlib' >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "no python3-matplotlib";
  const std::string png = ::testing::TempDir() + "/decode_plot.png";
  std::remove(png.c_str());
  const auto r = run("--edges " + std::string(TORQUED_SOURCE_DIR) +
                     "/tests/data/captures/rusefi/noisy-trigger-3.csv --wheel 36-2 --cam '' --plot " + png);
  ASSERT_EQ(r.status, 0) << r.out;
  const std::string bytes = slurp(png);
  ASSERT_GT(bytes.size(), 1000u);
  EXPECT_EQ(bytes.substr(1, 3), "PNG");
  std::ifstream teeth(png + ".teeth.csv");
  EXPECT_FALSE(teeth.good());  // the temporary per-tooth CSV is removed
}
}  // namespace
}  // namespace torqued
