#include "socketcan_source.hpp"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>

namespace torqued {
namespace {

static_assert(sizeof(can_filter) == 2 * sizeof(std::uint32_t), "can_filter layout");

std::int64_t now_ns(clockid_t clock) noexcept {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

bool is_link_error(int err) noexcept { return err == ENETDOWN || err == ENODEV || err == ENXIO; }

}  // namespace

const char* to_string(CanLinkState s) noexcept {
  switch (s) {
    case CanLinkState::kUp:
      return "up";
    case CanLinkState::kDown:
      return "down";
    case CanLinkState::kMissing:
      return "missing";
    case CanLinkState::kError:
      return "error";
  }
  return "unknown";
}

std::string validate(const SocketCanConfig& cfg) {
  if (cfg.interface.empty()) return "socketcan: interface name is empty";
  if (cfg.interface.size() >= IFNAMSIZ) {
    return "socketcan: interface name '" + cfg.interface + "' longer than " + std::to_string(IFNAMSIZ - 1) +
           " chars";
  }
  if (cfg.interface.find_first_of("/ \t") != std::string::npos) {
    return "socketcan: interface name '" + cfg.interface + "' contains '/' or blanks";
  }
  if (cfg.poll_timeout_ms < 1 || cfg.poll_timeout_ms > 10000)
    return "socketcan: poll_timeout_ms must be 1 .. 10000";
  if (cfg.reopen_interval_ms < 1 || cfg.reopen_interval_ms > 60000) {
    return "socketcan: reopen_interval_ms must be 1 .. 60000";
  }
  if (cfg.rcvbuf_bytes < 0) return "socketcan: rcvbuf_bytes must be >= 0";
  if (cfg.filters.size() > CAN_RAW_FILTER_MAX) return "socketcan: more than 512 filters";
  for (const CanIdFilter& f : cfg.filters) {
    const std::uint32_t lim = f.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
    if (f.id > lim) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "socketcan: filter id 0x%X out of range for a %s id", f.id,
                    f.extended ? "29-bit" : "11-bit");
      return buf;
    }
  }
  return {};
}

SocketCanSource::SocketCanSource(SocketCanConfig cfg) : cfg_(std::move(cfg)) {
  config_error_ = validate(cfg_);
  if (!config_error_.empty()) return;
  stop_fd_ = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (stop_fd_ < 0) {
    config_error_ = std::string("socketcan: eventfd: ") + std::strerror(errno);
    return;
  }
  if (!open_socket())
    next_open_ns_ = now_ns(CLOCK_MONOTONIC) + std::int64_t{cfg_.reopen_interval_ms} * 1'000'000;
}

SocketCanSource::~SocketCanSource() {
  close_socket();
  if (stop_fd_ >= 0) ::close(stop_fd_);
}

std::string SocketCanSource::describe() const {
  std::string s = "socketcan " + cfg_.interface + (cfg_.fd ? " (CAN FD)" : " (classic)");
  if (!cfg_.filters.empty()) s += ", " + std::to_string(cfg_.filters.size()) + " id filter(s)";
  return s;
}

std::string SocketCanSource::last_error() const {
  if (!config_error_.empty()) return config_error_;
  return std::string(error_.data());
}

void SocketCanSource::request_stop() noexcept {
  stop_.store(true, std::memory_order_relaxed);
  if (stop_fd_ >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t n = ::write(stop_fd_, &one, sizeof one);
  }
}

void SocketCanSource::set_error(const char* what, int err) noexcept {
  std::snprintf(error_.data(), error_.size(), "%s: %s: %s", cfg_.interface.c_str(), what, std::strerror(err));
}

void SocketCanSource::set_link(CanLinkState s) noexcept {
  if (link_.load(std::memory_order_relaxed) != s) {
    link_.store(s, std::memory_order_relaxed);
    link_changes_.fetch_add(1, std::memory_order_relaxed);
  }
}

void SocketCanSource::close_socket() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  can_stats_.kernel_drops = 0;  // SO_RXQ_OVFL restarts at 0 on a new socket
}

bool SocketCanSource::open_socket() noexcept {
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    ++can_stats_.open_failures;
    set_error(errno == EAFNOSUPPORT || errno == EPROTONOSUPPORT
                  ? "socket(PF_CAN) (kernel without CAN support?)"
                  : "socket(PF_CAN)",
              errno);
    set_link(CanLinkState::kError);
    return false;
  }
  auto fail = [&](const char* what, int err, CanLinkState state) {
    ++can_stats_.open_failures;
    set_error(what, err);
    set_link(state);
    ::close(fd);
    return false;
  };
  ifreq ifr{};
  std::memcpy(ifr.ifr_name, cfg_.interface.c_str(), cfg_.interface.size() + 1);
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
    const int err = errno;
    return fail("no such interface (SIOCGIFINDEX)", err,
                err == ENODEV ? CanLinkState::kMissing : CanLinkState::kError);
  }
  const int ifindex = ifr.ifr_ifindex;
  const int on = 1;
  if (cfg_.fd && ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
    return fail("setsockopt(CAN_RAW_FD_FRAMES)", errno, CanLinkState::kError);
  }
  if (!cfg_.filters.empty()) {
    can_filter f[CAN_RAW_FILTER_MAX];
    std::size_t n = 0;
    for (const CanIdFilter& c : cfg_.filters) {
      // CAN_EFF_FLAG in the mask makes the id type part of the match; CAN_RTR_FLAG excludes remote frames.
      f[n].can_id = c.extended ? (c.id | CAN_EFF_FLAG) : c.id;
      f[n].can_mask = (c.mask & (c.extended ? CAN_EFF_MASK : CAN_SFF_MASK)) | CAN_EFF_FLAG | CAN_RTR_FLAG;
      ++n;
    }
    if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, f, static_cast<socklen_t>(n * sizeof(can_filter))) <
        0) {
      return fail("setsockopt(CAN_RAW_FILTER)", errno, CanLinkState::kError);
    }
  }
  if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) < 0) {
    return fail("setsockopt(SO_TIMESTAMPNS)", errno, CanLinkState::kError);
  }
  if (::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) < 0) {
    return fail("setsockopt(SO_RXQ_OVFL)", errno, CanLinkState::kError);
  }
  if (cfg_.rcvbuf_bytes > 0 &&
      ::setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &cfg_.rcvbuf_bytes, sizeof cfg_.rcvbuf_bytes) < 0 &&
      ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &cfg_.rcvbuf_bytes, sizeof cfg_.rcvbuf_bytes) < 0) {
    return fail("setsockopt(SO_RCVBUF)", errno, CanLinkState::kError);
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifindex;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) {
    const int err = errno;
    return fail("bind", err, err == ENODEV ? CanLinkState::kMissing : CanLinkState::kError);
  }
  if (::ioctl(fd, SIOCGIFFLAGS, &ifr) == 0 && (ifr.ifr_flags & IFF_UP) == 0) {
    // Bound to a down interface: keep the socket (frames flow as soon as it comes up), report it as down.
    fd_ = fd;
    set_error("interface is down", ENETDOWN);
    set_link(CanLinkState::kDown);
  } else {
    fd_ = fd;
    set_link(CanLinkState::kUp);
  }
  if (ever_opened_) ++stats_.reopens;
  ever_opened_ = true;
  return true;
}

bool SocketCanSource::wait_stop(int timeout_ms) noexcept {
  pollfd p{stop_fd_, POLLIN, 0};
  if (::poll(&p, 1, timeout_ms) > 0) return true;
  return stop_.load(std::memory_order_relaxed);
}

// Interface missing or socket failed: retry by name every reopen_interval_ms. kOk when the socket is open.
SourceStatus SocketCanSource::ensure_open() noexcept {
  if (fd_ >= 0) return SourceStatus::kOk;
  const std::int64_t now = now_ns(CLOCK_MONOTONIC);
  if (now < next_open_ns_) {
    const std::int64_t wait_ms = (next_open_ns_ - now) / 1'000'000 + 1;
    return wait_stop(static_cast<int>(wait_ms < cfg_.poll_timeout_ms ? wait_ms : cfg_.poll_timeout_ms))
               ? SourceStatus::kEnd
               : SourceStatus::kWouldBlock;
  }
  if (open_socket()) return SourceStatus::kOk;
  next_open_ns_ = now + std::int64_t{cfg_.reopen_interval_ms} * 1'000'000;
  return SourceStatus::kWouldBlock;
}

// Nothing to read: wait for a frame or a stop request (kOk: read again). While the link is down, the
// interface flags are checked at the reopen rate; frames arriving also prove it is up.
SourceStatus SocketCanSource::wait_readable() noexcept {
  int timeout = cfg_.poll_timeout_ms;
  if (link_.load(std::memory_order_relaxed) == CanLinkState::kDown) {
    ifreq ifr{};
    std::memcpy(ifr.ifr_name, cfg_.interface.c_str(), cfg_.interface.size() + 1);
    if (::ioctl(fd_, SIOCGIFFLAGS, &ifr) == 0 && (ifr.ifr_flags & IFF_UP) != 0) {
      set_link(CanLinkState::kUp);
    } else if (cfg_.reopen_interval_ms < timeout) {
      timeout = cfg_.reopen_interval_ms;
    }
  }
  pollfd p[2] = {{fd_, POLLIN, 0}, {stop_fd_, POLLIN, 0}};
  const int r = ::poll(p, 2, timeout);
  if (r < 0 && errno != EINTR) {
    ++can_stats_.read_errors;
    set_error("poll", errno);
    return SourceStatus::kWouldBlock;
  }
  if ((r > 0 && (p[1].revents & POLLIN)) || stop_.load(std::memory_order_relaxed)) return SourceStatus::kEnd;
  return r <= 0 ? SourceStatus::kWouldBlock : SourceStatus::kOk;
}

// A failed recvmsg (not EAGAIN/EINTR): counted, and a lost link handled (down: keep the socket; gone:
// reopen).
void SocketCanSource::on_read_error(int err) noexcept {
  if (!is_link_error(err)) {
    ++can_stats_.read_errors;
    set_error("recvmsg", err);
    return;
  }
  ++can_stats_.link_losses;
  set_error("recvmsg", err);
  if (err == ENETDOWN) {
    set_link(CanLinkState::kDown);  // binding survives a down/up: keep the socket
  } else {                          // interface unregistered: reopen by name later
    close_socket();
    set_link(CanLinkState::kMissing);
    next_open_ns_ = now_ns(CLOCK_MONOTONIC) + std::int64_t{cfg_.reopen_interval_ms} * 1'000'000;
  }
}

// Control data: kernel receive time (-1 when absent) and the socket's cumulative overflow counter.
std::int64_t SocketCanSource::read_control(msghdr& msg) noexcept {
  std::int64_t t_ns = -1;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SCM_TIMESTAMPNS && c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
      timespec ts;
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      t_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
    } else if (c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(std::uint32_t))) {
      std::uint32_t drops;
      std::memcpy(&drops, CMSG_DATA(c), sizeof drops);
      if (drops != can_stats_.kernel_drops) {
        stats_.dropped += static_cast<std::uint32_t>(drops - can_stats_.kernel_drops);
        can_stats_.kernel_drops = drops;
      }
    }
  }
  return t_ns;
}

// A received frame into `out`; false (counted) for truncated, error and remote frames.
bool SocketCanSource::accept_frame(const canfd_frame& frame, ssize_t n, std::int64_t t_ns,
                                   CanFrame& out) noexcept {
  const bool is_fd = n == static_cast<ssize_t>(CANFD_MTU);
  if (!is_fd && n != static_cast<ssize_t>(CAN_MTU)) {
    ++can_stats_.truncated;
    return false;
  }
  if (frame.can_id & CAN_ERR_FLAG) {
    ++can_stats_.error_frames;
    return false;
  }
  if (frame.can_id & CAN_RTR_FLAG) {
    ++can_stats_.remote_frames;
    return false;
  }
  if (t_ns < 0) {
    ++can_stats_.no_timestamp;
    t_ns = now_ns(CLOCK_REALTIME);
  }
  out.t_ns = t_ns + cfg_.time_offset_ns;
  out.extended = (frame.can_id & CAN_EFF_FLAG) != 0;
  out.id = frame.can_id & (out.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
  out.fd = is_fd;
  const std::uint8_t max_len = is_fd ? CANFD_MAX_DLEN : CAN_MAX_DLEN;
  out.len = frame.len > max_len ? max_len : frame.len;
  out.bus = cfg_.bus;
  std::memcpy(out.data.data(), frame.data, out.len);
  if (out.len < out.data.size()) std::memset(out.data.data() + out.len, 0, out.data.size() - out.len);
  return true;
}

SourceStatus SocketCanSource::next(CanFrame& out) noexcept {
  if (!config_error_.empty()) return SourceStatus::kError;
  if (stop_.load(std::memory_order_relaxed)) return SourceStatus::kEnd;
  if (const SourceStatus st = ensure_open(); st != SourceStatus::kOk) return st;

  canfd_frame frame{};
  iovec iov{&frame, sizeof frame};
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t)) + 64];
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  for (int attempt = 0;; ++attempt) {
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    const ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
    if (n < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      if (err != EAGAIN && err != EWOULDBLOCK) {
        on_read_error(err);
        return SourceStatus::kWouldBlock;
      }
      if (attempt > 0) return SourceStatus::kWouldBlock;  // woke up but nothing to read (error consumed, ...)
      if (const SourceStatus st = wait_readable(); st != SourceStatus::kOk) return st;
      continue;
    }
    const std::int64_t t_ns = read_control(msg);
    if (link_.load(std::memory_order_relaxed) != CanLinkState::kUp) set_link(CanLinkState::kUp);
    if (!accept_frame(frame, n, t_ns, out)) continue;
    ++stats_.records;
    return SourceStatus::kOk;
  }
}

}  // namespace torqued
