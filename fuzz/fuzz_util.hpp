#pragma once
// Fuzz helper: the input as a file the readers can open (memfd, no disk), at /proc/self/fd/N.
// One memfd per process, rewritten for each input (ftruncate + pwrite): creating and closing a memfd per
// input cost more than the parsing of a small input.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace torqued::fuzz {

class MemFile {
 public:
  MemFile(const std::uint8_t* data, std::size_t size) {
    static const int fd = ::memfd_create("torqued-fuzz", MFD_CLOEXEC);
    if (fd < 0 || ::ftruncate(fd, 0) != 0) std::abort();
    for (std::size_t off = 0; off < size;) {
      const ssize_t n = ::pwrite(fd, data + off, size - off, static_cast<off_t>(off));
      if (n <= 0) std::abort();
      off += static_cast<std::size_t>(n);
    }
    path_ = "/proc/self/fd/" + std::to_string(fd);
  }
  MemFile(const MemFile&) = delete;
  MemFile& operator=(const MemFile&) = delete;
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace torqued::fuzz
