#pragma once
// SocketCAN live backend: a CAN_RAW socket bound to a named interface (can0, vcan0).
//  - CAN FD frames when configured (CAN_RAW_FD_FRAMES), classic otherwise;
//  - kernel receive timestamps (SO_TIMESTAMPNS, CLOCK_REALTIME ns) from the recvmsg control data;
//  - kernel filters (CAN_RAW_FILTER) for the configured ids;
//  - kernel queue overflows counted from SO_RXQ_OVFL (stats().dropped);
//  - next() waits at most poll_timeout_ms (poll on the socket and a stop eventfd), then returns kWouldBlock
//  so
//    the source thread can check its stop flag; request_stop() makes it return kEnd;
//  - survives the interface going down or away (ENETDOWN / ENODEV / ENXIO): the error is counted and kept in
//    last_error(), the socket is closed, and every reopen_interval_ms it is reopened by name once the
//    interface exists and is up again (stats().reopens, link_state()).
// next() does not allocate, lock or throw; it makes system calls (poll, recvmsg), so it belongs in a source
// thread, never in a pipeline thread. Single consumer: call next() from one thread.
#include <linux/can.h>
#include <sys/socket.h>
#include <sys/types.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "source.hpp"

namespace torqued {

/// One kernel receive filter: a frame passes when (frame id & mask) == (id & mask) and the id types match.
struct CanIdFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0x1FFFFFFF;  ///< default: exact match
  bool extended = false;
};

struct SocketCanConfig {
  std::string interface = "can0";    ///< interface name (IFNAMSIZ-1 chars at most)
  bool fd = false;                   ///< receive CAN FD frames too (CAN_RAW_FD_FRAMES)
  std::vector<CanIdFilter> filters;  ///< empty: receive every data frame
  int poll_timeout_ms = 100;         ///< longest wait inside next() (ms), 1 .. 10000
  int reopen_interval_ms = 250;      ///< retry period while the interface is down or missing (ms), 1 .. 60000
  int rcvbuf_bytes = 0;              ///< socket receive buffer (SO_RCVBUF(FORCE)), 0 = kernel default
  std::uint8_t bus = 0;              ///< CanFrame::bus given to the frames
  std::int64_t time_offset_ns = 0;   ///< added to every timestamp
};

/// Validates the config; returns an empty string when valid, else what is wrong.
[[nodiscard]] std::string validate(const SocketCanConfig& cfg);

enum class CanLinkState : std::uint8_t {
  kUp = 0,       ///< socket open, interface up
  kDown = 1,     ///< interface exists but is down (waiting)
  kMissing = 2,  ///< no interface of that name (waiting)
  kError = 3,    ///< socket could not be created/bound for another reason (waiting)
};
[[nodiscard]] const char* to_string(CanLinkState s) noexcept;

/// Counters beyond SourceStats (plain counters; read them from the thread that calls next()).
struct SocketCanStats {
  std::uint64_t link_losses = 0;    ///< times the open socket reported ENETDOWN/ENODEV/ENXIO
  std::uint64_t open_failures = 0;  ///< failed open attempts (interface down/missing, ...)
  std::uint64_t read_errors = 0;    ///< other recvmsg errors
  std::uint64_t truncated = 0;      ///< frames of an unexpected size (skipped)
  std::uint64_t error_frames = 0;   ///< CAN error frames (skipped)
  std::uint64_t remote_frames = 0;  ///< RTR frames (skipped: they carry no data)
  std::uint64_t no_timestamp = 0;   ///< frames without a kernel timestamp (CLOCK_REALTIME used instead)
  std::uint32_t kernel_drops = 0;   ///< last SO_RXQ_OVFL value (cumulative per socket)
};

class SocketCanSource final : public CanSource {
 public:
  /// Validates the config and tries to open the socket once. A missing or down interface is not fatal: next()
  /// keeps retrying (link_state() says why). An invalid config makes ok() false and next() return kError.
  explicit SocketCanSource(SocketCanConfig cfg);
  ~SocketCanSource() override;
  SocketCanSource(const SocketCanSource&) = delete;
  SocketCanSource& operator=(const SocketCanSource&) = delete;

  [[nodiscard]] bool ok() const noexcept { return config_error_.empty(); }

  SourceStatus next(CanFrame& out) noexcept override;
  [[nodiscard]] const SourceStats& stats() const noexcept override { return stats_; }
  [[nodiscard]] const SocketCanStats& can_stats() const noexcept { return can_stats_; }
  [[nodiscard]] std::string describe() const override;
  /// Most recent error ("vcan0: recvmsg: Network is down"), empty if none yet.
  [[nodiscard]] std::string last_error() const override;
  void request_stop() noexcept override;

  /// Thread-safe view of the link state (for status reports from another thread).
  [[nodiscard]] CanLinkState link_state() const noexcept { return link_.load(std::memory_order_relaxed); }
  /// Number of link state changes so far (thread-safe): a reporter compares it with the value it saw last.
  [[nodiscard]] std::uint64_t link_changes() const noexcept {
    return link_changes_.load(std::memory_order_relaxed);
  }

 private:
  bool open_socket() noexcept;
  void close_socket() noexcept;
  void set_link(CanLinkState s) noexcept;
  void set_error(const char* what, int err) noexcept;
  bool wait_stop(int timeout_ms) noexcept;  ///< sleeps on the stop eventfd; true when stop was requested
  SourceStatus ensure_open() noexcept;
  SourceStatus wait_readable() noexcept;
  void on_read_error(int err) noexcept;
  std::int64_t read_control(msghdr& msg) noexcept;
  bool accept_frame(const canfd_frame& frame, ssize_t n, std::int64_t t_ns, CanFrame& out) noexcept;

  SocketCanConfig cfg_;
  std::string config_error_;
  int fd_ = -1;
  int stop_fd_ = -1;
  std::int64_t next_open_ns_ = 0;  ///< CLOCK_MONOTONIC time of the next reopen attempt
  std::atomic<bool> stop_{false};
  std::atomic<CanLinkState> link_{CanLinkState::kMissing};
  std::atomic<std::uint64_t> link_changes_{0};
  SourceStats stats_;
  SocketCanStats can_stats_;
  std::array<char, 192> error_{};
  bool ever_opened_ = false;
};

}  // namespace torqued
