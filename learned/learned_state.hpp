#pragma once
// The learned state: ONE record for everything the daemon learns and keeps across restarts (friction law, its
// idle correction and motoring residual scale, the tooth table, the fuel model, the crank-only error
// variance, the inertia scale, the gas model's burn-phase offset). Fixed size and trivially copyable: the
// angle chain fills it on the real-time angle thread without allocating (AngleChain::snapshot), the angle
// stage hands it to the supervisor through a LatestValue<LearnedState> (rt/latest_value.hpp), and the file
// format (learned/state_store.hpp) reads and writes the same record. Each optional quantity carries its own
// validity flag (Opt<T>); the tooth table is a fixed array and a count (FixedVec); the identity read from a
// file is a fixed string (FixedString).
//
// Adding a learned quantity (the three edits, nothing else):
//   1. its field here, in LearnedState (an Opt<...> when it may be absent);
//   2. its row in the line table of learned/state_store.cpp (kLines: keyword, number kinds, optional trailing
//      values, parse message, get/set, physical bounds check), which serialize_state, parse_state and
//      check_state all walk; a bound of the configured engine goes into StateContext (state_context_from);
//   3. where the chain fills it (AngleChain::snapshot) and applies it at start (AngleChain::import_state) in
//      chain/angle_chain.cpp.
// (And its line in the format comment of learned/state_store.hpp.) The angle stage, the supervisor, fast
// replay and the tools pass the record whole and need no change.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>

#include "engine_geometry.hpp"
#include "fuel_torque.hpp"

namespace torqued {

/// A value with its own validity flag (std::optional's interface, trivially copyable when T is).
template <class T>
class Opt {
 public:
  Opt() = default;
  Opt(const T& v) noexcept : v_(v), ok_(true) {}  // NOLINT(google-explicit-constructor): as std::optional
  Opt& operator=(const T& v) noexcept {
    v_ = v;
    ok_ = true;
    return *this;
  }
  [[nodiscard]] bool has_value() const noexcept { return ok_; }
  explicit operator bool() const noexcept { return ok_; }
  void reset() noexcept { *this = Opt{}; }
  T& operator*() noexcept { return v_; }
  const T& operator*() const noexcept { return v_; }
  T* operator->() noexcept { return &v_; }
  const T* operator->() const noexcept { return &v_; }
  /// Equal when both are absent, or both present with equal values.
  friend bool operator==(const Opt& a, const Opt& b) noexcept requires requires(const T& x) { x == x; }
  { return a.ok_ == b.ok_ && (!a.ok_ || a.v_ == b.v_); }

 private:
  T v_{};
  bool ok_ = false;
};

/// Up to N values in a fixed array and their count (the part of std::vector's interface the state needs).
/// Growing beyond N keeps N values.
template <class T, std::size_t N>
class FixedVec {
 public:
  using value_type = T;
  using iterator = T*;
  using const_iterator = const T*;
  static constexpr std::size_t capacity() noexcept { return N; }
  [[nodiscard]] std::size_t size() const noexcept { return n_; }
  [[nodiscard]] bool empty() const noexcept { return n_ == 0; }
  T* data() noexcept { return v_.data(); }
  const T* data() const noexcept { return v_.data(); }
  T* begin() noexcept { return v_.data(); }
  T* end() noexcept { return v_.data() + n_; }
  const T* begin() const noexcept { return v_.data(); }
  const T* end() const noexcept { return v_.data() + n_; }
  T& operator[](std::size_t i) noexcept { return v_[i]; }
  const T& operator[](std::size_t i) const noexcept { return v_[i]; }
  void clear() noexcept { n_ = 0; }
  /// New size min(n, N); added values are `fill`.
  void resize(std::size_t n, const T& fill = T{}) noexcept {
    n = std::min(n, N);
    for (std::size_t i = n_; i < n; ++i) v_[i] = fill;
    n_ = n;
  }
  void assign(std::size_t n, const T& v) noexcept {
    n_ = 0;
    resize(n, v);
  }
  template <class It>
  void assign(It first, It last) noexcept {
    n_ = 0;
    for (; first != last && n_ < N; ++first) v_[n_++] = *first;
  }
  /// False (nothing added) when full.
  bool push_back(const T& v) noexcept {
    if (n_ == N) return false;
    v_[n_++] = v;
    return true;
  }
  friend bool operator==(const FixedVec& a, const FixedVec& b) noexcept {
    return std::equal(a.begin(), a.end(), b.begin(), b.end());
  }

 private:
  std::array<T, N> v_{};
  std::size_t n_ = 0;
};

/// Up to N characters (no terminating zero needed); longer assignments keep the first N.
template <std::size_t N>
class FixedString {
 public:
  FixedString() = default;
  FixedString& operator=(std::string_view s) noexcept {
    n_ = std::min(s.size(), N);
    std::copy_n(s.data(), n_, c_.data());
    return *this;
  }
  static constexpr std::size_t capacity() noexcept { return N; }
  [[nodiscard]] std::size_t size() const noexcept { return n_; }
  [[nodiscard]] bool empty() const noexcept { return n_ == 0; }
  [[nodiscard]] std::string_view view() const noexcept { return {c_.data(), n_}; }
  operator std::string_view() const noexcept { return view(); }  // NOLINT(google-explicit-constructor)
  [[nodiscard]] std::string str() const { return std::string(view()); }
  friend bool operator==(const FixedString& a, std::string_view b) noexcept { return a.view() == b; }
  friend bool operator==(const FixedString& a, const FixedString& b) noexcept { return a.view() == b.view(); }

 private:
  std::array<char, N> c_{};
  std::size_t n_ = 0;
};

/// Tooth corrections a state holds at most: two per tooth position of the densest wheel.
inline constexpr std::size_t kMaxToothCorrections = 2 * static_cast<std::size_t>(kMaxTeeth);
/// Characters of an identity line kept (state_context_from's line is under 160 for any engine and wheel).
inline constexpr std::size_t kMaxIdentityChars = 255;

struct LearnedState {
  Opt<std::array<double, 4>> friction;           ///< FrictionLearner coefficients [C1..C4]
  Opt<std::array<double, 2>> friction_idle;      ///< idle correction (N m) and its idle speed (rpm)
  Opt<std::array<double, 2>> friction_residual;  ///< motoring residual scale (N m), its count
  Opt<double> friction_reference_sd;  ///< 1σ of the most certain load reference the law rests on (N m)
  /// Motoring observations of a law learned from fewer than friction.min_observations (absent: converged or
  /// imported as converged): restored, the law stays "not converged" until the count is reached.
  Opt<double> friction_observations;
  FixedVec<double, kMaxToothCorrections> tooth_corrections_rad;  ///< ToothErrorLearner table (empty: none)
  Opt<FuelTorqueState> fuel;              ///< FuelTorque learned efficiency / pumping / covariance
  Opt<double> crank_error_var;            ///< measured crank-only indicated error variance (N m^2)
  Opt<std::array<double, 3>> inertia;     ///< InertiaLearner k, its information (1/sigma^2), J_spec (kg m^2)
  Opt<std::array<double, 2>> burn_phase;  ///< BurnPhaseLearner offset (deg) and the used cycles behind it
  std::int64_t saved_at_t_ns = 0;         ///< edge-clock time of the save
  FixedString<kMaxIdentityChars> identity;  ///< read from the file (version 2); written from StateContext
  int version = 2;                          ///< read from the file
};
static_assert(std::is_trivially_copyable_v<LearnedState>, "handed between threads by LatestValue");

}  // namespace torqued
