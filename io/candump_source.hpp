#pragma once
// candump -l log reader: "(1700000000.123456) can0 123#DEADBEEF" (classic), 8-hex-digit extended ids,
// remote frames "123#R" / "123#R5", CAN FD "123##<flags><data>". Optional trailing " T"/" R" direction
// markers (candump -x) are accepted. Streams through a large buffer; exact fixed-point timestamps in ns.
// Bad lines are reported "file:line: expected ..." (first 20 kept), counted in stats().bad_lines, skipped;
// never fatal. Interface names map to CanFrame::bus in order of first appearance (0, 1, ...).
// next() is real-time safe after construction (no allocation; bad-line messages — the first 20 — allocate).
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "line_reader.hpp"
#include "source.hpp"
#include "time_sanity.hpp"

namespace torqued {

struct CandumpOptions {
  std::int64_t time_offset_ns = 0;  ///< added to every timestamp (config inputs.can.time_offset_s)
  TimeSanityOptions time;           ///< outliers and clock jumps (io/time_sanity.hpp)
};

class CandumpSource final : public CanSource {
 public:
  CandumpSource(std::string path, CandumpOptions options = {});
  [[nodiscard]] bool ok() const noexcept { return ok_; }

  SourceStatus next(CanFrame& out) noexcept override;
  [[nodiscard]] const SourceStats& stats() const noexcept override { return stats_; }
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string last_error() const override { return error_; }
  [[nodiscard]] std::vector<std::string> input_messages() const override { return messages_; }
  [[nodiscard]] const std::vector<std::string>& bad_line_messages() const noexcept { return messages_; }
  /// Remote (RTR) frames seen; they carry no payload and are skipped.
  [[nodiscard]] std::uint64_t rtr_frames() const noexcept { return rtr_frames_; }
  /// Interface name of bus index i ("can0"), empty if unknown.
  [[nodiscard]] std::string_view bus_name(std::uint8_t bus) const noexcept;

  /// Parse one log line into `out` (no allocation). Returns nullptr on success, "" for a remote frame
  /// (not decoded), else what was expected.
  /// `bus_name` receives the interface name. Exposed for tests and the SocketCAN comparison.
  static const char* parse_line(std::string_view line, CanFrame& out, std::string_view& bus_name) noexcept;

 private:
  std::uint8_t bus_index(std::string_view bus) noexcept;

  std::string path_;
  CandumpOptions opt_;
  CanFrame frame_{};
  TimeSanity<CanFrame> sanity_;
  bool eof_ = false;
  LineReader reader_;
  bool ok_ = false;
  static constexpr int kMaxBuses = 8;
  std::array<std::array<char, 16>, kMaxBuses> bus_names_{};
  std::array<std::uint8_t, kMaxBuses> bus_name_len_{};  ///< strlen of each bus_names_ entry
  int buses_ = 0;
  std::uint64_t rtr_frames_ = 0;
  SourceStats stats_;
  std::string error_;
  std::vector<std::string> messages_;
};

}  // namespace torqued
