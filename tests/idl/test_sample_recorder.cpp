// CSV recorder (idl/sample_recorder) against a full disk: the error is kept and flagged at once,
// every file is cut back to complete rows, the rows not recorded are counted exactly, and recording never
// resumes after the error (a recording is a prefix of complete rows).
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "sample_recorder.hpp"

namespace torqued::dds {
namespace {
namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

AnySample estimator(std::int64_t i) {
  AnySample s;
  s.topic = Topic::kEstimatorTorque;
  s.u.estimator.source_t_ns = i * 1000;
  s.u.estimator.seq = static_cast<std::uint64_t>(i);
  return s;
}

AnySample crank(std::int64_t i) {
  AnySample s;
  s.topic = Topic::kCrankState;
  s.u.crank.source_t_ns = i * 1000;
  s.u.crank.seq = static_cast<std::uint64_t>(i);
  return s;
}

class RecorderFullDisk : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("torqued_rec_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (mounted_) ::umount(dir_.c_str());
    fs::remove_all(dir_);
  }
  fs::path dir_;
  bool mounted_ = false;
};

TEST_F(RecorderFullDisk, ASmallFileSystemFillsUpWithCompleteRowsOnly) {
  // A 256 KiB tmpfs of our own (needs CAP_SYS_ADMIN: skipped without it).
  if (::mount("tmpfs", dir_.c_str(), "tmpfs", 0, "size=256k") != 0)
    GTEST_SKIP() << "cannot mount a tmpfs here";
  mounted_ = true;
  SampleRecorder rec(dir_.string());
  ASSERT_TRUE(rec.ok()) << rec.error();
  std::uint64_t recorded = 0;
  for (std::int64_t i = 0; i < 200'000 && !rec.write_failed(); ++i, recorded += 2) {
    rec.record(estimator(i));
    rec.record(crank(i));
  }
  ASSERT_TRUE(rec.write_failed()) << "256 KiB cannot hold 400 k rows";
  EXPECT_NE(rec.error().find("No space left on device"), std::string::npos) << rec.error();
  EXPECT_NE(rec.error().find(dir_.string()), std::string::npos) << rec.error();
  for (int i = 0; i < 10; ++i) rec.record(estimator(1'000'000 + i));  // after the error: dropped, counted
  recorded += 10;
  rec.flush(true);
  std::uint64_t on_disk = 0;
  for (const char* name : {"estimator_torque.csv", "crank_state.csv"}) {
    const std::string text = slurp(dir_ / name);
    ASSERT_FALSE(text.empty()) << name;
    EXPECT_EQ(text.back(), '\n') << name << " ends inside a row";
    const auto lines = static_cast<std::uint64_t>(std::count(text.begin(), text.end(), '\n'));
    on_disk += lines - 1;  // header
    const auto header_cols = std::count(text.begin(), text.begin() + text.find('\n'), ',');
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) EXPECT_EQ(std::count(line.begin(), line.end(), ','), header_cols) << line;
  }
  EXPECT_EQ(on_disk + rec.rows_dropped(), recorded) << "every row is on disk or counted as dropped";
  EXPECT_GE(rec.rows_dropped(), 10u);
}

TEST_F(RecorderFullDisk, DevFullIsReportedWithTheFileName) {
  for (const char* name : SampleRecorder::kFileNames) fs::create_symlink("/dev/full", dir_ / name);
  SampleRecorder rec(dir_.string());
  rec.record(estimator(1));
  EXPECT_FALSE(rec.write_failed()) << "nothing written yet (buffered)";
  rec.flush(false);
  ASSERT_TRUE(rec.write_failed());
  EXPECT_NE(rec.error().find("estimator_torque.csv: No space left on device"), std::string::npos)
      << rec.error();
  EXPECT_EQ(rec.rows_dropped(), 1u);
}

TEST_F(RecorderFullDisk, RowsReachTheFileWithoutAnExplicitFlushAtEachStatusRow) {
  SampleRecorder rec(dir_.string());
  rec.record(estimator(1));
  rec.record(estimator(2));
  EXPECT_EQ(slurp(dir_ / "estimator_torque.csv"), "") << "buffered until the timer or a status row";
  AnySample st;
  st.topic = Topic::kDaemonStatus;
  rec.record(st);  // once per status period (1 s by default): every buffer goes to its file
  const std::string text = slurp(dir_ / "estimator_torque.csv");
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 3) << text;
}

TEST_F(RecorderFullDisk, BoundedSyncAtStopWritesEveryBufferAndReportsNothingPendingOnAQuickDisk) {
  SampleRecorder rec(dir_.string());
  rec.record(estimator(1));
  rec.record(crank(1));
  const std::vector<std::string> pending = rec.flush_sync_within(30.0);  // a bound, not an expected time
  EXPECT_TRUE(pending.empty()) << pending.front();
  EXPECT_FALSE(rec.write_failed());
  const std::string est = slurp(dir_ / "estimator_torque.csv");
  const std::string cr = slurp(dir_ / "crank_state.csv");
  EXPECT_EQ(std::count(est.begin(), est.end(), '\n'), 2) << est;
  EXPECT_EQ(std::count(cr.begin(), cr.end(), '\n'), 2) << cr;
}

TEST_F(RecorderFullDisk, AFileThatCannotBeOpenedIsAWriteErrorWithItsRowsCounted) {
  // GIVEN a record directory where estimator_torque.csv cannot be opened for writing (a directory of that
  // name: refused even to root, as a read-only file system refuses it) WHEN a crank row and two estimator
  // rows are recorded and flushed THEN write_failed() is set (the daemon's exit code 3 and its message), the
  // error names the file and the reason, and all three rows are counted as not recorded.
  fs::create_directory(dir_ / "estimator_torque.csv");
  SampleRecorder rec(dir_.string());
  ASSERT_TRUE(rec.ok());
  rec.record(crank(1));
  rec.record(estimator(1));
  rec.record(estimator(2));
  rec.flush(false);
  ASSERT_TRUE(rec.write_failed()) << "an unopenable file was silently not recorded";
  EXPECT_NE(rec.error().find("estimator_torque.csv: Is a directory"), std::string::npos) << rec.error();
  EXPECT_EQ(rec.rows_dropped(), 3u);
}

}  // namespace
}  // namespace torqued::dds
