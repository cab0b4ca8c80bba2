// tests/integration/test_faults.cpp: the real torqued binary against faults of its files.
//   - kill -9 during a paced --record run: every recording has its rows up to at most ~1 s before the kill
//     (timed flush), complete rows only (but the very last, which the kill may cut inside one write(2));
//   - a full disk (/dev/full behind each recording file): the error is logged, the estimation still runs to
//   the
//     end, and the exit status is non-zero;
//   - a corrupt or foreign learned-state file: set aside with a warning naming it, never overwritten,
//   learning
//     restarts from the prior, and the daemon saves a new valid file.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "config_loader.hpp"
#include "daemon_test.hpp"
#include "process.hpp"
#include "sample_recorder.hpp"
#include "state_store.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

class Faults : public test::DaemonTest {
 protected:
  Faults() : DaemonTest("torqued_faults_") {}
};

/// Data lines of a CSV file (header dropped) and whether its last line was complete.
std::vector<std::string> rows(const std::string& path, bool* last_complete) {
  const std::string text = test::slurp(path);
  *last_complete = text.empty() || text.back() == '\n';
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) out.push_back(line);
  return out;
}

int columns(const std::string& line) {
  return 1 + static_cast<int>(std::count(line.begin(), line.end(), ','));
}

TEST_F(Faults, Kill9DuringARecordingLosesAtMostAboutOneSecond) {
  const std::string rec = (dir_ / "rec").string();
  test::Process d(args({"--replay", "paced", "--speed", "1", "--record", rec}), {},
                  (dir_ / "daemon.log").string());
  ASSERT_TRUE(test::eventually(20, [&] { return log().find("running") != std::string::npos; })) << log();
  std::this_thread::sleep_for(std::chrono::milliseconds(3500));
  d.signal(SIGKILL);
  ASSERT_TRUE(d.wait(5));
  // Source time of the newest row of any file: the daemon's progress at the kill (paced at 1x).
  std::int64_t newest = 0;
  std::vector<std::pair<std::string, std::int64_t>> last;
  for (const char* name : dds::SampleRecorder::kFileNames) {
    bool complete = true;
    const auto r = rows(rec + "/" + name, &complete);
    ASSERT_FALSE(r.empty()) << name << " has no rows after 3.5 s (0-byte files: no timed flush)";
    const std::string header =
        test::slurp(rec + "/" + name).substr(0, test::slurp(rec + "/" + name).find('\n'));
    for (std::size_t i = 0; i + (complete ? 0 : 1) < r.size(); ++i)
      ASSERT_EQ(columns(r[i]), columns(header)) << name << " row " << i << ": " << r[i];
    const std::string& l = r[r.size() - (complete || r.size() == 1 ? 1 : 2)];
    last.emplace_back(name, std::stoll(l.substr(0, l.find(','))));
    newest = std::max(newest, last.back().second);
  }
  for (const auto& [name, t] : last)
    EXPECT_GE(t, newest - 1'500'000'000) << name << ": more than 1.5 s of rows lost";
  EXPECT_GT(newest, 2'000'000'000) << "the replay ran for at least 2 s of source time";
}

TEST_F(Faults, AFullDiskIsReportedAndTheEstimationGoesOn) {
  const fs::path rec = dir_ / "rec";
  fs::create_directories(rec);
  for (const char* name : dds::SampleRecorder::kFileNames) fs::create_symlink("/dev/full", rec / name);
  test::Process d(args({"--replay", "fast", "--record", rec.string()}), {}, (dir_ / "daemon.log").string());
  ASSERT_TRUE(d.wait(60)) << log();
  EXPECT_EQ(d.exit_code(), 3) << log();
  const std::string l = log();
  EXPECT_NE(l.find("No space left on device"), std::string::npos) << l;
  EXPECT_NE(l.find("rows not recorded"), std::string::npos) << l;
  const auto at = l.find("fast replay: ");
  ASSERT_NE(at, std::string::npos) << "the replay ran to its end: " << l;
  EXPECT_EQ(l.find(" 0 cycles", at), std::string::npos) << l;
}

TEST_F(Faults, ACorruptLearnedStateIsSetAsideAndReplaced) {
  const fs::path sdir = dir_ / "state";
  fs::create_directories(sdir);
  const std::string path = (sdir / "learned_state.txt").string();
  // A version-1 file with a typo (C3 e-06 -> e+06): no checksum to catch it, the bounds do.
  const std::string bad = "torqued-state 1\nfriction -23.86 0.00245 -5.2e+06 -0.00467\nsaved_at_t_ns 5\n";
  std::ofstream(path) << bad;
  {
    test::Process d(args({"--replay", "paced", "--speed", "4"}), {}, (dir_ / "daemon.log").string());
    ASSERT_TRUE(test::eventually(30, [&] {
      std::string e;
      auto s = load_state(path, &e);
      return s && s->version == 2 && s->friction.has_value();
    })) << log();
    d.signal(SIGTERM);
    ASSERT_TRUE(d.wait(10));
  }
  const std::string l = log();
  EXPECT_NE(l.find("<4>learned state rejected: " + path), std::string::npos) << l;
  EXPECT_NE(l.find("physical bound"), std::string::npos) << l;
  EXPECT_EQ(l.find("learned state loaded"), std::string::npos) << l;
  int aside = 0;
  for (const auto& e : fs::directory_iterator(sdir))
    if (e.path().filename().string().rfind("learned_state.txt.rejected-", 0) == 0) {
      ++aside;
      EXPECT_EQ(test::slurp(e.path().string()), bad) << "kept byte for byte";
    }
  EXPECT_EQ(aside, 1);
  std::string err;
  const auto s = load_state(path, &err);
  ASSERT_TRUE(s.has_value()) << err;
  const LoadResult cfg = load_config(config_);
  ASSERT_TRUE(cfg.ok());
  EXPECT_TRUE(check_state(*s, state_context_from(*cfg.config), path, &err)) << err;
}

}  // namespace
}  // namespace torqued
