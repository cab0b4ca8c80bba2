#pragma once
// File backends for crank/cam edges (DESIGN.md "Input formats"):
//  - EdgeCsvSource: logic-analyzer CSV export (Saleae Logic / sigrok): header row naming the columns (first
//    column = time in seconds), one level column per channel; the first data row gives the initial levels
//    (no edge); each later row emits one EdgeEvent per configured channel whose level changed.
//  - EdgeListSource: bare list, one edge time in seconds per line (all crank edges of the active polarity).
// Both stream the file through a large buffer with a hand-written fixed-point parser (exact ns, no iostreams,
// no std::stod). Bad lines are reported as "file:line: expected ..." (first few kept, all counted) and skipped.
// next() is real-time safe (no allocation) after construction.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "line_reader.hpp"
#include "source.hpp"

namespace torqued {

struct EdgeCsvOptions {
  std::string crank_column = "crank";  ///< header name of the crank channel (case-insensitive, trimmed)
  std::string cam_column = "cam";      ///< header name of the cam channel; empty = no cam
  std::uint8_t crank_channel = 0;      ///< EdgeEvent::channel given to crank edges
  std::uint8_t cam_channel = 1;        ///< EdgeEvent::channel given to cam edges
  std::int64_t time_offset_ns = 0;     ///< added to every time
};

class EdgeCsvSource final : public EdgeSource {
 public:
  /// Opens and reads the header. Check ok(); on failure last_error() says why (file:line).
  EdgeCsvSource(std::string path, EdgeCsvOptions options = {});
  [[nodiscard]] bool ok() const noexcept { return ok_; }

  SourceStatus next(EdgeEvent& out) noexcept override;
  [[nodiscard]] const SourceStats& stats() const noexcept override { return stats_; }
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string last_error() const override { return error_; }
  /// Messages for the first bad lines (up to 20), "file:line: ..." each. Not real-time.
  [[nodiscard]] const std::vector<std::string>& bad_line_messages() const noexcept { return messages_; }

 private:
  void bad_line(const char* what) noexcept;
  std::size_t parse_row_fast(const char* p, std::size_t avail, std::int64_t& t, int& crank, int& cam) const noexcept;
  bool parse_row(std::string_view line, std::int64_t& t, int& crank, int& cam) noexcept;

  std::string path_;
  EdgeCsvOptions opt_;
  LineReader reader_;
  bool ok_ = false;
  bool initial_ = true;          ///< next data row is the initial-levels row
  int crank_col_ = -1, cam_col_ = -1, columns_ = 0;
  std::array<std::uint8_t, 2> level_{};
  std::array<EdgeEvent, 2> pending_{};
  int pending_n_ = 0, pending_i_ = 0;
  std::int64_t last_t_ns_ = 0;
  std::int64_t time_scale_div_ = 1;  ///< header time unit: [s] 1, [ms] 1e3, [us] 1e6, [ns] 1e9
  SourceStats stats_;
  std::string error_;
  std::vector<std::string> messages_;
};

struct EdgeListOptions {
  std::uint8_t channel = 0;        ///< channel given to every edge
  std::uint8_t level = 1;          ///< level given to every edge (1: the wheel's rising edges)
  std::int64_t time_offset_ns = 0;
};

class EdgeListSource final : public EdgeSource {
 public:
  EdgeListSource(std::string path, EdgeListOptions options = {});
  [[nodiscard]] bool ok() const noexcept { return ok_; }

  SourceStatus next(EdgeEvent& out) noexcept override;
  [[nodiscard]] const SourceStats& stats() const noexcept override { return stats_; }
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string last_error() const override { return error_; }
  [[nodiscard]] const std::vector<std::string>& bad_line_messages() const noexcept { return messages_; }

 private:
  std::string path_;
  EdgeListOptions opt_;
  LineReader reader_;
  bool ok_ = false;
  SourceStats stats_;
  std::string error_;
  std::vector<std::string> messages_;
};

}  // namespace torqued
