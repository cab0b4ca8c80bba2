#pragma once
// The last N values of a per-tooth quantity, newest at [0], pushed in O(1) (a ring instead of shifting the
// whole array on every tooth: two such shifts were a tenth of a Kalman or Fourier update). Real-time safe.
#include <array>
#include <cstddef>

namespace torqued {

template <class T, std::size_t N>
class LagRing {
 public:
  void fill(T v) noexcept {
    buf_.fill(v);
    head_ = 0;
  }
  void push(T v) noexcept {
    head_ = head_ == 0 ? N - 1 : head_ - 1;
    buf_[head_] = v;
  }
  /// The value pushed `age` pushes ago (0: the newest); age < N.
  [[nodiscard]] T operator[](std::size_t age) const noexcept {
    std::size_t i = head_ + age;
    if (i >= N) i -= N;
    return buf_[i];
  }

 private:
  std::array<T, N> buf_{};
  std::size_t head_ = 0;
};

}  // namespace torqued
