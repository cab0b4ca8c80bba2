#pragma once
// Test helper: plain TCP clients on 127.0.0.1 for the web servers' hostile-peer tests (held connections,
// trickled headers, WebSocket clients that never read). Every call has a deadline; nothing leaves loopback.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <string>

namespace torqued::test {

/// A connected loopback socket (closed on destruction); fd() < 0 when the connection failed.
class LoopbackSocket {
 public:
  explicit LoopbackSocket(int port, int rcvbuf = 0) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) return;
    if (rcvbuf > 0) ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~LoopbackSocket() {
    if (fd_ >= 0) ::close(fd_);
  }
  LoopbackSocket(const LoopbackSocket&) = delete;
  LoopbackSocket& operator=(const LoopbackSocket&) = delete;
  [[nodiscard]] int fd() const noexcept { return fd_; }

  bool send_all(const std::string& s) {
    std::size_t off = 0;
    while (off < s.size()) {
      const ssize_t n = ::send(fd_, s.data() + off, s.size() - off, MSG_NOSIGNAL);
      if (n <= 0) return false;
      off += static_cast<std::size_t>(n);
    }
    return true;
  }
  /// Reads until the peer closes, `until` appears or the deadline passes; returns what was read.
  std::string read_for(std::chrono::milliseconds deadline, const std::string& until = "") {
    std::string out;
    const auto end = std::chrono::steady_clock::now() + deadline;
    char buf[65536];
    for (;;) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
      if (left.count() <= 0) break;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) break;
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) break;
      out.append(buf, static_cast<std::size_t>(n));
      if (!until.empty() && out.find(until) != std::string::npos) break;
    }
    return out;
  }

 private:
  int fd_ = -1;
};

/// One GET on a fresh connection; the response (headers and body) or "" when none came within `deadline`.
inline std::string http_get(int port, const std::string& path, std::chrono::milliseconds deadline) {
  LoopbackSocket s(port);
  if (s.fd() < 0) return "";
  if (!s.send_all("GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")) return "";
  return s.read_for(deadline);
}

/// A minimal WebSocket client (RFC 6455) on a LoopbackSocket: handshake with a subprotocol, masked text
/// frames out, frames in (pings answered). Enough for the servers' hostile-peer tests, nothing more.
class WsClient {
 public:
  WsClient(int port, const std::string& path, const std::string& protocol, int rcvbuf = 0)
      : s_(port, rcvbuf) {
    if (s_.fd() < 0) return;
    s_.send_all("GET " + path +
                " HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n" +
                (protocol.empty() ? "" : "Sec-WebSocket-Protocol: " + protocol + "\r\n") + "\r\n");
    buf_ = s_.read_for(std::chrono::milliseconds(3000), "\r\n\r\n");
    const auto end = buf_.find("\r\n\r\n");
    ok_ = buf_.rfind("HTTP/1.1 101", 0) == 0 && end != std::string::npos;
    if (end != std::string::npos) buf_.erase(0, end + 4);
  }
  [[nodiscard]] bool ok() const noexcept { return ok_; }
  bool send_text(const std::string& text) { return s_.send_all(frame(0x1, text)); }

  /// Reads frames for up to `deadline`; calls on_frame(opcode, payload) for each data frame. Returns false
  /// when the connection closed.
  template <class F>
  bool read_frames(std::chrono::milliseconds deadline, F&& on_frame) {
    const auto end = std::chrono::steady_clock::now() + deadline;
    for (;;) {
      while (parse_one(on_frame)) {
      }
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
      if (left.count() <= 0) return true;
      pollfd p{s_.fd(), POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) return true;
      char tmp[65536];
      const ssize_t n = ::recv(s_.fd(), tmp, sizeof tmp, 0);
      if (n <= 0) return false;
      buf_.append(tmp, static_cast<std::size_t>(n));
    }
  }

 private:
  static std::string frame(int opcode, const std::string& payload) {
    std::string f;
    f += static_cast<char>(0x80 | opcode);
    const std::size_t n = payload.size();
    if (n < 126) {
      f += static_cast<char>(0x80 | n);
    } else {
      f += static_cast<char>(0x80 | 126);
      f += static_cast<char>((n >> 8) & 0xff);
      f += static_cast<char>(n & 0xff);
    }
    const char mask[4] = {0x12, 0x34, 0x56, 0x78};
    f.append(mask, 4);
    for (std::size_t i = 0; i < n; ++i) f += static_cast<char>(payload[i] ^ mask[i % 4]);
    return f;
  }
  template <class F>
  bool parse_one(F& on_frame) {
    if (buf_.size() < 2) return false;
    const auto* b = reinterpret_cast<const unsigned char*>(buf_.data());
    const int opcode = b[0] & 0x0f;
    std::uint64_t len = b[1] & 0x7f;
    std::size_t head = 2;
    if (len == 126) {
      if (buf_.size() < 4) return false;
      len = (std::uint64_t{b[2]} << 8) | b[3];
      head = 4;
    } else if (len == 127) {
      if (buf_.size() < 10) return false;
      len = 0;
      for (int i = 0; i < 8; ++i) len = (len << 8) | b[2 + i];
      head = 10;
    }
    if (buf_.size() < head + len) return false;
    const std::string payload = buf_.substr(head, static_cast<std::size_t>(len));
    buf_.erase(0, head + static_cast<std::size_t>(len));
    if (opcode == 0x9) {
      s_.send_all(frame(0xA, payload));  // pong
    } else if (opcode == 0x1 || opcode == 0x2) {
      on_frame(opcode, payload);
    }
    return true;
  }

  LoopbackSocket s_;
  std::string buf_;
  bool ok_ = false;
};

}  // namespace torqued::test
