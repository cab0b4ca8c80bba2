// The bundled demo recording data/demo/ is reproducible from the simulator and stays small.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "engine_sim.hpp"
#include "sim_writer.hpp"

namespace torqued::sim {
namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

TEST(SimDemo, BundledDemoIsReproducibleAndSmall) {
  const std::filesystem::path dir = std::filesystem::path(TORQUED_SOURCE_DIR) / "data" / "demo";
  std::uintmax_t total = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) total += e.file_size();
  EXPECT_LT(total, 6u * 1000u * 1000u) << "bytes in data/demo";
  const Scenario sc = scenario_by_name("demo");
  const SimOutput out = simulate(sc);
  // On mismatch regenerate with: torque-sim --scenario demo --out data/demo
  EXPECT_TRUE(edges_csv(out) == slurp(dir / "edges.csv")) << "edges.csv differs";
  EXPECT_TRUE(candump_log(out) == slurp(dir / "can.log")) << "can.log differs";
  EXPECT_TRUE(truth_tooth_csv(out, sc) == slurp(dir / "truth_tooth.csv")) << "truth_tooth.csv differs";
  EXPECT_TRUE(truth_cycle_csv(out, sc) == slurp(dir / "truth_cycle.csv")) << "truth_cycle.csv differs";
  EXPECT_TRUE(engine_yaml(sc) == slurp(dir / "engine.yaml")) << "engine.yaml differs";
}

}  // namespace
}  // namespace torqued::sim
