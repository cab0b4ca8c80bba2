// Learned-state file (daemon/state_store): exact round trip of every field, clear errors naming file and line.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "state_store.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

class StateStore : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("torqued_state_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    path_ = (dir_ / "sub" / "learned_state.txt").string();
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
  std::string path_;
};

TEST_F(StateStore, RoundTripIsExactForEveryField) {
  LearnedState s;
  s.friction = std::array<double, 4>{-23.86, 2.45e-3, -5.2e-6, -4.67e-3};
  s.friction_idle = std::array<double, 2>{1.4999999999999998, 812.25};
  s.tooth_corrections_rad = {1e-4, -3.3e-5, 0.0, 7.123456789012345e-4};
  s.saved_at_t_ns = 12'345'678'901;
  std::string err;
  ASSERT_TRUE(save_state_atomic(path_, s, &err)) << err;  // creates the missing directory too
  EXPECT_FALSE(fs::exists(path_ + ".tmp"));
  const auto r = load_state(path_, &err);
  ASSERT_TRUE(r.has_value()) << err;
  EXPECT_EQ(r->friction, s.friction);
  EXPECT_EQ(r->friction_idle, s.friction_idle);
  EXPECT_EQ(r->tooth_corrections_rad, s.tooth_corrections_rad);
  EXPECT_EQ(r->saved_at_t_ns, s.saved_at_t_ns);
}

TEST_F(StateStore, OptionalFieldsMayBeAbsent) {
  LearnedState s;
  s.tooth_corrections_rad = {2e-4};
  std::string err;
  ASSERT_TRUE(save_state_atomic(path_, s, &err)) << err;
  const auto r = load_state(path_, &err);
  ASSERT_TRUE(r.has_value()) << err;
  EXPECT_FALSE(r->friction.has_value());
  EXPECT_FALSE(r->friction_idle.has_value());
  EXPECT_EQ(r->tooth_corrections_rad.size(), 1u);
}

TEST_F(StateStore, MalformedLinesAreRefusedNamingFileAndLine) {
  fs::create_directories(fs::path(path_).parent_path());
  const std::pair<const char*, const char*> cases[] = {
      {"torqued-state 1\nfriction_idle 1.5 0\n", "positive idle speed"},
      {"torqued-state 1\nfriction_idle nan 800\n", "idle friction correction"},
      {"torqued-state 1\nfriction 1 2 3\n", "4 finite friction coefficients"},
      {"torqued-state 2\n", "torqued-state 1"},
      {"torqued-state 1\nwhat 1\n", "unknown key 'what'"},
  };
  for (const auto& [text, expect] : cases) {
    std::ofstream(path_) << text;
    std::string err;
    EXPECT_FALSE(load_state(path_, &err).has_value()) << text;
    EXPECT_NE(err.find(path_), std::string::npos) << err;
    EXPECT_NE(err.find(expect), std::string::npos) << "got: " << err;
  }
}

}  // namespace
}  // namespace torqued
