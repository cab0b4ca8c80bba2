#pragma once
// spdlog set-up for the daemon and tools. On a terminal: human-readable with colours. Under systemd
// (JOURNAL_STREAM or INVOCATION_ID set) or when stderr is not a tty: no colours, no timestamp (journald
// stamps), and an sd-daemon(3)
// "<N>" syslog-priority prefix per line so that journald records the level.
//
// Logging is NEVER called on the real-time path (decoder, estimator update, ring push/pop, pipelines): those
// count events in atomics and the non-real-time supervisor/publisher thread logs the counts.
#include <spdlog/logger.h>
#include <spdlog/sinks/sink.h>

#include <memory>
#include <string_view>

#include "config.hpp"

namespace torqued::logging {

enum class Style { kTerminal, kJournal };

/// kJournal when JOURNAL_STREAM or INVOCATION_ID is set or stderr is not a terminal, else kTerminal.
[[nodiscard]] Style detect_style() noexcept;

/// syslog priority of a spdlog level (sd-daemon(3): <7> debug .. <2> critical).
[[nodiscard]] int syslog_priority(spdlog::level::level_enum level) noexcept;
[[nodiscard]] spdlog::level::level_enum to_spdlog(LogLevel level) noexcept;

/// Logger named `name` writing to `sink` in the given style (tests pass an ostream sink).
[[nodiscard]] std::shared_ptr<spdlog::logger> make_logger(std::string_view name, Style style,
                                                          spdlog::sink_ptr sink);

/// Install the process-wide default logger on stderr (style detected unless given). Call once at start-up.
void init(LogLevel level, Style style = detect_style());

/// Change the default logger's level (e.g. after SIGHUP reload).
void set_level(LogLevel level);

}  // namespace torqued::logging
