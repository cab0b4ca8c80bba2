#pragma once
// Test helper: run a program in another process with extra environment, output to a file; wait with a
// time-out; signal it. POSIX only.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace torqued::test {

class Process {
 public:
  Process(const std::vector<std::string>& argv, const std::vector<std::string>& env,
          const std::string& log_path) {
    pid_ = ::fork();
    if (pid_ == 0) {
      const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
      }
      for (const auto& e : env) ::putenv(const_cast<char*>(e.c_str()));
      std::vector<char*> a;
      for (const auto& s : argv) a.push_back(const_cast<char*>(s.c_str()));
      a.push_back(nullptr);
      ::execv(a[0], a.data());
      ::_exit(127);
    }
  }
  ~Process() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      wait(5.0);
    }
  }
  [[nodiscard]] pid_t pid() const { return pid_; }
  void signal(int sig) const { ::kill(pid_, sig); }
  [[nodiscard]] bool running() {
    if (exited_) return false;
    int st = 0;
    const pid_t r = ::waitpid(pid_, &st, WNOHANG);
    if (r == pid_) {
      exited_ = true;
      status_ = st;
    }
    return !exited_;
  }
  /// Waits up to timeout_s; returns true when the process exited.
  bool wait(double timeout_s) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (running() && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return !running();
  }
  /// Exit code (or 128 + signal number).
  [[nodiscard]] int exit_code() const {
    if (WIFEXITED(status_)) return WEXITSTATUS(status_);
    if (WIFSIGNALED(status_)) return 128 + WTERMSIG(status_);
    return -1;
  }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  int status_ = 0;
};

inline std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Polls until pred() or the time-out; returns pred().
template <class P>
bool eventually(double timeout_s, P&& pred) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!pred()) {
    if (std::chrono::steady_clock::now() >= until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

/// The demo configuration rewritten with absolute paths into `dir` (so tests can edit and reload it).
inline std::string write_demo_config(const std::string& dir, const std::string& extra_replace_from = "",
                                     const std::string& extra_replace_to = "") {
  const std::string src = std::string(TORQUED_SOURCE_DIR) + "/config/demo.yaml";
  std::string y = slurp(src);
  auto replace_all = [&](const std::string& from, const std::string& to) {
    for (std::size_t p = 0; (p = y.find(from, p)) != std::string::npos; p += to.size())
      y.replace(p, from.size(), to);
  };
  replace_all("../data/demo/", std::string(TORQUED_SOURCE_DIR) + "/data/demo/");
  replace_all("dbc: demo.dbc", std::string("dbc: ") + TORQUED_SOURCE_DIR + "/config/demo.dbc");
  // These tests stop the daemon themselves (signals, kill -9, reloads): it keeps running at the end of the
  // recording instead of exiting there (replay.exit_when_done defaults on; --exit-when-done still forces it).
  replace_all("  speed: 1.0", "  speed: 1.0\n  exit_when_done: false");
  if (!extra_replace_from.empty()) replace_all(extra_replace_from, extra_replace_to);
  const std::string path = dir + "/torqued.yaml";
  std::ofstream(path) << y;
  return path;
}

}  // namespace torqued::test
