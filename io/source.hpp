#pragma once
// The one backend interface of io/ (docs/conventions.md habit 6): pull-based sources of fixed-size records.
// Fast replay calls next() in one thread; the daemon's source threads call next() and try_push into rings.
// Sources only read. Live sources return kWouldBlock when their wait times out (so threads can check stop
// flags).
#include <cstdint>
#include <string>
#include <vector>

#include "records.hpp"

namespace torqued {

enum class SourceStatus : std::uint8_t {
  kOk = 0,          ///< a record was written to the out parameter
  kEnd = 1,         ///< end of file / source closed for good
  kWouldBlock = 2,  ///< live source: nothing arrived within its poll time-out; call again
  kError = 3,       ///< unrecoverable error (message in describe() / last_error())
};

[[nodiscard]] constexpr const char* to_string(SourceStatus s) noexcept {
  switch (s) {
    case SourceStatus::kOk:
      return "ok";
    case SourceStatus::kEnd:
      return "end";
    case SourceStatus::kWouldBlock:
      return "would_block";
    case SourceStatus::kError:
      return "error";
  }
  return "unknown";
}

/// Counters every source keeps. Plain counters: read them from the thread that calls next(), or copy them
/// out at the end; the daemon publishes them.
struct SourceStats {
  std::uint64_t records = 0;  ///< records handed out by next()
  std::uint64_t bad_lines =
      0;                      ///< malformed input lines / frames skipped (file backends: each reported once)
  std::uint64_t dropped = 0;  ///< records lost inside the source (kernel overflow, lost encoder frames, ...)
  std::uint64_t bytes = 0;    ///< input bytes consumed (file backends)
  std::uint64_t lines = 0;    ///< input lines read (file backends)
  std::uint64_t reopens = 0;  ///< live backends: times the device was reopened after an error
  /// File backends (io/time_sanity.hpp): records dropped for their time (behind the time base, or an outlier
  /// far ahead of it); each is also a bad line, named file:line in input_messages().
  std::uint64_t time_outliers = 0;
  std::uint64_t time_rebases = 0;  ///< genuine clock jumps adopted (a run of records in step after the jump)
};

/// End of a line-based file source: final byte and line counts; kError with `error` = "<path>: read error:
/// ..." when the reader failed, else kEnd. `Reader`: LineReader (bytes(), line_number(), error()).
template <class Reader>
SourceStatus finish_lines(const Reader& r, const std::string& path, SourceStats& stats, std::string& error) {
  stats.bytes = r.bytes();
  stats.lines = r.line_number();
  if (!r.error().empty()) {
    error = path + ": read error: " + r.error();
    return SourceStatus::kError;
  }
  return SourceStatus::kEnd;
}

/// Source of crank/cam edge events (edge capture file, bare edge list, GPIO, CAN encoder interface).
class EdgeSource {
 public:
  virtual ~EdgeSource() = default;
  /// Next edge in time order. Real-time safe for file backends after construction (no allocation).
  [[nodiscard]] virtual SourceStatus next(EdgeEvent& out) noexcept = 0;
  [[nodiscard]] virtual const SourceStats& stats() const noexcept = 0;
  /// Human-readable description ("edge-csv data/demo/edges.csv (crank=crank, cam=cam)").
  [[nodiscard]] virtual std::string describe() const = 0;
  /// Last error message (file:line: what was expected), empty if none. Not for the real-time path.
  [[nodiscard]] virtual std::string last_error() const { return {}; }
  /// Ask a blocking live source to return (kEnd) soon; thread-safe. File sources ignore it.
  /// Problems with the input named with file:line (bad lines, the first few; a file without data), for the
  /// log. Call only after next() returned kEnd or kError, from the thread that called it or once that thread
  /// has finished (the list is written by next()).
  [[nodiscard]] virtual std::vector<std::string> input_messages() const { return {}; }
  virtual void request_stop() noexcept {}
};

/// Source of CAN / CAN FD frames (candump log, SocketCAN).
class CanSource {
 public:
  virtual ~CanSource() = default;
  [[nodiscard]] virtual SourceStatus next(CanFrame& out) noexcept = 0;
  [[nodiscard]] virtual const SourceStats& stats() const noexcept = 0;
  [[nodiscard]] virtual std::string describe() const = 0;
  [[nodiscard]] virtual std::string last_error() const { return {}; }
  /// Problems with the input named with file:line (bad lines, the first few; a file without data), for the
  /// log. Call only after next() returned kEnd or kError, from the thread that called it or once that thread
  /// has finished (the list is written by next()).
  [[nodiscard]] virtual std::vector<std::string> input_messages() const { return {}; }
  virtual void request_stop() noexcept {}
};

}  // namespace torqued
