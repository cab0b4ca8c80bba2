#include "gpio_source.hpp"

#include <gpiod.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

namespace torqued {
namespace {

std::int64_t clock_ns(clockid_t c) noexcept {
  timespec ts{};
  clock_gettime(c, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

std::string validate(const GpioConfig& cfg) {
  if (cfg.chip.empty()) return "gpio: chip is empty (expected e.g. gpiochip0, 0 or /dev/gpiochip0)";
  if (cfg.crank_line < 0) return "gpio: crank_line must be given (line offset on the chip, >= 0)";
  if (cfg.cam_line < -1) return "gpio: cam_line must be -1 (none) or a line offset >= 0";
  if (cfg.cam_line == cfg.crank_line) return "gpio: crank_line and cam_line must differ";
  if (cfg.poll_timeout_ms < 1 || cfg.poll_timeout_ms > 10000)
    return "gpio: poll_timeout_ms must be 1 .. 10000";
  if (cfg.consumer.empty() || cfg.consumer.size() > 31) return "gpio: consumer label must be 1 .. 31 chars";
  if (cfg.crank_channel == cfg.cam_channel) return "gpio: crank_channel and cam_channel must differ";
  return {};
}

bool parse_gpio_bias(const std::string& name, GpioConfig::Bias& out) noexcept {
  if (name == "as-is")
    out = GpioConfig::Bias::kAsIs;
  else if (name == "disable")
    out = GpioConfig::Bias::kDisable;
  else if (name == "pull-up")
    out = GpioConfig::Bias::kPullUp;
  else if (name == "pull-down")
    out = GpioConfig::Bias::kPullDown;
  else
    return false;
  return true;
}

bool GpioEdgeConverter::convert(int event_type, std::int64_t ts_sec, std::int64_t ts_nsec,
                                std::int64_t offset_ns, EdgeEvent& out) noexcept {
  if (event_type != GPIOD_LINE_EVENT_RISING_EDGE && event_type != GPIOD_LINE_EVENT_FALLING_EDGE) return false;
  if (ts_sec < 0 || ts_nsec < 0 || ts_nsec >= 1'000'000'000) return false;
  const int level = event_type == GPIOD_LINE_EVENT_RISING_EDGE ? 1 : 0;
  const std::int64_t t_ns = ts_sec * 1'000'000'000 + ts_nsec + offset_ns;
  if (last_level_ == level) ++lost_;  // an opposite edge went missing (kernel FIFO overflow or glitch)
  if (last_level_ >= 0 && t_ns < last_t_ns_) ++backwards_;
  last_level_ = level;
  last_t_ns_ = t_ns;
  out.t_ns = t_ns;
  out.channel = channel_;
  out.level = static_cast<std::uint8_t>(level);
  return true;
}

GpioEdgeSource::GpioEdgeSource(GpioConfig cfg) : cfg_(std::move(cfg)) {
  error_ = validate(cfg_);
  if (!error_.empty()) return;
  chip_ = gpiod_chip_open_lookup(cfg_.chip.c_str());
  if (chip_ == nullptr) {
    error_ = "gpio: cannot open chip '" + cfg_.chip + "': " + std::strerror(errno ? errno : ENOENT) +
             " (expected a name like gpiochip0, a number or a /dev/gpiochipN path; `gpiodetect` lists them)";
    return;
  }
  if (!request(lines_[0], cfg_.crank_line, cfg_.crank_channel, "crank")) return;
  num_lines_ = 1;
  if (cfg_.cam_line >= 0) {
    if (!request(lines_[1], cfg_.cam_line, cfg_.cam_channel, "cam")) return;
    num_lines_ = 2;
  }
  stop_fd_ = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (stop_fd_ < 0) {
    error_ = std::string("gpio: eventfd: ") + std::strerror(errno);
    return;
  }
  refresh_offset();
}

bool GpioEdgeSource::request(Line& l, int offset, std::uint8_t channel, const char* what) {
  const unsigned n = gpiod_chip_num_lines(chip_);
  if (static_cast<unsigned>(offset) >= n) {
    error_ = std::string("gpio: ") + what + "_line " + std::to_string(offset) + " is not on chip '" +
             cfg_.chip + "' (it has " + std::to_string(n) + " lines: 0 .. " +
             std::to_string(n == 0 ? 0 : n - 1) + ")";
    return false;
  }
  l.line = gpiod_chip_get_line(chip_, static_cast<unsigned>(offset));
  if (l.line == nullptr) {
    error_ = std::string("gpio: ") + what + "_line " + std::to_string(offset) + ": " + std::strerror(errno);
    return false;
  }
  int flags = 0;
  if (cfg_.active_low) flags |= GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW;
  switch (cfg_.bias) {
    case GpioConfig::Bias::kAsIs:
      break;
    case GpioConfig::Bias::kDisable:
      flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_DISABLE;
      break;
    case GpioConfig::Bias::kPullUp:
      flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP;
      break;
    case GpioConfig::Bias::kPullDown:
      flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_DOWN;
      break;
  }
  if (gpiod_line_request_both_edges_events_flags(l.line, cfg_.consumer.c_str(), flags) < 0) {
    const int err = errno;
    const char* user = gpiod_line_consumer(l.line);
    error_ = std::string("gpio: cannot request edge events on ") + what + "_line " + std::to_string(offset) +
             " of '" + cfg_.chip + "': " + std::strerror(err) +
             (err == EBUSY && user ? std::string(" (in use by '") + user + "')" : std::string());
    l.line = nullptr;
    return false;
  }
  l.fd = gpiod_line_event_get_fd(l.line);
  l.conv = GpioEdgeConverter(channel);
  return true;
}

GpioEdgeSource::~GpioEdgeSource() {
  for (Line& l : lines_) {
    if (l.line != nullptr) gpiod_line_release(l.line);
  }
  if (chip_ != nullptr) gpiod_chip_close(chip_);
  if (stop_fd_ >= 0) ::close(stop_fd_);
}

std::string GpioEdgeSource::describe() const {
  std::string s = "gpio " + cfg_.chip + " crank line " + std::to_string(cfg_.crank_line);
  if (cfg_.cam_line >= 0) s += ", cam line " + std::to_string(cfg_.cam_line);
  return s + (cfg_.to_realtime ? " (CLOCK_REALTIME)" : " (CLOCK_MONOTONIC)");
}

void GpioEdgeSource::request_stop() noexcept {
  stop_.store(true, std::memory_order_relaxed);
  if (stop_fd_ >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t n = ::write(stop_fd_, &one, sizeof one);
  }
}

void GpioEdgeSource::refresh_offset() noexcept {
  const std::int64_t mono = clock_ns(CLOCK_MONOTONIC);
  offset_ns_ = cfg_.time_offset_ns + (cfg_.to_realtime ? clock_ns(CLOCK_REALTIME) - mono : 0);
  next_refresh_mono_ns_ = mono + 1'000'000'000;
}

int GpioEdgeSource::read_line(Line& l) noexcept {
  gpiod_line_event ev[kBatch];
  const int n = gpiod_line_event_read_fd_multiple(l.fd, ev, kBatch);
  if (n < 0) return -1;
  l.n = l.i = 0;
  for (int k = 0; k < n; ++k) {
    const std::uint64_t lost_before = l.conv.lost();
    if (l.conv.convert(ev[k].event_type, ev[k].ts.tv_sec, ev[k].ts.tv_nsec, offset_ns_,
                       l.buf[static_cast<std::size_t>(l.n)])) {
      ++l.n;
    } else {
      ++stats_.bad_lines;
    }
    stats_.dropped += l.conv.lost() - lost_before;
  }
  return l.n;
}

SourceStatus GpioEdgeSource::next(EdgeEvent& out) noexcept {
  if (!error_.empty()) return SourceStatus::kError;
  for (int round = 0; round < 2; ++round) {
    // Two lines: before handing out a buffered event, pick up what the other (empty) line has pending, so a
    // cam edge is never handed out after a later crank edge (the decoder needs non-decreasing times). One
    // zero-time-out poll per edge, only while the other line's buffer is empty.
    if (num_lines_ == 2) {
      for (int k = 0; k < 2; ++k) {
        Line& other = lines_[static_cast<std::size_t>(1 - k)];
        const Line& mine = lines_[static_cast<std::size_t>(k)];
        if (mine.i < mine.n && other.i >= other.n) {
          pollfd q{other.fd, POLLIN, 0};
          if (::poll(&q, 1, 0) > 0 && (q.revents & (POLLIN | POLLPRI)) && read_line(other) < 0)
            ++stats_.bad_lines;
        }
      }
    }
    // Hand out the earliest buffered event over both lines (each line's events are in order).
    int best = -1;
    for (int k = 0; k < num_lines_; ++k) {
      const Line& l = lines_[static_cast<std::size_t>(k)];
      if (l.i < l.n &&
          (best < 0 || l.buf[static_cast<std::size_t>(l.i)].t_ns <
                           lines_[static_cast<std::size_t>(best)]
                               .buf[static_cast<std::size_t>(lines_[static_cast<std::size_t>(best)].i)]
                               .t_ns)) {
        best = k;
      }
    }
    if (best >= 0) {
      Line& l = lines_[static_cast<std::size_t>(best)];
      out = l.buf[static_cast<std::size_t>(l.i++)];
      ++stats_.records;
      return SourceStatus::kOk;
    }
    if (stop_.load(std::memory_order_relaxed)) return SourceStatus::kEnd;
    if (round == 1) break;
    if (clock_ns(CLOCK_MONOTONIC) >= next_refresh_mono_ns_) refresh_offset();
    pollfd p[3] = {{stop_fd_, POLLIN, 0}, {lines_[0].fd, POLLIN, 0}, {lines_[1].fd, POLLIN, 0}};
    const int r = ::poll(p, static_cast<nfds_t>(1 + num_lines_), cfg_.poll_timeout_ms);
    if (r < 0) return SourceStatus::kWouldBlock;  // EINTR
    if (p[0].revents & POLLIN) return SourceStatus::kEnd;
    if (r == 0) return SourceStatus::kWouldBlock;
    for (int k = 0; k < num_lines_; ++k) {
      if (p[1 + k].revents & (POLLIN | POLLPRI)) {
        if (read_line(lines_[static_cast<std::size_t>(k)]) < 0) ++stats_.bad_lines;
      }
    }
  }
  return SourceStatus::kWouldBlock;
}

}  // namespace torqued
