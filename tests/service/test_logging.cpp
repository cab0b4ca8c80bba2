// service/logging.cpp: journald style has "<N>" priority prefixes and no colour codes; terminal style has
// neither.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>

#include <cstdlib>
#include <sstream>

#include "logging.hpp"

namespace torqued::logging {
namespace {

std::string log_lines(Style style) {
  std::ostringstream os;
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(os);
  auto logger = make_logger("t", style, sink);
  logger->set_level(spdlog::level::trace);
  logger->debug("d {}", 1);
  logger->info("i");
  logger->warn("w");
  logger->error("e");
  logger->critical("c");
  return os.str();
}

TEST(Logging, JournalStyleHasSyslogPrioritiesAndNoColour) {
  EXPECT_EQ(log_lines(Style::kJournal), "<7>d 1\n<6>i\n<4>w\n<3>e\n<2>c\n");
}

TEST(Logging, TerminalStyleIsHumanReadable) {
  const std::string s = log_lines(Style::kTerminal);
  EXPECT_EQ(s.find("<6>"), std::string::npos);
  EXPECT_NE(s.find("warning w"), std::string::npos) << s;
  EXPECT_NE(s.find("info  i"), std::string::npos) << s;
}

// Hostile input (the finding: log lines quoted raw control characters from input files): an ESC sequence
// and a newline in a message are escaped, one message stays one line.
TEST(Logging, ControlCharactersFromInputsAreEscaped) {
  for (const Style style : {Style::kJournal, Style::kTerminal}) {
    std::ostringstream os;
    auto logger = make_logger("t", style, std::make_shared<spdlog::sinks::ostream_sink_mt>(os));
    logger->warn("bad line: '{}'", std::string("a\x1b[2Jb\nforged\x7f\tc"));
    const std::string s = os.str();
    EXPECT_EQ(s.find('\x1b'), std::string::npos) << s;
    EXPECT_EQ(s.find('\x7f'), std::string::npos) << s;
    EXPECT_NE(s.find("'a\\x1b[2Jb\\nforged\\x7f\\tc'"), std::string::npos) << s;
    EXPECT_EQ(s.find('\n'), s.size() - 1) << "one message, one line: " << s;
  }
}

TEST(Logging, UnderSystemdTheJournalStyleIsDetected) {
  ::setenv("JOURNAL_STREAM", "8:12345", 1);
  EXPECT_EQ(detect_style(), Style::kJournal);
  ::unsetenv("JOURNAL_STREAM");
  ::setenv("INVOCATION_ID", "0123456789abcdef", 1);
  EXPECT_EQ(detect_style(), Style::kJournal);
  ::unsetenv("INVOCATION_ID");
}

TEST(Logging, LevelsMapOntoSpdlog) {
  EXPECT_EQ(to_spdlog(LogLevel::kWarn), spdlog::level::warn);
  EXPECT_EQ(to_spdlog(LogLevel::kOff), spdlog::level::off);
  EXPECT_EQ(syslog_priority(spdlog::level::err), 3);
}

}  // namespace
}  // namespace torqued::logging
