#pragma once
// File backends for crank/cam edges (docs/io.md "Sources"):
//  - EdgeCsvSource: logic-analyzer CSV export (Saleae Logic / sigrok / rusEFI logs): an optional header row
//    naming the columns (first column = time in seconds, plain or exponent notation "8e-05"), one level
//    column per channel. Without a header (first line is a data row) columns are chosen by number (time = 0,
//    crank = 1, cam = 2 if present, or the numbers given as crank_column / cam_column). What the first data
//    row means is a documented option (EdgeCsvFirstRow); each later row emits one EdgeEvent per configured
//    channel whose level changed.
//  - EdgeListSource: bare list, one edge time in seconds per line (all crank edges of the active polarity).
// Both stream the file through a large buffer with a hand-written fixed-point parser (exact ns, no iostreams,
// no std::stod). Bad lines are reported as "file:line: expected ..." (first few kept, all counted) and
// skipped. next() is real-time safe (no allocation) after construction.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "line_reader.hpp"
#include "source.hpp"
#include "time_sanity.hpp"

namespace torqued {

/// What the first data row of an edge CSV means.
enum class EdgeCsvFirstRow : std::uint8_t {
  kInitialLevels,  ///< the levels at capture start: no edge (Saleae / sigrok exports start with the idle
                   ///< state)
  kEdgesFromLow,   ///< every channel starts low: a 1 in the first row is a rising edge (rusEFI's CSV reader)
};

struct EdgeCsvOptions {
  /// Crank column: header name (case-insensitive, trimmed) or column number (1 = first after time). Without a
  /// header, the default name "crank" means column 1.
  std::string crank_column = "crank";
  /// Cam column: name or number as above; empty = no cam. Without a header, the default name "cam" means
  /// column 2 when the rows have one, else no cam.
  std::string cam_column = "cam";
  EdgeCsvFirstRow first_row = EdgeCsvFirstRow::kInitialLevels;
  std::uint8_t crank_channel = 0;   ///< EdgeEvent::channel given to crank edges
  std::uint8_t cam_channel = 1;     ///< EdgeEvent::channel given to cam edges
  std::int64_t time_offset_ns = 0;  ///< added to every time
  TimeSanityOptions time;           ///< outliers and clock jumps (io/time_sanity.hpp)
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
  [[nodiscard]] std::vector<std::string> input_messages() const override { return messages_; }
  /// Messages for the first bad lines (up to 20), "file:line: ..." each, then (once the file has ended) one
  /// line counting the rest, and a warning for a file without data rows. Not real-time.
  [[nodiscard]] const std::vector<std::string>& bad_line_messages() const noexcept { return messages_; }
  [[nodiscard]] bool has_header() const noexcept { return has_header_; }

 private:
  void bad_line(const char* what) noexcept;
  std::size_t parse_row_fast(const char* p, std::size_t avail, std::int64_t& t, int& crank,
                             int& cam) const noexcept;
  bool parse_row(std::string_view line, std::int64_t& t, int& crank, int& cam) noexcept;
  bool resolve_columns(std::string_view first_line);
  SourceStatus finish() noexcept;
  void push_event(const EdgeEvent& e) noexcept;

  std::string path_;
  EdgeCsvOptions opt_;
  TimeSanity<EdgeEvent> sanity_;
  bool eof_ = false;
  LineReader reader_;
  bool ok_ = false;
  bool initial_ = true;  ///< next data row is the first one (see EdgeCsvFirstRow)
  bool has_header_ = true;
  bool first_row_pending_ =
      false;  ///< headerless: the first data row (read while opening) is still to be used
  std::string first_row_text_;
  bool finished_ = false;
  std::uint64_t data_rows_ = 0;
  int crank_col_ = -1, cam_col_ = -1, columns_ = 0;
  std::array<std::uint8_t, 2> level_{};
  std::int64_t time_scale_div_ = 1;  ///< header time unit: [s] 1, [ms] 1e3, [us] 1e6, [ns] 1e9
  SourceStats stats_;
  std::string error_;
  std::vector<std::string> messages_;
};

struct EdgeListOptions {
  std::uint8_t channel = 0;  ///< channel given to every edge
  std::uint8_t level = 1;    ///< level given to every edge (1: the wheel's rising edges)
  std::int64_t time_offset_ns = 0;
  TimeSanityOptions time;  ///< outliers and clock jumps (io/time_sanity.hpp)
};

class EdgeListSource final : public EdgeSource {
 public:
  EdgeListSource(std::string path, EdgeListOptions options = {});
  [[nodiscard]] bool ok() const noexcept { return ok_; }

  SourceStatus next(EdgeEvent& out) noexcept override;
  [[nodiscard]] const SourceStats& stats() const noexcept override { return stats_; }
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string last_error() const override { return error_; }
  [[nodiscard]] std::vector<std::string> input_messages() const override { return messages_; }
  [[nodiscard]] const std::vector<std::string>& bad_line_messages() const noexcept { return messages_; }

 private:
  std::string path_;
  EdgeListOptions opt_;
  TimeSanity<EdgeEvent> sanity_;
  bool eof_ = false;
  LineReader reader_;
  bool ok_ = false;
  SourceStats stats_;
  std::string error_;
  std::vector<std::string> messages_;
};

}  // namespace torqued
