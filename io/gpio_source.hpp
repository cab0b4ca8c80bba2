#pragma once
// GPIO live backend: crank (and optionally cam) sensor edges as libgpiod v1 line events with kernel
// timestamps. Both edges of each line are requested (gpiod_line_request_both_edges_events_flags); next()
// polls the lines' event fds plus a stop eventfd for at most poll_timeout_ms, reads the events in batches and
// hands them out in time order. The kernel stamps v1 line events with CLOCK_MONOTONIC (Linux >= 5.7); by
// default they are moved onto CLOCK_REALTIME (the clock of SocketCAN's SO_TIMESTAMPNS) with an offset
// re-measured once a second. next() does not allocate, lock or throw (it makes poll/read system calls: source
// thread only). A repeated level on a line means the kernel's event FIFO lost edges in between: counted in
// stats().dropped.
#include <array>
#include <atomic>
#include <cstdint>
#include <string>

#include "source.hpp"

struct gpiod_chip;
struct gpiod_line;

namespace torqued {

struct GpioConfig {
  std::string chip =
      "gpiochip0";          ///< chip name ("gpiochip0"), number ("0"), path ("/dev/gpiochip0") or label
  int crank_line = -1;      ///< line offset of the crank sensor on the chip (required)
  int cam_line = -1;        ///< line offset of the cam sensor, -1 = none
  bool active_low = false;  ///< invert the levels
  enum class Bias : std::uint8_t { kAsIs = 0, kDisable, kPullUp, kPullDown } bias = Bias::kAsIs;
  std::string consumer = "torqued";  ///< consumer label shown by gpioinfo
  int poll_timeout_ms = 100;         ///< longest wait inside next() (ms), 1 .. 10000
  bool to_realtime = true;           ///< convert CLOCK_MONOTONIC event times to CLOCK_REALTIME
  std::int64_t time_offset_ns = 0;   ///< added to every timestamp
  std::uint8_t crank_channel = 0;    ///< EdgeEvent::channel of crank edges
  std::uint8_t cam_channel = 1;      ///< EdgeEvent::channel of cam edges
};

/// Validates the config without touching hardware; empty string when valid, else what is wrong.
[[nodiscard]] std::string validate(const GpioConfig& cfg);

/// Parses a bias name ("as-is", "disable", "pull-up", "pull-down"); false if unknown.
[[nodiscard]] bool parse_gpio_bias(const std::string& name, GpioConfig::Bias& out) noexcept;

/// Pure conversion of one kernel line event into an EdgeEvent, with lost-edge detection per line.
/// event_type: 1 = rising (GPIOD_LINE_EVENT_RISING_EDGE), 2 = falling. Real-time safe.
class GpioEdgeConverter {
 public:
  explicit GpioEdgeConverter(std::uint8_t channel) noexcept : channel_(channel) {}
  /// Returns false (out untouched) for an unknown event type or a negative timestamp. `offset_ns` is added
  /// to the event time (clock conversion + configured offset).
  bool convert(int event_type, std::int64_t ts_sec, std::int64_t ts_nsec, std::int64_t offset_ns,
               EdgeEvent& out) noexcept;
  /// Edges lost so far: same level twice in a row (at least one opposite edge missing in between).
  [[nodiscard]] std::uint64_t lost() const noexcept { return lost_; }
  /// Events whose time went backwards (kept, counted).
  [[nodiscard]] std::uint64_t backwards() const noexcept { return backwards_; }

 private:
  std::uint8_t channel_;
  int last_level_ = -1;
  std::int64_t last_t_ns_ = 0;
  std::uint64_t lost_ = 0;
  std::uint64_t backwards_ = 0;
};

class GpioEdgeSource final : public EdgeSource {
 public:
  /// Opens the chip and requests the lines. Check ok(); on failure last_error() says what and how to fix it.
  explicit GpioEdgeSource(GpioConfig cfg);
  ~GpioEdgeSource() override;
  GpioEdgeSource(const GpioEdgeSource&) = delete;
  GpioEdgeSource& operator=(const GpioEdgeSource&) = delete;

  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }

  SourceStatus next(EdgeEvent& out) noexcept override;
  [[nodiscard]] const SourceStats& stats() const noexcept override { return stats_; }
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string last_error() const override { return error_; }
  void request_stop() noexcept override;

 private:
  static constexpr int kBatch = 16;
  struct Line {
    gpiod_line* line = nullptr;
    int fd = -1;
    GpioEdgeConverter conv{0};
    std::array<EdgeEvent, kBatch> buf{};
    int n = 0, i = 0;
  };
  bool request(Line& l, int offset, std::uint8_t channel, const char* what);
  int read_line(Line& l) noexcept;  ///< reads pending events into l.buf; returns count, -1 on error
  void refresh_offset() noexcept;

  GpioConfig cfg_;
  std::string error_;
  gpiod_chip* chip_ = nullptr;
  std::array<Line, 2> lines_{};
  int num_lines_ = 0;
  int stop_fd_ = -1;
  std::atomic<bool> stop_{false};
  std::int64_t offset_ns_ = 0;
  std::int64_t next_refresh_mono_ns_ = 0;
  SourceStats stats_;
};

}  // namespace torqued
