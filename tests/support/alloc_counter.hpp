#pragma once
// Counting global operator new for tests that prove a code path does not allocate (docs/conventions.md habit
// 4). Link torqued_test_support into the test binary; wrap the code under test in an AllocationScope.
#include <cstddef>

namespace torqued::test {

/// Number of global operator new calls since process start (all threads).
std::size_t allocation_count() noexcept;

/// Counts allocations between construction and `count()`.
class AllocationScope {
 public:
  AllocationScope() noexcept : start_(allocation_count()) {}
  [[nodiscard]] std::size_t count() const noexcept { return allocation_count() - start_; }

 private:
  std::size_t start_;
};

}  // namespace torqued::test
