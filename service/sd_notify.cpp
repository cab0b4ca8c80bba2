#include "sd_notify.hpp"

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstdarg>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace torqued {

int sd_notify_state(const char* state) noexcept {
  const char* path = std::getenv("NOTIFY_SOCKET");
  if (path == nullptr || path[0] == '\0') return 0;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::size_t len = std::strlen(path);
  if ((path[0] != '/' && path[0] != '@') || len >= sizeof addr.sun_path) return -EINVAL;
  std::memcpy(addr.sun_path, path, len);
  if (path[0] == '@') addr.sun_path[0] = '\0';  // abstract namespace
  const auto addr_len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + len);
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -errno;
  // The address is a sockaddr_un viewed as the generic sockaddr the socket calls take (their interface).
  const auto* sa =
      reinterpret_cast<const sockaddr*>(&addr);  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast)
  const ssize_t n = ::sendto(fd, state, std::strlen(state), MSG_NOSIGNAL, sa, addr_len);
  const int err = errno;
  ::close(fd);
  return n < 0 ? -err : 1;
}

int sd_notify_statef(const char* format, ...) noexcept {
  char buf[1024];
  va_list ap;
  va_start(ap, format);
  const int n = std::vsnprintf(buf, sizeof buf, format, ap);
  va_end(ap);
  if (n < 0) return -EINVAL;
  return sd_notify_state(buf);
}

int sd_watchdog_usec(std::uint64_t* usec) noexcept {
  const char* us = std::getenv("WATCHDOG_USEC");
  if (us == nullptr) return 0;
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = std::strtoull(us, &end, 10);
  if (errno != 0 || end == us || *end != '\0' || v == 0) return -EINVAL;
  if (const char* pid = std::getenv("WATCHDOG_PID")) {
    char* pend = nullptr;
    const long p = std::strtol(pid, &pend, 10);
    if (pend == pid || *pend != '\0' || p <= 0) return -EINVAL;
    if (p != static_cast<long>(::getpid())) return 0;  // meant for another process
  }
  if (usec != nullptr) *usec = v;
  return 1;
}

}  // namespace torqued
