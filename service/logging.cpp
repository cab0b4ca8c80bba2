#include "logging.hpp"

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdlib>
#include <string>
#include <string_view>

namespace torqued::logging {
namespace {

/// `%*` → "<N>" syslog priority prefix (sd-daemon(3) SD_ERR etc.), understood by journald on stderr.
class PriorityFlag final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    const std::string p = "<" + std::to_string(syslog_priority(msg.level)) + ">";
    dest.append(p.data(), p.data() + p.size());
  }
  [[nodiscard]] std::unique_ptr<custom_flag_formatter> clone() const override {
    return spdlog::details::make_unique<PriorityFlag>();
  }
};

/// `%Q` → the message with control characters escaped: text from input files (a DBC name, a CSV line) can
/// hold an ESC sequence that would repaint a terminal, or a newline that would forge a second journal entry.
/// "\n", "\r", "\t" and "\xNN" (other bytes below 0x20, and 0x7f) instead; everything else is copied.
class EscapedMessage final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    static constexpr char kHex[] = "0123456789abcdef";
    for (const char ch : std::string_view(msg.payload.data(), msg.payload.size())) {
      const auto c = static_cast<unsigned char>(ch);
      if (c >= 0x20 && c != 0x7f) {
        dest.push_back(ch);
        continue;
      }
      const char* named = c == '\n' ? "\\n" : c == '\r' ? "\\r" : c == '\t' ? "\\t" : nullptr;
      if (named != nullptr) {
        dest.append(named, named + 2);
      } else {
        const char esc[4] = {'\\', 'x', kHex[c >> 4], kHex[c & 15]};
        dest.append(esc, esc + 4);
      }
    }
  }
  [[nodiscard]] std::unique_ptr<custom_flag_formatter> clone() const override {
    return spdlog::details::make_unique<EscapedMessage>();
  }
};

std::unique_ptr<spdlog::formatter> make_formatter(Style style) {
  auto f = std::make_unique<spdlog::pattern_formatter>();
  f->add_flag<EscapedMessage>('Q');
  if (style == Style::kJournal) {
    f->add_flag<PriorityFlag>('*').set_pattern("%*%Q");
  } else {
    f->set_pattern("%H:%M:%S.%e %^%-5l%$ %Q");
  }
  return f;
}

}  // namespace

Style detect_style() noexcept {
  if (std::getenv("JOURNAL_STREAM") != nullptr || std::getenv("INVOCATION_ID") != nullptr)
    return Style::kJournal;
  return ::isatty(STDERR_FILENO) ? Style::kTerminal : Style::kJournal;
}

int syslog_priority(spdlog::level::level_enum level) noexcept {
  switch (level) {
    case spdlog::level::trace:
    case spdlog::level::debug:
      return 7;  // LOG_DEBUG
    case spdlog::level::info:
      return 6;  // LOG_INFO
    case spdlog::level::warn:
      return 4;  // LOG_WARNING
    case spdlog::level::err:
      return 3;  // LOG_ERR
    case spdlog::level::critical:
      return 2;  // LOG_CRIT
    default:
      return 6;
  }
}

spdlog::level::level_enum to_spdlog(LogLevel level) noexcept {
  switch (level) {
    case LogLevel::kTrace:
      return spdlog::level::trace;
    case LogLevel::kDebug:
      return spdlog::level::debug;
    case LogLevel::kInfo:
      return spdlog::level::info;
    case LogLevel::kWarn:
      return spdlog::level::warn;
    case LogLevel::kError:
      return spdlog::level::err;
    case LogLevel::kCritical:
      return spdlog::level::critical;
    case LogLevel::kOff:
      return spdlog::level::off;
  }
  return spdlog::level::info;
}

std::shared_ptr<spdlog::logger> make_logger(std::string_view name, Style style, spdlog::sink_ptr sink) {
  sink->set_formatter(make_formatter(style));
  return std::make_shared<spdlog::logger>(std::string(name), std::move(sink));
}

void init(LogLevel level, Style style) {
  spdlog::sink_ptr sink;
  if (style == Style::kTerminal) {
    sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>(spdlog::color_mode::automatic);
  } else {
    sink = std::make_shared<spdlog::sinks::stderr_sink_mt>();  // no colour codes for journald
  }
  auto logger = make_logger("torqued", style, std::move(sink));
  logger->set_level(to_spdlog(level));
  logger->flush_on(spdlog::level::warn);
  spdlog::set_default_logger(std::move(logger));
}

void set_level(LogLevel level) { spdlog::default_logger()->set_level(to_spdlog(level)); }

}  // namespace torqued::logging
