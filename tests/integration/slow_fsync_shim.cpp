// tests/integration/slow_fsync_shim.cpp: LD_PRELOAD shim for the slow-storage stop test (slow_fsync_stop.sh):
// every fsync/fdatasync sleeps SLOW_FSYNC_S seconds (default 8) before the real call, as a disk that takes
// that long to flush would. Test-only; never linked into the daemon.
#include <dlfcn.h>
#include <time.h>

#include <cstdlib>

namespace {
void slow_down() {
  const char* v = std::getenv("SLOW_FSYNC_S");
  const double s = v != nullptr ? std::atof(v) : 8.0;
  timespec ts{static_cast<time_t>(s),
              static_cast<long>((s - static_cast<double>(static_cast<time_t>(s))) * 1e9)};
  while (nanosleep(&ts, &ts) != 0) {
  }
}
}  // namespace

extern "C" int fsync(int fd) {
  using Fn = int (*)(int);
  static const auto real = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "fsync"));
  slow_down();
  return real(fd);
}

extern "C" int fdatasync(int fd) {
  using Fn = int (*)(int);
  static const auto real = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "fdatasync"));
  slow_down();
  return real(fd);
}
