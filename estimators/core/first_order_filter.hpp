#pragma once
// Exact zero-order-hold discretisation of the first-order low-pass k·ẋ_f = −x_f + x (Na-9, Na-42).
// With the input held over one step T (the pipeline samples every T and holds), the ODE solution is
//   x_f[n+1] = x_f[n] + (1 − e^{−T/k}) (x[n] − x_f[n])          (exact, any T/k)
// The matching discrete derivative of the filter state is (x_f[n+1] − x_f[n]) / T = (α/T)(x[n] − x_f[n]),
// the discrete counterpart of ẋ_f = (x − x_f)/k. Estimators use gain() = α/T in place of 1/k so that the
// invariant manifold J ω̇_f = τ_ef − τ_lf (Na-15) holds exactly between samples and a constant torque is
// recovered exactly (α/T → 1/k as T → 0; at T = 1 ms, k = 10 ms the two differ by 4.8 %).
// Real-time safe: no allocation, noexcept; exp() is recomputed only when the step changes.
#include <cmath>
#include <type_traits>

namespace torqued {

template <typename T>
class FirstOrderFilter {
 public:
  FirstOrderFilter() noexcept = default;
  FirstOrderFilter(double k_s, double step_s) noexcept { configure(k_s, step_s); }

  /// Sets the time constant k (s) and the step T (s); both must be > 0 (checked by the config loader).
  void configure(double k_s, double step_s) noexcept {
    k_s_ = k_s;
    set_step(step_s);
  }
  /// Recomputes α only when the step changed (timer jitter): one exp() per change.
  void set_step(double step_s) noexcept {
    if (step_s == step_s_) return;
    step_s_ = step_s;
    alpha_ = -std::expm1(-step_s / k_s_);  // 1 − e^{−T/k}, accurate for small T/k
    gain_per_s_ = alpha_ / step_s;
  }
  void reset(const T& value) noexcept { state_ = value; }

  /// Advances one step with the input x[n] held over the step; returns the new state x_f[n+1].
  const T& update(const T& x) noexcept {
    state_ += alpha_ * (x - state_);
    return state_;
  }

  [[nodiscard]] const T& state() const noexcept { return state_; }
  [[nodiscard]] double alpha() const noexcept { return alpha_; }
  /// α/T (1/s): discrete counterpart of 1/k, see the file comment.
  [[nodiscard]] double gain_per_s() const noexcept { return gain_per_s_; }
  [[nodiscard]] double k_s() const noexcept { return k_s_; }
  [[nodiscard]] double step_s() const noexcept { return step_s_; }

 private:
  static T zero() noexcept {
    if constexpr (std::is_arithmetic_v<T>) {
      return T{0};
    } else {
      return T::Zero();  // Eigen types are not zeroed by value-initialisation
    }
  }

  T state_ = zero();
  double k_s_ = 0.01;
  double step_s_ = -1.0;
  double alpha_ = 0.0;
  double gain_per_s_ = 0.0;
};

}  // namespace torqued
