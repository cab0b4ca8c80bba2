#pragma once
// Streams a file line by line through one large buffer with read(2): no iostreams, no per-line allocation.
// Lines are returned as views into the buffer (valid until the next call), without the '\n' (and '\r').
// A line longer than the buffer is returned truncated and flagged. Used by every text-file backend.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

namespace torqued {

class LineReader {
 public:
  static constexpr std::size_t kDefaultBuffer = 1u << 20;  ///< 1 MiB

  LineReader() = default;
  ~LineReader();
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  /// Open a file (allocates the buffer). Returns false with error() set ("path: strerror").
  bool open(const std::string& path, std::size_t buffer_bytes = kDefaultBuffer);
  /// Next line; false at end of file or on a read error (then error() is set). Real-time safe (read(2) only).
  bool next(std::string_view& line) noexcept;

  /// Fast-path parsers: the bytes read but not yet consumed, without reading more (may end mid-line).
  [[nodiscard]] std::string_view buffered() const noexcept {
    if (skip_rest_) return {};  // the rest of an over-long line: next() skips it
    return std::string_view(buf_.get() + begin_, end_ - begin_);
  }
  /// Consumes the first `n` bytes of buffered() as one complete line (the caller checked its '\n' is
  /// at n - 1): what next() would have returned, without the memchr.
  void consume_line(std::size_t n) noexcept {
    begin_ += n;
    bytes_ += n;
    ++line_no_;
    truncated_ = false;
  }
  [[nodiscard]] std::uint64_t line_number() const noexcept {
    return line_no_;
  }                                                                      ///< 1-based, of the last line
  [[nodiscard]] std::uint64_t bytes() const noexcept { return bytes_; }  ///< bytes consumed so far
  [[nodiscard]] bool truncated() const noexcept { return truncated_; }   ///< last line was cut
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  [[nodiscard]] std::int64_t file_size() const noexcept { return size_; }  ///< -1 if unknown (pipe)

 private:
  bool refill() noexcept;
  bool skip_rest_of_line() noexcept;  ///< after a truncated line: up to and including its '\n'

  int fd_ = -1;
  std::unique_ptr<char[]> buf_;
  std::size_t cap_ = 0, begin_ = 0, end_ = 0;
  bool eof_ = false, truncated_ = false, skip_rest_ = false;
  std::uint64_t line_no_ = 0, bytes_ = 0;
  std::int64_t size_ = -1;
  std::string error_;
};

}  // namespace torqued
