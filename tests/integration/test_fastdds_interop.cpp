// tests/integration/test_fastdds_interop.cpp: a Fast DDS 2.9 subscriber (fastddsgen code of idl/torque.idl,
// another vendor, another process) receives torqued's EngineTorque from Cyclone DDS and its values equal the
// daemon's own recording (matched by seq). Fails loudly when nothing matches (type/topic-name mismatch).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

#include "process.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

TEST(FastDdsInterop, FastDdsSubscriberReceivesEngineTorque) {
  const fs::path dir = fs::temp_directory_path() / ("torqued_fastdds_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string out = (dir / "fastdds.out").string(), err = (dir / "fastdds.err").string();
  constexpr int kCount = 60;
  test::Process sub({FASTDDS_SUB_EXE, std::to_string(kCount), "40"}, {}, out);
  test::Process d({TORQUED_EXE, "--config", std::string(TORQUED_SOURCE_DIR) + "/config/demo.yaml", "--speed",
                   "4", "--exit-when-done", "--wait-subscribers", "1", "--record", (dir / "rec").string(),
                   "--state-dir", (dir / "state").string()},
                  {}, (dir / "daemon.log").string());
  ASSERT_TRUE(sub.wait(45)) << test::slurp(out);
  ASSERT_EQ(sub.exit_code(), 0) << "Fast DDS subscriber failed:\n" << test::slurp(out);
  d.signal(SIGTERM);
  ASSERT_TRUE(d.wait(10));

  // Daemon's recording: seq -> fused_nm, for segments and cycles.
  std::map<unsigned long long, double> fused;
  for (const char* f : {"engine_segment.csv", "engine_cycle.csv"}) {
    std::istringstream in(test::slurp((dir / "rec" / f).string()));
    std::string line;
    std::getline(in, line);  // t_ns,engine_id,seq,...,fused_nm(15)
    while (std::getline(in, line)) {
      std::vector<std::string> c;
      std::stringstream ls(line);
      for (std::string x; std::getline(ls, x, ',');) c.push_back(x);
      fused[std::stoull(c[2])] = std::stod(c[15]);
    }
  }
  // Fast DDS lines: "cycle kind fused_nm seq engine_id" (stdout and stderr share the file; skip stderr
  // lines).
  std::istringstream in(test::slurp(out));
  std::string line;
  int checked = 0;
  while (std::getline(in, line)) {
    if (line.rfind("fastdds", 0) == 0) continue;
    unsigned cycle = 0, kind = 0, engine = 0;
    double value = 0;
    unsigned long long seq = 0;
    if (std::sscanf(line.c_str(), "%u %u %lf %llu %u", &cycle, &kind, &value, &seq, &engine) != 5) continue;
    EXPECT_EQ(engine, 1u);
    ASSERT_TRUE(fused.count(seq)) << "seq " << seq << " not in the daemon's recording";
    EXPECT_NEAR(value, fused[seq], 1e-5) << line;
    ++checked;
  }
  EXPECT_EQ(checked, kCount);
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace torqued
