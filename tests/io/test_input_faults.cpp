// Bad inputs of the readers: over-long lines (skipped in block reads), DBC VAL_ out of the
// int64 range (was an out-of-range float->int cast: UB).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "dbc.hpp"
#include "line_reader.hpp"
#include "signal_store.hpp"

namespace torqued {
namespace {
namespace fs = std::filesystem;

TEST(LineReaderLong, A12MegabyteLineIsCutAndSkippedAndTheNextLinesAreIntact) {
  const fs::path p = fs::temp_directory_path() / ("torqued_long_" + std::to_string(::getpid()));
  {
    std::ofstream f(p, std::ios::binary);
    f << "first\n" << std::string(12u << 20, 'x') << "\nsecond\r\nthird";
  }
  LineReader r;
  ASSERT_TRUE(r.open(p.string(), 1u << 16));
  std::string_view line;
  ASSERT_TRUE(r.next(line));
  EXPECT_EQ(line, "first");
  ASSERT_TRUE(r.next(line));
  EXPECT_TRUE(r.truncated());
  EXPECT_EQ(line.size(), 1u << 16) << "the first buffer-full of the long line";
  EXPECT_TRUE(r.buffered().empty()) << "fast-path parsers must not see the rest of the long line";
  ASSERT_TRUE(r.next(line));
  EXPECT_FALSE(r.truncated());
  EXPECT_EQ(line, "second");
  EXPECT_EQ(r.line_number(), 3u);
  ASSERT_TRUE(r.next(line));
  EXPECT_EQ(line, "third");
  EXPECT_FALSE(r.next(line));
  EXPECT_EQ(r.bytes(), fs::file_size(p));
  fs::remove(p);
}

TEST(LineReaderLong, AnOverLongLastLineEndsTheFile) {
  const fs::path p = fs::temp_directory_path() / ("torqued_long2_" + std::to_string(::getpid()));
  std::ofstream(p, std::ios::binary) << "a\n" << std::string(100'000, 'y');
  LineReader r;
  ASSERT_TRUE(r.open(p.string(), 4096));
  std::string_view line;
  ASSERT_TRUE(r.next(line));
  ASSERT_TRUE(r.next(line));
  EXPECT_TRUE(r.truncated());
  EXPECT_FALSE(r.next(line));
  EXPECT_EQ(r.bytes(), fs::file_size(p));
  fs::remove(p);
}

TEST(LineReaderSized, AFileThatIsOneLongLineIsNotCut) {
  // GIVEN files that are a single line without '\n', up to exactly the default buffer size
  // WHEN read with the default buffer (sized down to the file for small files)
  // THEN the one line comes back whole, not flagged truncated, and the reader then ends.
  const fs::path p = fs::temp_directory_path() / ("torqued_oneline_" + std::to_string(::getpid()));
  for (const std::size_t n : {std::size_t{1}, std::size_t{4095}, std::size_t{4096}, std::size_t{4097},
                              std::size_t{100'000}, LineReader::kDefaultBuffer}) {
    std::ofstream(p, std::ios::binary | std::ios::trunc) << std::string(n, 'x');
    LineReader r;
    ASSERT_TRUE(r.open(p.string()));
    std::string_view line;
    ASSERT_TRUE(r.next(line)) << n;
    EXPECT_EQ(line.size(), n);
    EXPECT_FALSE(r.truncated()) << n;
    EXPECT_FALSE(r.next(line)) << n;
    EXPECT_EQ(r.bytes(), n);
  }
  fs::remove(p);
}

constexpr const char* kDbc = R"(VERSION ""
BU_: ECU
BO_ 256 ENGINE_1: 8 ECU
 SG_ MAP : 16|16@1+ (0.01,0) [0|300] "kPa" Vector__XXX
 SG_ TooFar : 60|16@1+ (1,0) [0|0] "" Vector__XXX
)";

TEST(DbcFaults, AValueTableEntryBeyondInt64IsAnErrorNotUndefinedBehaviour) {
  // Fuzzing found VAL_ 1e308 cast to int64 (UB). fuzz/corpus/dbc/val_1e308.dbc is the same input.
  for (const char* v : {"1e308", "-1e19", "18446744073709551616"}) {  // 2^64: past unsigned 64-bit too
    const std::string text = std::string(kDbc) + "VAL_ 256 MAP " + v + " \"huge\" ;\n";
    const DbcParseResult r = DbcDatabase::parse_string(text, "t.dbc");
    ASSERT_EQ(r.errors.size(), 1u) << v;
    EXPECT_NE(r.errors[0].find("t.dbc:6: VAL_"), std::string::npos) << r.errors[0];
  }
  const DbcParseResult ok =
      DbcDatabase::parse_string(std::string(kDbc) + "VAL_ 256 MAP -9.2e18 \"low\" 3 \"x\" ;\n");
  EXPECT_TRUE(ok.errors.empty());
}

TEST(DbcFaults, ASignalOutsideItsMessageIsAWarningWithFileAndLine) {
  const DbcParseResult r = DbcDatabase::parse_string(kDbc, "t.dbc");
  ASSERT_TRUE(r.errors.empty());
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("t.dbc:5:"), std::string::npos) << r.warnings[0];
  EXPECT_NE(r.warnings[0].find("TooFar"), std::string::npos) << r.warnings[0];
}

TEST(SignalStoreFaults, ShortFramesAreNamedOnceWithTheFirstFrameAndCounted) {
  const DbcParseResult r = DbcDatabase::parse_string(kDbc, "t.dbc");
  ASSERT_TRUE(r.db.has_value());
  SignalStore store(*r.db);
  std::string err;
  ASSERT_TRUE(store.bind(Quantity::kMap, "ENGINE_1", "MAP", 100'000'000, &err)) << err;
  EXPECT_TRUE(store.describe_bad_frames().empty());
  CanFrame f;
  f.id = 256;
  f.len = 3;  // MAP needs bytes 2..3: 4 bytes
  for (int i = 0; i < 5; ++i) {
    f.t_ns = 1'500'000'000 + i;
    EXPECT_FALSE(store.on_frame(f));
  }
  f.len = 8;
  EXPECT_TRUE(store.on_frame(f));
  EXPECT_EQ(store.stats().bad_frames, 5u);
  const auto lines = store.describe_bad_frames();
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(
      lines[0],
      "CAN frame 0x100 (ENGINE_1) at t=1.500000 s: 3 data bytes, ENGINE_1.MAP needs 4 (DBC DLC 8); 5 such "
      "frames");
}

}  // namespace
}  // namespace torqued
