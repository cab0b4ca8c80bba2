#pragma once
// The service manager's notification protocol (systemd's sd_notify(3) and sd_watchdog_enabled(3)), written
// here instead of linking libsystemd: the daemon only sends READY/STATUS/WATCHDOG/RELOADING/STOPPING
// datagrams, and libsystemd with the seven libraries it brings (libgcrypt, liblzma, libzstd, liblz4, libcap,
// …) cost the dynamic loader ≈ 1.9 M instructions at every start (README.md, performance section).
// Protocol: one datagram per message to the AF_UNIX socket named by $NOTIFY_SOCKET (a path, or '@' for the
// abstract namespace); no socket, no message (not run by a service manager). Not real-time: supervisor only.
#include <cstdint>

namespace torqued {

/// Sends `state` (e.g. "READY=1\nSTATUS=running") to $NOTIFY_SOCKET. Returns 1 sent, 0 no socket, < 0 failed.
int sd_notify_state(const char* state) noexcept;
/// sd_notify_state() of a printf-formatted message (truncated at 1 KiB).
[[gnu::format(printf, 1, 2)]] int sd_notify_statef(const char* format, ...) noexcept;
/// Whether the service manager expects WATCHDOG=1 pings: $WATCHDOG_USEC set (and $WATCHDOG_PID, when set,
/// names this process). Returns 1 with `usec` set, 0 not enabled, < 0 malformed variables.
int sd_watchdog_usec(std::uint64_t* usec) noexcept;

}  // namespace torqued
