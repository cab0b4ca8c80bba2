#include "state_store.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace torqued {
namespace {
std::string errno_text(const std::string& what) { return what + ": " + std::strerror(errno); }
}  // namespace

bool save_state_atomic(const std::string& path, const LearnedState& s, std::string* error) {
  std::string text = "torqued-state 1\n";
  char buf[64];
  if (s.friction) {
    text += "friction";
    for (double c : *s.friction) {
      std::snprintf(buf, sizeof buf, " %.17g", c);
      text += buf;
    }
    text += '\n';
  }
  if (s.friction_idle) {
    std::snprintf(buf, sizeof buf, "friction_idle %.17g %.17g\n", (*s.friction_idle)[0], (*s.friction_idle)[1]);
    text += buf;
  }
  if (!s.tooth_corrections_rad.empty()) {
    text += "tooth_corrections " + std::to_string(s.tooth_corrections_rad.size());
    for (double c : s.tooth_corrections_rad) {
      std::snprintf(buf, sizeof buf, " %.17g", c);
      text += buf;
    }
    text += '\n';
  }
  text += "saved_at_t_ns " + std::to_string(s.saved_at_t_ns) + "\n";

  const std::filesystem::path p(path);
  std::error_code ec;
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path(), ec);
  const std::string tmp = path + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    if (error) *error = errno_text("open " + tmp);
    return false;
  }
  std::size_t off = 0;
  while (off < text.size()) {
    const ssize_t n = ::write(fd, text.data() + off, text.size() - off);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (error) *error = errno_text("write " + tmp);
      ::close(fd);
      return false;
    }
    off += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    if (error) *error = errno_text("fsync " + tmp);
    ::close(fd);
    return false;
  }
  ::close(fd);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    if (error) *error = errno_text("rename " + tmp + " -> " + path);
    return false;
  }
  const std::string dir = p.has_parent_path() ? p.parent_path().string() : ".";
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);  // make the rename itself durable
    ::close(dfd);
  }
  return true;
}

std::optional<LearnedState> load_state(const std::string& path, std::string* error) {
  std::ifstream f(path);
  if (!f) {
    if (error) *error = path + ": cannot open (" + std::strerror(errno) + ")";
    return std::nullopt;
  }
  LearnedState s;
  std::string line;
  int lineno = 0;
  auto fail = [&](const std::string& what) {
    if (error) *error = path + ":" + std::to_string(lineno) + ": " + what;
    return std::nullopt;
  };
  while (std::getline(f, line)) {
    ++lineno;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key.empty() || key[0] == '#') continue;
    if (lineno == 1) {
      int version = 0;
      if (key != "torqued-state" || !(ls >> version) || version != 1)
        return fail("expected 'torqued-state 1' header");
      continue;
    }
    if (key == "friction") {
      std::array<double, 4> c{};
      for (double& v : c)
        if (!(ls >> v) || !std::isfinite(v)) return fail("expected 4 finite friction coefficients");
      s.friction = c;
    } else if (key == "friction_idle") {
      std::array<double, 2> v{};
      if (!(ls >> v[0] >> v[1]) || !std::isfinite(v[0]) || !std::isfinite(v[1]) || !(v[1] > 0.0))
        return fail("expected an idle friction correction (N m) and a positive idle speed (rpm)");
      s.friction_idle = v;
    } else if (key == "tooth_corrections") {
      std::size_t n = 0;
      if (!(ls >> n) || n > 720) return fail("expected a tooth count (<= 720)");
      s.tooth_corrections_rad.resize(n);
      for (double& v : s.tooth_corrections_rad)
        if (!(ls >> v) || !std::isfinite(v)) return fail("expected " + std::to_string(n) + " finite corrections");
    } else if (key == "saved_at_t_ns") {
      if (!(ls >> s.saved_at_t_ns)) return fail("expected an integer time");
    } else {
      return fail("unknown key '" + key + "'");
    }
  }
  if (lineno == 0) return fail("empty file");
  return s;
}

}  // namespace torqued
