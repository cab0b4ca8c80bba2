// tests/rt/test_memory_use.cpp: read_memory_use() tells locked address space from locked resident memory.
// The daemon's stop line printed VmLck as "locked 357-617 MiB": glibc's reserved malloc arenas, locked by
// mlockall but never touched, while 38 MiB were resident. A mapping locked on fault and left untouched
// plays the arenas' part here.
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cstring>

#include "rt_setup.hpp"

namespace torqued {
namespace {

constexpr std::size_t kMiB = 1024 * 1024;

// mlock through the system call: AddressSanitizer's mlock interceptor returns 0 without locking anything.
int sys_mlock(void* p, std::size_t n) { return static_cast<int>(::syscall(SYS_mlock, p, n)); }
int sys_munlock(void* p, std::size_t n) { return static_cast<int>(::syscall(SYS_munlock, p, n)); }

TEST(MemoryUse, LockedResidentCountsTouchedPagesOnly) {
  const MemoryUse before = read_memory_use();
  ASSERT_GT(before.rss, 0u);
  constexpr std::size_t kTouched = 2 * kMiB, kReserved = 32 * kMiB;
  void* touched = ::mmap(nullptr, kTouched, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  void* reserved = ::mmap(nullptr, kReserved, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(touched, MAP_FAILED);
  ASSERT_NE(reserved, MAP_FAILED);
  std::memset(touched, 1, kTouched);
  if (sys_mlock(touched, kTouched) != 0 || ::mlock2(reserved, kReserved, MLOCK_ONFAULT) != 0) {
    ::munmap(touched, kTouched);
    ::munmap(reserved, kReserved);
    GTEST_SKIP() << "mlock not permitted here (RLIMIT_MEMLOCK / CAP_IPC_LOCK)";
  }
  const MemoryUse m = read_memory_use();
  sys_munlock(touched, kTouched);
  sys_munlock(reserved, kReserved);
  ::munmap(touched, kTouched);
  ::munmap(reserved, kReserved);
  EXPECT_GE(m.locked, before.locked + kTouched + kReserved);  // VmLck: both mappings in full
  EXPECT_GE(m.locked_resident, before.locked_resident + kTouched);
  EXPECT_LT(m.locked_resident,
            before.locked_resident + kTouched + kReserved / 4);  // the reserved part is not
  EXPECT_LE(m.locked_resident, m.rss);
}

}  // namespace
}  // namespace torqued
