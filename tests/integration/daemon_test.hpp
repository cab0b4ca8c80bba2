#pragma once
// Test fixture of the tests that run the torqued binary: a private directory per test (kept when the test
// failed, for its logs), the demo configuration written into it, and the daemon's command line.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "process.hpp"

namespace torqued::test {

class DaemonTest : public ::testing::Test {
 protected:
  explicit DaemonTest(std::string prefix) : prefix_(std::move(prefix)) {}
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           (prefix_ + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    config_ = write_demo_config(dir_.string());
  }
  void TearDown() override {
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }
  [[nodiscard]] std::string log() const { return slurp((dir_ / "daemon.log").string()); }
  /// torqued --config <demo> --no-dds --state-dir <dir>/state, then `extra`.
  [[nodiscard]] std::vector<std::string> args(std::vector<std::string> extra) const {
    std::vector<std::string> a{TORQUED_EXE, "--config",    config_,
                               "--no-dds",  "--state-dir", (dir_ / "state").string()};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }

  std::string prefix_;
  std::filesystem::path dir_;
  std::string config_;
};

}  // namespace torqued::test
