// File backends: line reader, edge CSV / bare list, candump -l. Bad lines reported with file:line, skipped,
// counted, never fatal; times parsed exactly to the nanosecond.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "alloc_counter.hpp"
#include "candump_source.hpp"
#include "edge_file_source.hpp"
#include "fast_parse.hpp"
#include "io_test_util.hpp"
#include "line_reader.hpp"

namespace torqued {
namespace {

using test::TempFile;

TEST(FastParse, SecondsToNanosecondsIsExact) {
  auto ns = [](const char* s) {
    const char* p = s;
    std::int64_t v = 0;
    EXPECT_TRUE(parse::seconds_to_ns(p, s + std::strlen(s), v)) << s;
    return v;
  };
  EXPECT_EQ(ns("0.000000001"), 1);
  EXPECT_EQ(ns("1700000000.123456"), 1'700'000'000'123'456'000);
  EXPECT_EQ(ns("12.5"), 12'500'000'000);
  EXPECT_EQ(ns("-0.25"), -250'000'000);
  EXPECT_EQ(ns("3"), 3'000'000'000);
  EXPECT_EQ(ns("0.0000000015"), 2);    // rounded on the 10th digit
  const char* huge = "17000000000.5";  // would overflow int64 ns
  const char* q = huge;
  std::int64_t h = 0;
  EXPECT_FALSE(parse::seconds_to_ns(q, huge + std::strlen(huge), h));
  EXPECT_EQ(ns("9200000000.999999999"), 9'200'000'000'999'999'999);
  const char* bad = "abc";
  std::int64_t v = 0;
  const char* p = bad;
  EXPECT_FALSE(parse::seconds_to_ns(p, bad + 3, v));
}

// seconds_to_ns takes 8 digits at a time (SWAR) where 8 bytes remain; hex_digit is a table. Both must agree
// with the digit-by-digit definitions (below, as they were written before) on every input: value, success
// and where the parse stopped.
namespace reference {
bool seconds_to_ns(const char*& p, const char* end, std::int64_t& ns) {
  bool neg = false;
  if (p < end && (*p == '-' || *p == '+')) neg = *p++ == '-';
  std::int64_t whole = 0;
  int digits = 0;
  while (p < end && static_cast<unsigned>(*p - '0') < 10u) {
    whole = whole * 10 + (*p++ - '0');
    if (whole > 9'200'000'000) return false;
    ++digits;
  }
  std::int64_t frac = 0;
  if (p < end && *p == '.') {
    ++p;
    int f = 0;
    while (p < end && static_cast<unsigned>(*p - '0') < 10u) {
      if (f < 9) {
        frac = frac * 10 + (*p - '0');
      } else if (f == 9 && *p >= '5') {
        ++frac;
      }
      ++f;
      ++p;
      ++digits;
    }
    for (int k = f; k < 9; ++k) frac *= 10;
  }
  if (digits == 0) return false;
  ns = whole * 1'000'000'000 + frac;
  if (neg) ns = -ns;
  return true;
}
int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  c = static_cast<char>(c | 0x20);
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}
}  // namespace reference

TEST(FastParse, EightDigitsAtATimeAgreeWithTheDigitByDigitParse) {
  for (int c = 0; c < 256; ++c)
    ASSERT_EQ(parse::hex_digit(static_cast<char>(c)), reference::hex_digit(static_cast<char>(c))) << c;
  // GIVEN random texts: runs of digits (0-21 of them, around 8 and 16 most), a '.', a sign, other bytes after
  // (digit-like bytes '/', ':', 0x1F, 0x3A-0x3F, 0xFA-0xFF next to digits: the SWAR test's edge cases), and
  // the text ending anywhere (fewer than 8 bytes left)
  std::mt19937_64 rng(41);
  const char others[] = {'/', ':',    ';',    '?',    ')',    ' ',    'e',   '.',
                         '-', '\x1f', '\x3a', '\xfa', '\xff', '\x00', '\x80'};
  int ok = 0;
  for (int trial = 0; trial < 200000; ++trial) {
    std::string text;
    if (rng() % 4 == 0) text += rng() % 2 ? '-' : '+';
    auto digits = [&](int n) {
      for (int i = 0; i < n; ++i) text += static_cast<char>('0' + rng() % 10);
    };
    const int w = static_cast<int>(rng() % 3 == 0 ? rng() % 22 : 6 + rng() % 12);
    digits(w);
    if (rng() % 4 != 0) {
      text += '.';
      digits(static_cast<int>(rng() % 3 == 0 ? rng() % 22 : rng() % 12));
    }
    for (int i = static_cast<int>(rng() % 10); i > 0; --i)
      text += rng() % 2 ? others[rng() % sizeof others] : static_cast<char>('0' + rng() % 10);
    const std::size_t cut = rng() % 3 == 0 ? rng() % (text.size() + 1) : text.size();
    // WHEN both parse it
    const char* a = text.data();
    const char* b = text.data();
    std::int64_t va = -1, vb = -1;
    const bool ra = parse::seconds_to_ns(a, text.data() + cut, va);
    const bool rb = reference::seconds_to_ns(b, text.data() + cut, vb);
    // THEN they agree (where a failed parse stopped is not part of the contract)
    ASSERT_EQ(ra, rb) << text.substr(0, cut);
    if (!ra) continue;
    ASSERT_EQ(va, vb) << text.substr(0, cut);
    ASSERT_EQ(a, b) << text.substr(0, cut);
    ++ok;
  }
  EXPECT_GT(ok, 80000);
}

TEST(LineReader, LinesAcrossBufferBoundariesAndCrLf) {
  std::string content;
  for (int i = 0; i < 3000; ++i) content += "line " + std::to_string(i) + (i % 3 ? "\n" : "\r\n");
  content += "last-without-newline";
  TempFile f(content);
  LineReader r;
  ASSERT_TRUE(r.open(f.path(), 4096));
  std::string_view line;
  int n = 0;
  while (r.next(line)) {
    if (n < 3000) {
      ASSERT_EQ(line, "line " + std::to_string(n));
    } else {
      EXPECT_EQ(line, "last-without-newline");
    }
    ++n;
  }
  EXPECT_EQ(n, 3001);
  EXPECT_EQ(r.bytes(), content.size());
  LineReader missing;
  EXPECT_FALSE(missing.open("/nonexistent/file.csv"));
  EXPECT_NE(missing.error().find("/nonexistent/file.csv"), std::string::npos);
}

TEST(EdgeCsv, InitialLevelsThenOneEdgePerChange) {
  TempFile f(
      "Time [s],crank,cam\n"
      "0.000000000,0,1\n"
      "0.000100000,1,1\n"
      "0.000200000,0,0\n"  // both change: two edges, crank first
      "0.000300000,1,0\n"
      "0.000300500,1,1\n");
  EdgeCsvSource src(f.path());
  ASSERT_TRUE(src.ok()) << src.last_error();
  std::vector<EdgeEvent> ev;
  EdgeEvent e;
  while (src.next(e) == SourceStatus::kOk) ev.push_back(e);
  ASSERT_EQ(ev.size(), 5u);
  EXPECT_EQ(ev[0].t_ns, 100'000);
  EXPECT_EQ(ev[0].channel, 0);
  EXPECT_EQ(ev[0].level, 1);
  EXPECT_EQ(ev[1].channel, 0);
  EXPECT_EQ(ev[1].level, 0);
  EXPECT_EQ(ev[2].channel, 1);
  EXPECT_EQ(ev[2].level, 0);
  EXPECT_EQ(ev[4].t_ns, 300'500);
  EXPECT_EQ(ev[4].channel, 1);
  EXPECT_EQ(src.stats().records, 5u);
  EXPECT_EQ(src.stats().bad_lines, 0u);
}

TEST(EdgeCsv, SaleaeStyleConfiguredNamesAndExtraColumns) {
  TempFile f(
      "Time [s], Channel 0, Channel 1, Channel 2\r\n"
      "0.0, 1, 0, 0\r\n"
      "0.5, 0, 0, 1\r\n"
      "1.0, 0, 1, 1\r\n");
  EdgeCsvOptions o;
  o.crank_column = "channel 1";  // case-insensitive
  o.cam_column = "";
  EdgeCsvSource src(f.path(), o);
  ASSERT_TRUE(src.ok()) << src.last_error();
  EdgeEvent e;
  ASSERT_EQ(src.next(e), SourceStatus::kOk);
  EXPECT_EQ(e.t_ns, 1'000'000'000);
  EXPECT_EQ(e.level, 1);
  EXPECT_EQ(src.next(e), SourceStatus::kEnd);
}

TEST(EdgeCsv, MissingColumnNamesTheHeader) {
  TempFile f("Time [s],A,B\n0,0,0\n");
  EdgeCsvSource src(f.path());
  EXPECT_FALSE(src.ok());
  EXPECT_NE(src.last_error().find(":1: no crank column named 'crank'"), std::string::npos)
      << src.last_error();
  EXPECT_NE(src.last_error().find("found: A, B"), std::string::npos);
  EdgeEvent e;
  EXPECT_EQ(src.next(e), SourceStatus::kError);
}

TEST(EdgeCsv, BadLinesAreReportedSkippedAndCounted) {
  // The row behind in time is dropped but its level counts: the next row's rising edge is still seen.
  TempFile f("Time [s],crank,cam\n0,0,0\n0.001,1,0\nxyz,0,0\n0.002,2,0\n0.003,0\n0.0005,0,0\n0.004,1,0\n");
  EdgeCsvSource src(f.path());
  ASSERT_TRUE(src.ok());
  std::vector<EdgeEvent> ev;
  EdgeEvent e;
  while (src.next(e) == SourceStatus::kOk) ev.push_back(e);
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[1].t_ns, 4'000'000);
  EXPECT_EQ(src.stats().bad_lines, 4u);
  ASSERT_EQ(src.bad_line_messages().size(), 4u);
  EXPECT_NE(src.bad_line_messages()[0].find(":4: expected a time"), std::string::npos)
      << src.bad_line_messages()[0];
  EXPECT_NE(src.bad_line_messages()[1].find(":5: expected '<time>,<level 0|1>"), std::string::npos);
  EXPECT_NE(src.bad_line_messages()[3].find(":7: time goes backwards"), std::string::npos);
}

TEST(EdgeCsv, TimeUnitFromHeader) {
  TempFile f("Time [us],crank\n0,0\n1.5,1\n");
  EdgeCsvOptions o;
  o.cam_column = "";
  EdgeCsvSource src(f.path(), o);
  ASSERT_TRUE(src.ok());
  EdgeEvent e;
  ASSERT_EQ(src.next(e), SourceStatus::kOk);
  EXPECT_EQ(e.t_ns, 1500);
}

// The fixed-format fast path ("<s>.<9 digits>,c,c") and the general parser must agree on every line: the same
// rows with a leading space (always the general path) give the same events, bad-line count and messages.
TEST(EdgeCsv, FastPathAgreesWithGeneralParser) {
  std::mt19937 rng(20261121);
  // No e/E: since exponent notation is read, "1.5e7" is a valid time far ahead that would make
  // every later row "time goes backwards"; exponents are covered by EdgeCsv.ExponentNotationIsReadExactly.
  const std::string alphabet = "0123456789.,- x+";
  std::string fast = "Time [s],crank,cam\n", general = fast;
  std::int64_t t = 0;
  int crank = 0, cam = 0;
  for (int i = 0; i < 80000; ++i) {  // > 1 MiB: rows across the line reader's buffer refills
    t += 1 + static_cast<std::int64_t>(rng() % 200'000'000);  // a mutated fraction moves < 1 s
    if (rng() % 3 == 0) crank ^= 1;
    if (rng() % 50 == 0) cam ^= 1;
    char buf[64];
    std::snprintf(buf, sizeof buf, "%lld.%09lld,%d,%d", static_cast<long long>(t / 1'000'000'000),
                  static_cast<long long>(t % 1'000'000'000), crank, cam);
    std::string line = buf;
    // Mutations after the '.' (a larger integer part would make every later row "time goes backwards"):
    // some still valid in another format, most bad.
    const std::size_t dot = line.find('.') + 1;
    auto pos = [&](std::size_t extra) { return dot + rng() % (line.size() - dot + extra); };
    switch (rng() % 16) {
      case 0:
        line[pos(0)] = alphabet[rng() % alphabet.size()];
        break;
      case 1:
        line.erase(pos(0), 1);
        break;
      case 2:
        line.insert(pos(1), 1, alphabet[rng() % alphabet.size()]);
        break;
      case 3:
        line += ",1";
        break;  // extra column
      case 4:
        line.insert(line.find(','), "0");
        break;  // 10 decimals (rounded)
      case 5:
        line.erase(line.find(',') - 1, 1);
        break;  // 8 decimals
      case 6:
        line = "0000000000" + line;
        break;  // 10+ integer digits
      case 7:
        line = (rng() % 2 ? "+" : "-") + line;
        break;  // signs
      default:
        break;
    }
    fast += line + "\n";
    general += " " + line + "\n";
  }
  TempFile ff(fast), fg(general);
  EdgeCsvSource a(ff.path()), b(fg.path());
  ASSERT_TRUE(a.ok() && b.ok());
  EdgeEvent ea, eb;
  std::size_t n = 0;
  for (;;) {
    const SourceStatus sa = a.next(ea), sb = b.next(eb);
    ASSERT_EQ(sa, sb) << "record " << n;
    if (sa != SourceStatus::kOk) break;
    ASSERT_EQ(ea.t_ns, eb.t_ns) << "record " << n;
    ASSERT_EQ(ea.channel, eb.channel) << "record " << n;
    ASSERT_EQ(ea.level, eb.level) << "record " << n;
    ++n;
  }
  EXPECT_GT(n, 20000u);
  EXPECT_GT(a.stats().bad_lines, 400u);
  EXPECT_EQ(a.stats().lines, b.stats().lines);
  EXPECT_EQ(a.stats().bytes + 80000, b.stats().bytes);
  EXPECT_EQ(a.stats().bad_lines, b.stats().bad_lines);
  ASSERT_EQ(a.bad_line_messages().size(), b.bad_line_messages().size());
  for (std::size_t i = 0; i < a.bad_line_messages().size(); ++i) {  // same line numbers and texts
    const auto& ma = a.bad_line_messages()[i];
    const auto& mb = b.bad_line_messages()[i];
    EXPECT_EQ(ma.substr(ma.find(':')), mb.substr(mb.find(':')));
  }
}

TEST(EdgeCsv, FastPathExactNanosecondsAndHeaderUnits) {
  TempFile f("Time [ms],crank,cam\n0.000000000,0,0\n1.000000001,1,0\n123456789.999999999,0,1\n");
  EdgeCsvOptions o;
  o.time.max_jump_ns =
      0;  // parsing only: the 34 h jump would be dropped by the time checks (test_time_sanity)
  EdgeCsvSource src(f.path(), o);
  ASSERT_TRUE(src.ok());
  EdgeEvent e;
  ASSERT_EQ(src.next(e), SourceStatus::kOk);
  EXPECT_EQ(e.t_ns, 1'000'000);  // 1.000000001 ms, truncated to ns like the general parser
  ASSERT_EQ(src.next(e), SourceStatus::kOk);
  EXPECT_EQ(e.t_ns, 123'456'789'999'999);
  EXPECT_EQ(e.channel, 0);
  ASSERT_EQ(src.next(e), SourceStatus::kOk);
  EXPECT_EQ(e.channel, 1);
  EXPECT_EQ(e.level, 1);
  TempFile g("Time [s],crank,cam\n0.000000000,0,0\n9.123456789,1,0\n");
  EdgeCsvSource s2(g.path());
  ASSERT_EQ(s2.next(e), SourceStatus::kOk);
  EXPECT_EQ(e.t_ns, 9'123'456'789);
}

TEST(EdgeCsv, OneEventPerChangedChannelInRowOrder) {
  // initial levels, cam only, no change (a glitch export), both (crank first), crank only, end
  TempFile f(
      "Time [s],crank,cam\n0.000000000,0,0\n0.000000010,0,1\n0.000000020,0,1\n"
      "0.000000030,1,0\n0.000000040,0,0\n");
  EdgeCsvSource src(f.path());
  ASSERT_TRUE(src.ok());
  std::vector<std::tuple<std::int64_t, int, int>> got;
  EdgeEvent e;
  while (src.next(e) == SourceStatus::kOk) got.emplace_back(e.t_ns, e.channel, e.level);
  const std::vector<std::tuple<std::int64_t, int, int>> want{{10, 1, 1}, {30, 0, 1}, {30, 1, 0}, {40, 0, 0}};
  EXPECT_EQ(got, want);
  EXPECT_EQ(src.stats().records, 4u);
}

namespace {
std::vector<EdgeEvent> read_all(EdgeCsvSource& src) {
  std::vector<EdgeEvent> ev;
  EdgeEvent e;
  while (src.next(e) == SourceStatus::kOk) ev.push_back(e);
  return ev;
}
}  // namespace

// Real captures: exports such as rusEFI's noisy-trigger logs print times like "8e-05"; the reader called that
// a bad time. Exponent notation is now read exactly (to the ns, rounded half up).
TEST(EdgeCsv, ExponentNotationIsReadExactly) {
  TempFile f("Time [s],crank\n0,0\n8e-05,1\n1.5E-3,0\n0.00383033,1\n2.5e+0,0\n1.0000000005e1,1\n");
  EdgeCsvOptions o;
  o.cam_column = "";
  o.time.max_jump_ns = 0;  // parsing only: the jumps of 2.5 and 7.5 s are for the time checks to judge
  EdgeCsvSource src(f.path(), o);
  ASSERT_TRUE(src.ok()) << src.last_error();
  const auto ev = read_all(src);
  ASSERT_EQ(ev.size(), 5u) << (src.bad_line_messages().empty() ? "" : src.bad_line_messages()[0]);
  EXPECT_EQ(ev[0].t_ns, 80'000);
  EXPECT_EQ(ev[1].t_ns, 1'500'000);
  EXPECT_EQ(ev[2].t_ns, 3'830'330);
  EXPECT_EQ(ev[3].t_ns, 2'500'000'000);
  EXPECT_EQ(ev[4].t_ns, 10'000'000'005);
  EXPECT_EQ(src.stats().bad_lines, 0u);
}

// Real captures: a file without a header (first line is data) was refused. Columns are then numbered (crank =
// 1, cam = 2 if present) and the first row is data, not lost.
TEST(EdgeCsv, HeaderlessFileUsesColumnNumbers) {
  TempFile f("0,0\n8e-05,1\n0.00383033,0\n");
  EdgeCsvSource src(f.path());  // default names "crank"/"cam": column 1, no cam (only one level column)
  ASSERT_TRUE(src.ok()) << src.last_error();
  EXPECT_FALSE(src.has_header());
  const auto ev = read_all(src);
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[0].t_ns, 80'000);
  EXPECT_EQ(ev[0].level, 1);
  EXPECT_EQ(ev[1].level, 0);

  TempFile g("0.5,1,0,1\n0.6,1,1,0\n0.7,0,1,0\n");
  EdgeCsvOptions o;
  o.crank_column = "3";  // by number
  o.cam_column = "1";
  EdgeCsvSource src2(g.path(), o);
  ASSERT_TRUE(src2.ok()) << src2.last_error();
  const auto ev2 = read_all(src2);
  ASSERT_EQ(ev2.size(), 2u);  // 0.6: crank (col 3) 1->0; 0.7: cam (col 1) 1->0
  EXPECT_EQ(ev2[0].channel, o.crank_channel);
  EXPECT_EQ(ev2[0].level, 0);
  EXPECT_EQ(ev2[1].channel, o.cam_channel);
  EXPECT_EQ(ev2[1].t_ns, 700'000'000);

  EdgeCsvOptions bad;
  bad.crank_column = "7";
  EdgeCsvSource src3(g.path(), bad);
  EXPECT_FALSE(src3.ok());
  EXPECT_NE(src3.last_error().find(":1: no crank column named '7'"), std::string::npos) << src3.last_error();
}

// The first row's meaning is an option: initial levels (no edge, default) or edges from all-low (rusEFI).
TEST(EdgeCsv, FirstRowSemanticsAreSelectable) {
  TempFile f("Time [s],crank,cam\n0.1,1,0\n0.2,0,1\n");
  EdgeCsvSource a(f.path());
  ASSERT_EQ(read_all(a).size(), 2u);  // 0.2: crank falls, cam rises
  EdgeCsvOptions o;
  o.first_row = EdgeCsvFirstRow::kEdgesFromLow;
  EdgeCsvSource b(f.path(), o);
  const auto ev = read_all(b);
  ASSERT_EQ(ev.size(), 3u);
  EXPECT_EQ(ev[0].t_ns, 100'000'000);
  EXPECT_EQ(ev[0].level, 1);
}

// Every rejected line is named once with file:line and what was expected; beyond the first 20 they are
// counted, and the count is reported once at the end.
TEST(EdgeCsv, BadLinesBeyondTheLimitAreCountedOnce) {
  std::string s = "Time [s],crank\n0,0\n";
  for (int i = 0; i < 30; ++i) s += "x,1\n";
  s += "1,1\n";
  TempFile f(s);
  EdgeCsvOptions o;
  o.cam_column = "";
  EdgeCsvSource src(f.path(), o);
  EXPECT_EQ(read_all(src).size(), 1u);
  EdgeEvent e;
  EXPECT_EQ(src.next(e), SourceStatus::kEnd);  // a second end adds nothing
  EXPECT_EQ(src.stats().bad_lines, 30u);
  ASSERT_EQ(src.bad_line_messages().size(), 21u);
  EXPECT_NE(src.bad_line_messages()[0].find(":3: expected a time in seconds"), std::string::npos);
  EXPECT_NE(src.bad_line_messages()[20].find("10 more bad lines not listed (30 in all)"), std::string::npos)
      << src.bad_line_messages()[20];
}

TEST(EdgeCsv, HeaderOnlyFileIsWarnedAbout) {
  TempFile f("Time [s],crank,cam\n");
  EdgeCsvSource src(f.path());
  ASSERT_TRUE(src.ok()) << src.last_error();
  EXPECT_TRUE(read_all(src).empty());
  ASSERT_EQ(src.bad_line_messages().size(), 1u);
  EXPECT_NE(src.bad_line_messages()[0].find(":1: warning: no data rows after the header"), std::string::npos)
      << src.bad_line_messages()[0];
  TempFile empty("");
  EdgeCsvSource src2(empty.path());
  EXPECT_FALSE(src2.ok());
  EXPECT_NE(src2.last_error().find("empty file"), std::string::npos);
}

// Bad input: the fast path accumulated every leading digit into an int64 before checking the count: a long
// digit run was signed overflow (UB; caught by -fsanitize=undefined). Such a row is now left to the general
// parser, which reports it as out of range, and the next row still reads.
TEST(EdgeCsv, LongIntegerPartIsNotUndefinedBehaviour) {
  TempFile f("Time [s],crank,cam\n0.000000000,0,0\n99999999999999999999999.000000000,1,0\n1.000000000,1,0\n");
  EdgeCsvSource src(f.path());
  ASSERT_TRUE(src.ok());
  const auto ev = read_all(src);
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].t_ns, 1'000'000'000);
  EXPECT_EQ(src.stats().bad_lines, 1u);
  ASSERT_FALSE(src.bad_line_messages().empty());
  EXPECT_NE(src.bad_line_messages()[0].find(":3: expected a time"), std::string::npos);
}

TEST(EdgeList, OneTimePerLineWithHeaderAndComments) {
  TempFile f("time\n# comment\n0.001\n0.002\n\nbad\n0.003\n");
  EdgeListSource src(f.path());
  ASSERT_TRUE(src.ok());
  std::vector<std::int64_t> t;
  EdgeEvent e;
  while (src.next(e) == SourceStatus::kOk) t.push_back(e.t_ns);
  EXPECT_EQ(t, (std::vector<std::int64_t>{1'000'000, 2'000'000, 3'000'000}));
  EXPECT_EQ(src.stats().bad_lines, 1u);
  EXPECT_NE(src.last_error().find(":6: expected one edge time"), std::string::npos) << src.last_error();
}

TEST(Candump, ClassicExtendedFdRemoteAndBadLines) {
  TempFile f(
      "(1700000000.000100) can0 100#0011223344556677\n"
      "(1700000000.000200) can0 18FF0000#DEAD\n"
      "(1700000000.000300) vcan1 123##1000102030405060708090A0B\n"
      "(1700000000.000400) can0 7FF#R\n"
      "(1700000000.000500) can0 100#001\n"
      "garbage line\n"
      "(1700000000.000600) can0 800#00\n"
      "(1700000000.000700) can0 101#\n"
      "(1700000000.000800) can0 102#0102030405060708090A\n"
      "(1700000000.000900) can0 103#01 T\n");
  CandumpOptions o;
  o.time_offset_ns = -1'700'000'000'000'000'000;
  CandumpSource src(f.path(), o);
  ASSERT_TRUE(src.ok());
  std::vector<CanFrame> fr;
  CanFrame c;
  while (src.next(c) == SourceStatus::kOk) fr.push_back(c);
  ASSERT_EQ(fr.size(), 5u);
  EXPECT_EQ(fr[0].t_ns, 100'000);
  EXPECT_EQ(fr[0].id, 0x100u);
  EXPECT_FALSE(fr[0].extended);
  EXPECT_EQ(fr[0].len, 8);
  EXPECT_EQ(fr[0].data[7], 0x77);
  EXPECT_TRUE(fr[1].extended);
  EXPECT_EQ(fr[1].id, 0x18FF0000u);
  EXPECT_EQ(fr[1].len, 2);
  EXPECT_TRUE(fr[2].fd);
  EXPECT_EQ(fr[2].len, 12);
  EXPECT_EQ(fr[2].data[11], 0x0B);
  EXPECT_EQ(fr[2].bus, 1);
  EXPECT_EQ(src.bus_name(1), "vcan1");
  EXPECT_EQ(fr[3].len, 0);  // 101#: empty payload is legal
  EXPECT_EQ(fr[4].id, 0x103u);
  EXPECT_EQ(src.rtr_frames(), 1u);
  EXPECT_EQ(src.stats().bad_lines, 4u);
  ASSERT_EQ(src.bad_line_messages().size(), 4u);
  EXPECT_NE(src.bad_line_messages()[0].find(":5: odd number of hex digits"), std::string::npos)
      << src.bad_line_messages()[0];
  EXPECT_NE(src.bad_line_messages()[1].find(":6: expected '(<seconds>)"), std::string::npos);
  EXPECT_NE(src.bad_line_messages()[2].find(":7: standard id above 0x7FF"), std::string::npos);
  EXPECT_NE(src.bad_line_messages()[3].find(":9: classic CAN payload longer than 8 bytes"),
            std::string::npos);
}

TEST(Candump, AnInterfaceNameWithANulByteIsOneBusNamedByTheBytesMatched) {
  // A corrupt log: "can0<NUL>x" is not "can0"; each keeps one bus, and bus_name() gives the bytes matched.
  const std::string text = std::string("(1.000000) can0") + '\0' + "x 100#01\n(1.001000) can0 100#02\n" +
                           "(1.002000) can0" + '\0' + "x 100#03\n";
  TempFile f(text);
  CandumpSource src(f.path());
  ASSERT_TRUE(src.ok());
  std::vector<CanFrame> fr;
  CanFrame c;
  while (src.next(c) == SourceStatus::kOk) fr.push_back(c);
  ASSERT_EQ(fr.size(), 3u);
  EXPECT_EQ(fr[0].bus, 0);
  EXPECT_EQ(fr[1].bus, 1);
  EXPECT_EQ(fr[2].bus, 0);
  EXPECT_EQ(src.bus_name(0), std::string_view("can0\0x", 6));
  EXPECT_EQ(src.bus_name(1), "can0");
}

TEST(Candump, NextDoesNotAllocate) {
  std::string content;
  for (int i = 0; i < 1000; ++i) content += "(1700000000.000100) can0 100#0011223344556677\n";
  TempFile f(content);
  CandumpSource src(f.path());
  CanFrame c;
  int n = 0;
  const test::AllocationScope scope;
  while (src.next(c) == SourceStatus::kOk) ++n;
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_EQ(n, 1000);
}

TEST(Candump, RandomGarbageNeverCrashesAndIsCounted) {
  // Mutated valid lines and random bytes: every line is either a frame or a counted bad line.
  std::mt19937 rng(11);
  const std::string base = "(1700000000.000100) can0 18FF0000##1001122334455667788";
  std::string content;
  std::uint64_t comments = 0;
  const int n = 5000;
  for (int i = 0; i < n; ++i) {
    std::string l = base;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < edits; ++k) {
      const std::size_t pos = rng() % l.size();
      switch (rng() % 3) {
        case 0:
          l[pos] = static_cast<char>(1 + rng() % 255);
          break;
        case 1:
          l.erase(pos, 1 + rng() % 5);
          break;
        default:
          l.insert(pos, 1, "#()R 0F"[rng() % 7]);
          break;
      }
      if (l.empty()) l = "x";
    }
    std::erase(l, '\n');
    std::erase(l, '\r');
    if (l.empty()) l = "x";
    comments += l.front() == '#' ? 1 : 0;  // comment lines are skipped silently
    content += l + "\n";
  }
  TempFile f(content);
  CandumpSource src(f.path());
  CanFrame c;
  std::uint64_t frames = 0;
  while (src.next(c) == SourceStatus::kOk) {
    ++frames;
    EXPECT_LE(c.len, c.fd ? 64 : 8);
  }
  EXPECT_EQ(frames + src.stats().bad_lines + src.rtr_frames() + comments, static_cast<std::uint64_t>(n));
  EXPECT_GT(src.stats().bad_lines, 0u);
}

TEST(Candump, MissingFileIsAnErrorNotACrash) {
  CandumpSource src("/nonexistent/can.log");
  EXPECT_FALSE(src.ok());
  CanFrame c;
  EXPECT_EQ(src.next(c), SourceStatus::kError);
  EXPECT_NE(src.last_error().find("/nonexistent/can.log"), std::string::npos);
}

}  // namespace
}  // namespace torqued
