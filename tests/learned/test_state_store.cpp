// Learned-state file (daemon/state_store): exact round trip, checksum, identity, physical bounds, rejected
// files set aside (never overwritten), backup, off-thread saves, and kill -9 in the middle of saves.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <future>
#include <numbers>
#include <random>
#include <sstream>
#include <thread>

#include "config.hpp"
#include "state_store.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

std::string slurp(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Files in `dir` whose name starts with `prefix`.
int count_prefixed(const fs::path& dir, const std::string& prefix) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().rfind(prefix, 0) == 0) ++n;
  return n;
}

class StateStore : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("torqued_state_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    path_ = (dir_ / "sub" / "learned_state.txt").string();
    ctx_ = state_context_from(Config{});  // 4 cylinders, 60-2 wheel, engine_id 1, paper's friction prior
  }
  void TearDown() override { fs::remove_all(dir_); }
  /// A state that passes every check of ctx_.
  LearnedState good(double scale = 1.0) const {
    LearnedState s;
    s.friction = std::array<double, 4>{-23.86 * scale, 2.45e-3, -5.2e-6, -4.67e-3};
    s.friction_idle = std::array<double, 2>{1.4999999999999998, 812.25};
    s.friction_residual = std::array<double, 2>{0.31234567890123456, 87.0};
    s.friction_reference_sd = 2.0615528128088303;
    s.friction_observations = 7.0;
    s.tooth_corrections_rad.assign(58, 0.0);
    s.tooth_corrections_rad[3] = 7.123456789012345e-4 * scale;
    s.inertia = std::array<double, 3>{1.0873456789012345, 4321.5, 0.146722};
    s.burn_phase = std::array<double, 2>{-3.998678044526581, 315.0};
    s.saved_at_t_ns = 12'345'678'901;
    s.identity = ctx_.identity;
    return s;
  }
  void write(const std::string& text) {
    fs::create_directories(fs::path(path_).parent_path());
    std::ofstream(path_, std::ios::binary) << text;
  }
  fs::path dir_;
  std::string path_;
  StateContext ctx_;
};

TEST_F(StateStore, RoundTripIsExactForEveryFieldAndPassesTheChecks) {
  const LearnedState s = good();
  std::string err;
  ASSERT_TRUE(save_state_atomic(path_, s, ctx_.identity, &err)) << err;  // creates the missing directory too
  EXPECT_FALSE(fs::exists(path_ + ".tmp"));
  const auto r = load_state(path_, &err);
  ASSERT_TRUE(r.has_value()) << err;
  EXPECT_EQ(r->friction, s.friction);
  EXPECT_EQ(r->friction_idle, s.friction_idle);
  EXPECT_EQ(r->friction_residual, s.friction_residual);
  EXPECT_EQ(r->friction_reference_sd, s.friction_reference_sd);
  EXPECT_EQ(r->friction_observations, s.friction_observations);
  EXPECT_EQ(r->tooth_corrections_rad, s.tooth_corrections_rad);
  EXPECT_EQ(r->inertia, s.inertia);
  EXPECT_EQ(r->burn_phase, s.burn_phase);
  EXPECT_EQ(r->saved_at_t_ns, s.saved_at_t_ns);
  EXPECT_EQ(r->identity, ctx_.identity);
  EXPECT_TRUE(check_state(*r, ctx_, path_, &err)) << err;
}

TEST_F(StateStore, MalformedLinesAreRefusedNamingFileAndLine) {
  const std::pair<const char*, const char*> cases[] = {
      {"torqued-state 1\nfriction_idle 1.5 0\n", "positive idle speed"},
      {"torqued-state 1\nfriction_idle nan 800\n", "idle friction correction"},
      {"torqued-state 1\nfriction 1 2 3\n", "4 finite friction coefficients"},
      {"torqued-state 1\nfriction 1 2 3 4 5\n", "unexpected '5'"},
      {"torqued-state 3\n", "'torqued-state 2' header"},
      {"torqued-state 1\nwhat 1\n", "unknown key 'what'"},
      {"torqued-state 1\ninertia 1.1 400\n", "inertia scale, its information"},
      {"torqued-state 1\nfriction_residual 0 10\n", "positive motoring residual scale"},
      {"torqued-state 1\nfriction_reference x\n", "1 sigma (N m) of the load references"},
      {"torqued-state 1\nfriction_residual 0.3 -1\n", "positive motoring residual scale"},
      {"torqued-state 1\nfuel_model 0.4 10 1e-4 0 0 1 4 100 0.5\n", "optionally the residual scale"},
      {"torqued-state 2\nidentity x\n", "no checksum line"},
      {"torqued-state 1\nfriction 1 2 3 4", "truncated"},
      {"", "empty file"},
  };
  for (const auto& [text, expect] : cases) {
    write(text);
    std::string err;
    EXPECT_FALSE(load_state(path_, &err).has_value()) << text;
    EXPECT_NE(err.find(path_ + ":"), std::string::npos) << err;
    EXPECT_NE(err.find(expect), std::string::npos) << "got: " << err;
  }
}

TEST_F(StateStore, OneChangedCharacterFailsTheChecksum) {
  // A typo: e-06 -> e+06 in C3.
  std::string text = serialize_state(good(), ctx_.identity);
  const auto at = text.find("e-06");
  ASSERT_NE(at, std::string::npos) << text;
  text[at + 1] = '+';
  write(text);
  std::string err;
  EXPECT_FALSE(load_state(path_, &err).has_value());
  EXPECT_NE(err.find("checksum mismatch"), std::string::npos) << err;
}

// Hostile state (the finding: tooth corrections at 0.95 x the old bound, half a tooth pitch = 2.85 deg, with
// a valid checksum, loaded, and 356/356 cycles published quality 0 with a fused error of 10.4 N m RMS against
// 0.52). The bound is now realistic machining (estimators.tooth_learn.max_correction_deg, 0.5 deg by
// default).
TEST_F(StateStore, ToothCorrectionsBeyondRealisticMachiningAreRefused) {
  const double deg = std::numbers::pi / 180.0;
  LearnedState s = good();
  for (std::size_t i = 0; i < s.tooth_corrections_rad.size(); ++i)
    s.tooth_corrections_rad[i] = (i % 2 ? 2.85 : -2.85) * deg;
  std::string err;
  EXPECT_FALSE(check_state(s, ctx_, "x", &err));
  EXPECT_NE(err.find("tooth correction 0"), std::string::npos) << err;
  EXPECT_NE(err.find("max_correction_deg"), std::string::npos) << err;
  for (double& c : s.tooth_corrections_rad) c *= 0.3 / 2.85;  // 0.3 deg: a coarse but real wheel
  EXPECT_TRUE(check_state(s, ctx_, "x", &err)) << err;
  Config loose;  // the bound is configurable (at most half a tooth pitch)
  loose.estimators.tooth_max_correction_deg = 3.0;
  for (double& c : s.tooth_corrections_rad) c *= 2.85 / 0.3;
  EXPECT_TRUE(check_state(s, state_context_from(loose), "x", &err)) << err;
}

// Hostile file system (the finding: a FIFO as the state file blocked the start-up in open()). It is refused
// at once as not a regular file.
TEST_F(StateStore, FifoInPlaceOfTheStateFileIsRefusedWithoutBlocking) {
  fs::create_directories(fs::path(path_).parent_path());
  ASSERT_EQ(::mkfifo(path_.c_str(), 0600), 0);
  auto result = std::async(std::launch::async, [&] {
    std::string err;
    const bool loaded = load_state(path_, &err).has_value();
    return std::pair{loaded, err};
  });
  if (result.wait_for(std::chrono::seconds(5)) != std::future_status::ready) {
    std::ofstream unblock(path_);  // let the blocked reader finish before failing
    FAIL() << "load_state blocked on a FIFO";
  }
  const auto [loaded, err] = result.get();
  EXPECT_FALSE(loaded);
  EXPECT_NE(err.find("not a regular file"), std::string::npos) << err;
}

TEST_F(StateStore, ValuesOutsidePhysicalBoundsAreRejectedEvenWithAValidChecksum) {
  auto rejects = [&](const LearnedState& s, const char* expect) {
    std::string err;
    EXPECT_FALSE(check_state(s, ctx_, "f", &err)) << expect;
    EXPECT_NE(err.find(expect), std::string::npos) << err;
  };
  LearnedState s = good();
  (*s.friction)[0] = 1e12;  // a friction of 1e12
  rejects(s, "physical bound");
  s = good();
  (*s.friction)[2] = -5.2e6;  // e-06 typed as e+06 in a version-1 file (no checksum to catch it)
  rejects(s, "physical bound");
  s = good();
  (*s.friction)[3] = 0.2;  // e^(0.2 * 200 degC)
  rejects(s, "physical bound");
  s = good();
  (*s.friction_idle)[0] = 5e4;
  rejects(s, "idle friction correction");
  s = good();
  s.tooth_corrections_rad[10] = 0.06;  // > half of a 6 degree pitch (0.052 rad)
  rejects(s, "tooth correction 10");
  s = good();
  s.tooth_corrections_rad.resize(30);  // 30 corrections for a 58-tooth wheel
  rejects(s, "30 tooth corrections, but the wheel has 58 teeth");
  s = good();
  (*s.inertia)[0] = 3.0;  // J three times the spec sheet's
  rejects(s, "inertia scale 3");
  s = good();
  (*s.burn_phase)[0] = 14.0;  // beyond kalman.burn_phase_max_offset_deg (12 deg)
  rejects(s, "burn phase offset 14 deg not in [-12, 12]");
  s = good();
  (*s.inertia)[2] = 0.0;
  rejects(s, "spec J 0");
  s = good();
  (*s.friction_residual)[0] = 1e5;
  rejects(s, "motoring residual scale 100000");
  s = good();
  s.friction.reset();
  s.friction_idle.reset();
  rejects(s, "a motoring residual scale without friction coefficients");
  // The configured prior itself and a learned law 50 % away from it pass.
  std::string err;
  EXPECT_TRUE(check_state(good(1.5), ctx_, "f", &err)) << err;
}

TEST_F(StateStore, AFileOfAnotherEngineOrWheelIsForeign) {
  Config other;
  other.wheel.geometry.positions = 36;
  other.wheel.geometry.missing = 1;
  const StateContext octx = state_context_from(other);
  LearnedState s = good();
  s.identity = octx.identity;
  std::string err;
  EXPECT_FALSE(check_state(s, ctx_, "f", &err));
  EXPECT_NE(err.find("another engine/wheel"), std::string::npos) << err;
  EXPECT_NE(err.find("wheel=36-1"), std::string::npos) << err;
  Config engine2;
  engine2.dds.engine_id = 2;
  EXPECT_NE(state_context_from(engine2).identity, ctx_.identity);
}

TEST_F(StateStore, RejectedFileIsSetAsideAndTheBackupIsUsed) {
  std::string err;
  ASSERT_TRUE(save_state_atomic(path_, good(1.0), ctx_.identity, &err)) << err;
  ASSERT_TRUE(save_state_atomic(path_, good(1.2), ctx_.identity, &err)) << err;  // 1.0 becomes the backup
  ASSERT_TRUE(fs::exists(path_ + ".bak"));
  std::string text = slurp(path_);
  text[text.find("e-06") + 1] = '+';
  write(text);
  const RestoreResult r = restore_learned_state(path_, ctx_);
  ASSERT_TRUE(r.state.has_value());
  EXPECT_EQ(r.state->friction, good(1.0).friction) << "the backup's values";
  ASSERT_EQ(r.warnings.size(), 2u);
  EXPECT_NE(r.warnings[0].find("checksum mismatch"), std::string::npos) << r.warnings[0];
  EXPECT_NE(r.warnings[0].find(".rejected-"), std::string::npos) << r.warnings[0];
  EXPECT_NE(r.warnings[1].find("backup"), std::string::npos) << r.warnings[1];
  EXPECT_FALSE(fs::exists(path_));
  EXPECT_EQ(count_prefixed(fs::path(path_).parent_path(), "learned_state.txt.rejected-"), 1);
  EXPECT_EQ(slurp(r.warnings[0].substr(r.warnings[0].find("moved to ") + 9)), text)
      << "the rejected file is kept byte for byte";
  EXPECT_TRUE(r.may_save);
}

TEST_F(StateStore, WithoutAGoodFileLearningRestartsFromThePrior) {
  LearnedState s = good();
  s.tooth_corrections_rad.resize(30);
  std::string err;
  ASSERT_TRUE(save_state_atomic(path_, s, ctx_.identity, &err)) << err;
  std::ofstream(path_ + ".bak") << "garbage\n";
  const RestoreResult r = restore_learned_state(path_, ctx_);
  EXPECT_FALSE(r.state.has_value());
  ASSERT_EQ(r.warnings.size(), 2u);
  EXPECT_NE(r.warnings[0].find("30 tooth corrections"), std::string::npos) << r.warnings[0];
  EXPECT_NE(r.warnings[1].find(".bak:1:"), std::string::npos) << r.warnings[1];
  ASSERT_EQ(r.infos.size(), 1u);
  EXPECT_NE(r.infos[0].find("restarts from the configured prior"), std::string::npos);
  EXPECT_EQ(count_prefixed(fs::path(path_).parent_path(), "learned_state.txt.rejected-"), 1);
  EXPECT_EQ(count_prefixed(fs::path(path_).parent_path(), "learned_state.txt.bak.rejected-"), 1);
}

TEST_F(StateStore, AnUnreadableFileIsSetAsideNotOverwritten) {
  fs::create_directories(path_);  // a directory: opening succeeds, reading fails (even as root)
  std::ofstream(fs::path(path_) / "x") << "keep me";
  const RestoreResult r = restore_learned_state(path_, ctx_);
  EXPECT_FALSE(r.state.has_value());
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_TRUE(r.may_save);
  EXPECT_FALSE(fs::exists(path_));
  EXPECT_EQ(count_prefixed(fs::path(path_).parent_path(), "learned_state.txt.rejected-"), 1);
}

TEST_F(StateStore, VersionOneFilesAreStillReadAndChecked) {
  write("torqued-state 1\nfriction -23.86 0.00245 -5.2e-06 -0.00467\nsaved_at_t_ns 5\n");
  RestoreResult r = restore_learned_state(path_, ctx_);
  ASSERT_TRUE(r.state.has_value());
  EXPECT_EQ(r.state->version, 1);
  write("torqued-state 1\nfriction -23.86 0.00245 -5.2e+06 -0.00467\nsaved_at_t_ns 5\n");
  r = restore_learned_state(path_, ctx_);
  EXPECT_FALSE(r.state.has_value());
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("physical bound"), std::string::npos) << r.warnings[0];
}

TEST_F(StateStore, SaverReturnsWhileTheDiskIsStuckAndReportsFailures) {
  std::atomic<bool> release{false};
  std::atomic<int> calls{0};
  StateSaver saver([&](const LearnedState& s, std::string* e) {
    ++calls;
    while (!release.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    *e = "disk says no " + std::to_string(s.saved_at_t_ns);
    return false;
  });
  LearnedState s;
  for (int i = 1; i <= 50; ++i) {  // would never return if submit() waited for the stuck writer
    s.saved_at_t_ns = i;
    saver.submit(s);
  }
  EXPECT_LE(calls.load(), 1) << "the writer is still stuck in its first save";
  release = true;
  ASSERT_TRUE(saver.finish(30.0));
  const auto errors = saver.take_errors();
  EXPECT_EQ(saver.failures(), errors.size());
  ASSERT_FALSE(errors.empty());
  EXPECT_EQ(errors.back(), "disk says no 50") << "queued states are replaced: the newest one is written";
  EXPECT_LE(saver.failures(), 2u);
}

TEST_F(StateStore, SaverRefusesToSaveOutOfBoundsValues) {
  StateSaver saver(path_, ctx_);
  LearnedState s = good();
  (*s.friction)[0] = 1e12;
  saver.submit(s);
  ASSERT_TRUE(saver.finish(30.0));
  EXPECT_EQ(saver.failures(), 1u);
  EXPECT_FALSE(fs::exists(path_));
  saver.submit(good());
  ASSERT_TRUE(saver.finish(30.0));
  EXPECT_EQ(saver.saves(), 1u);
  std::string err;
  EXPECT_TRUE(load_state(path_, &err).has_value()) << err;
}

TEST_F(StateStore, Kill9DuringSavesLeavesTheOldOrTheNewFile) {
  // A child saves two alternating states in a loop; it is killed at random moments (many of them inside a
  // save). After each kill the file is one of the two states, complete and passing every check.
  const LearnedState a = good(1.0), b = good(1.3);
  std::string err;
  ASSERT_TRUE(save_state_atomic(path_, a, ctx_.identity, &err)) << err;
  std::mt19937 rng(16);
  int tmp_left = 0;
  for (int round = 0; round < 40; ++round) {
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      for (std::uint64_t i = 0;; ++i) {
        std::string e;
        if (!save_state_atomic(path_, (i & 1) ? a : b, ctx_.identity, &e)) ::_exit(3);
      }
    }
    std::this_thread::sleep_for(
        std::chrono::microseconds(std::uniform_int_distribution<int>(200, 20000)(rng)));
    ::kill(pid, SIGKILL);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the saving child failed on its own (exit " << WEXITSTATUS(status)
                                     << ")";
    tmp_left += fs::exists(path_ + ".tmp");
    const auto s = load_state(path_, &err);
    ASSERT_TRUE(s.has_value()) << "round " << round << ": " << err;
    ASSERT_TRUE(check_state(*s, ctx_, path_, &err)) << err;
    EXPECT_TRUE(s->friction == a.friction || s->friction == b.friction);
    const RestoreResult r = restore_learned_state(path_, ctx_);
    EXPECT_TRUE(r.state.has_value() && r.warnings.empty()) << round;
  }
  EXPECT_GT(tmp_left, 0) << "no kill landed inside a save (between creating and renaming the .tmp file)";
}

}  // namespace
}  // namespace torqued
