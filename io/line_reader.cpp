#include "line_reader.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace torqued {

LineReader::~LineReader() {
  if (fd_ >= 0) ::close(fd_);
}

bool LineReader::open(const std::string& path, std::size_t buffer_bytes) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  size_ = -1;
  if (fd_ < 0) {
    error_ = path + ": " + std::strerror(errno);
    return false;
  }
  struct stat st {};
  if (::fstat(fd_, &st) == 0 && S_ISREG(st.st_mode)) {
    size_ = static_cast<std::int64_t>(st.st_size);
    // Sequential read-ahead: we stream large captures once.
    (void)::posix_fadvise(fd_, 0, 0, POSIX_FADV_SEQUENTIAL);
  }
  // A regular file no larger than the buffer gets a buffer of its size + 1 (at least 4 KiB): small files (and
  // each fuzz input) do not allocate and clear 1 MiB, and the + 1 keeps a file that is one line without '\n',
  // as long as the buffer, from being reported cut.
  constexpr std::size_t kMinBuffer = 4096;
  std::size_t cap = buffer_bytes < kMinBuffer ? kMinBuffer : buffer_bytes;
  if (size_ >= 0 && static_cast<std::uint64_t>(size_) <= cap)
    cap = std::max(kMinBuffer, static_cast<std::size_t>(size_) + 1);
  cap_ = cap;
  buf_ = std::make_unique_for_overwrite<char[]>(cap_);
  begin_ = end_ = 0;
  eof_ = truncated_ = skip_rest_ = false;
  line_no_ = bytes_ = 0;
  error_.clear();
  return true;
}

bool LineReader::refill() noexcept {
  if (eof_ || fd_ < 0) return false;
  if (begin_ > 0) {  // keep the partial line at the front
    std::memmove(buf_.get(), buf_.get() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  if (end_ == cap_) return false;  // a line longer than the buffer
  for (;;) {
    const ssize_t n = ::read(fd_, buf_.get() + end_, cap_ - end_);
    if (n > 0) {
      end_ += static_cast<std::size_t>(n);
      return true;
    }
    if (n == 0) {
      eof_ = true;
      return false;
    }
    if (errno == EINTR) continue;
    error_ = std::strerror(errno);
    eof_ = true;
    return false;
  }
}

bool LineReader::skip_rest_of_line() noexcept {
  for (;;) {
    if (const void* nl = begin_ < end_ ? std::memchr(buf_.get() + begin_, '\n', end_ - begin_) : nullptr) {
      const std::size_t pos = static_cast<std::size_t>(static_cast<const char*>(nl) - buf_.get());
      bytes_ += pos + 1 - begin_;
      begin_ = pos + 1;
      skip_rest_ = false;
      return true;
    }
    bytes_ += end_ - begin_;
    begin_ = end_ = 0;
    if (!refill()) {  // end of file (or error) inside the over-long line
      skip_rest_ = false;
      return false;
    }
  }
}

bool LineReader::next(std::string_view& line) noexcept {
  truncated_ = false;
  if (skip_rest_ && !skip_rest_of_line()) return false;
  std::size_t scan = begin_;
  for (;;) {
    const void* nl = scan < end_ ? std::memchr(buf_.get() + scan, '\n', end_ - scan) : nullptr;
    if (nl != nullptr) {
      const std::size_t pos = static_cast<std::size_t>(static_cast<const char*>(nl) - buf_.get());
      std::size_t len = pos - begin_;
      bytes_ += len + 1;
      if (len > 0 && buf_[begin_ + len - 1] == '\r') --len;
      line = std::string_view(buf_.get() + begin_, len);
      begin_ = pos + 1;
      ++line_no_;
      return true;
    }
    const std::size_t scanned = end_ - begin_;
    if (!refill()) {
      if (end_ > begin_) {  // last line without '\n', or an over-long line
        truncated_ = (end_ - begin_) == cap_;
        std::size_t len = end_ - begin_;
        bytes_ += len;
        if (buf_[begin_ + len - 1] == '\r') --len;
        line = std::string_view(buf_.get() + begin_, len);
        begin_ = end_;
        ++line_no_;
        // An over-long line: its rest is skipped in whole-buffer reads at the next call (`line` still points
        // into the buffer now).
        if (truncated_) skip_rest_ = true;
        return true;
      }
      return false;
    }
    scan = begin_ + scanned;
  }
}

}  // namespace torqued
